"""The code's shape: the renderer renders what the bundle holds (it imports from vdmbake only the
package itself, scene, schema, errors, the Dask mechanism both tools share (cluster) and three rooms: bundle/, formats/ and common/; the benchmarks, which
drive both tools, live outside both packages in bench/), the baker never imports the renderer, neither
package has an import cycle, and every declared technique has its renderer."""
from __future__ import annotations

import ast
import re
import importlib
import importlib.util
from pathlib import Path

import vdmbake
import vdmrender
from vdmbake.scene import REGISTRY

RENDER_MAY_IMPORT = {"vdmbake", "vdmbake.scene", "vdmbake.schema", "vdmbake.errors", "vdmbake.cluster"}
# rooms of the baker the renderer may read from: the bundle format, the file formats, and the neutral
# pure numpy (geometry, sRGB, the pyramid, the albedo lookup: the reference's twins of GL code)
RENDER_MAY_IMPORT_ROOMS = ("vdmbake.bundle", "vdmbake.formats", "vdmbake.common")


def render_may_import(module: str) -> bool:
    return module in RENDER_MAY_IMPORT or any(module == r or module.startswith(r + ".") for r in RENDER_MAY_IMPORT_ROOMS)


def imports(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out |= {node.module} | {f"{node.module}.{a.name}" for a in node.names
                                    if importlib.util.find_spec(node.module) and _is_module(f"{node.module}.{a.name}")}
    return out


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def test_renderer_imports_only_neutral_parts_of_the_baker():
    root = Path(vdmrender.__file__).parent
    for path in sorted(root.rglob("*.py")):
        wrong = {m for m in imports(path) if m.startswith("vdmbake") and not render_may_import(m)}
        assert not wrong, f"{path.relative_to(root.parent)} imports {sorted(wrong)}"


def test_baker_never_imports_the_renderer():
    root = Path(vdmbake.__file__).parent
    for path in sorted(root.rglob("*.py")):
        assert not {m for m in imports(path) if m.startswith("vdmrender")}, path


def test_every_technique_has_its_renderer():
    for name, t in REGISTRY.items():
        module = importlib.import_module(f"vdmrender.techniques.{name}")
        assert callable(module.build), name
        assert t.kinds and set(t.kinds) <= {"surface", "quadrics"}


def _graph(package) -> dict[str, set[str]]:
    """Module -> the package's modules it imports, at module level or inside functions, relative imports
    resolved (`from . import gl`, `from ..techniques import x`)."""
    root = Path(package.__file__).parent
    name = package.__name__
    modules = {}
    for path in root.rglob("*.py"):
        parts_ = [name, *path.relative_to(root).with_suffix("").parts]
        is_init = parts_[-1] == "__init__"
        modules[".".join(parts_[:-1] if is_init else parts_)] = (path, is_init)
    graph = {}
    for mod, (path, is_init) in modules.items():
        here = mod.split(".") if is_init else mod.split(".")[:-1]
        out = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                out |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = ".".join(here[:len(here) - node.level + 1]) if node.level else ""
                target = ".".join(p for p in (base, node.module or "") if p)
                out.add(target)
                out |= {f"{target}.{a.name}" for a in node.names}
        graph[mod] = {m for m in out if m in modules and m != mod}
    return graph


def test_no_import_cycles():
    """No module of either package reaches itself through imports (a cycle makes each module's meaning
    depend on import order, and hides where a piece belongs)."""
    for package in (vdmbake, vdmrender):
        graph = _graph(package)
        for start in graph:
            stack, seen = [(start, [start])], set()
            while stack:
                node, path = stack.pop()
                for nxt in graph[node]:
                    assert nxt != start, f"import cycle: {' -> '.join(path + [nxt])}"
                    if nxt not in seen:
                        seen.add(nxt)
                        stack.append((nxt, path + [nxt]))


def test_architecture_page_names_real_files_and_every_technique():
    """docs/architecture.md is a newcomer's map: every repository path it names exists (globs match),
    and its technique table has a row for every registered technique."""
    root = Path(__file__).resolve().parent.parent
    text = (root / "docs" / "architecture.md").read_text()
    named = set()
    for quoted in re.findall(r"`([^`]+)`", re.sub(r"```.*?```", "", text, flags=re.S)):
        path = quoted.split(":")[0].split(" ")[0]
        if path.split("/")[0] in ("vdmbake", "vdmrender", "shaders", "tests", "bench", "docs", "tools") and "NAME" not in path:
            named.add(path)
    missing = sorted(p for p in named if not list(root.glob(p)))
    assert len(named) > 50 and not missing, missing
    table = text[text.index("### Where each technique lives"):text.index("### The one arrow")]
    rows = set(re.findall(r"^\| `([a-z_]+)` \|", table, re.M))
    assert rows == set(REGISTRY), sorted(rows ^ set(REGISTRY))


def test_shared_rooms_never_import_the_file_readers():
    """The mesh type and the pure numpy every room shares (common/), the file formats (formats/) and the papers'
    kernels (kernels/) depend on no reader of asset files (assets/): the readers make meshes, they do not define
    them."""
    root = Path(vdmbake.__file__).parent
    for room in ("common", "formats", "kernels"):
        for path in sorted((root / room).rglob("*.py")):
            package = ["vdmbake", room, *path.relative_to(root / room).parts[:-1]]
            found = set()
            for node in ast.walk(ast.parse(path.read_text())):   # relative imports resolved, function-level too
                if isinstance(node, ast.ImportFrom):
                    base = package[:len(package) - node.level + 1] if node.level else []
                    found |= {".".join(base + (node.module.split(".") if node.module else []))}
                elif isinstance(node, ast.Import):
                    found |= {a.name for a in node.names}
            assert not {m for m in found if m.startswith("vdmbake.assets")}, path


GL_ROOMS = ("vdmrender.gpu", "vdmrender.measuring", "vdmrender.passes", "vdmrender.techniques", "vdmrender.views")


def test_tracing_deciding_and_common_draw_nothing():
    """The renderer's rooms that trace the reference (tracing/), decide from measured rows (deciding/: the timing
    statistic is there, the loop that times is measuring's) or are shared by all (common/) reach no GL, directly or
    through what they import: no module of a drawing room, no moderngl; and nothing but the run imports the run
    (render, many, cluster, cli)."""
    root = Path(vdmrender.__file__).parent
    for room in ("tracing", "deciding", "common"):
        roots = [f"vdmrender.{room}.{p.stem}" for p in sorted((root / room).glob("*.py")) if p.stem != "__init__"]
        reached = vdmbake.imported_closure(roots)
        assert not [m for m in reached if m.startswith(GL_ROOMS)], (room, reached)
        for name in reached:
            source = Path(importlib.util.find_spec(name).origin).read_text()
            assert not re.search(r"^\s*(import|from) moderngl", source, re.M), (room, name)
    run = {"vdmrender.render", "vdmrender.many", "vdmrender.cluster", "vdmrender.cli"}
    for path in sorted(root.rglob("*.py")):
        name = ".".join(("vdmrender", *path.relative_to(root).with_suffix("").parts)).removesuffix(".__init__")
        if name not in run:
            assert not set(vdmbake.imported_closure([name])) & run - {name}, name
