"""vdmbake: bakes the tables, maps and meshes a scene's objects need into an EXR/PLY bundle.

The tool's identity has two parts: `__version__`, which a release bumps, and the fingerprint of the
code as installed (`code_fingerprint`), which changes with any edit or upgrade. Caches key on both,
so a bundle or a reference made by other code is never taken for current."""
from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
from pathlib import Path

__version__ = "0.1.0"

PACKAGES = ("vdmbake", "vdmrender")   # whose modules a fingerprint follows through imports


def package_modules(package: str) -> list[str]:
    """Every module of an installed package (its .py files, as found on disk)."""
    root = Path(importlib.util.find_spec(package).origin).parent
    return sorted(".".join((package, *p.relative_to(root).with_suffix("").parts)).removesuffix(".__init__")
                  for p in root.rglob("*.py"))


def imported_closure(roots, stop=frozenset()) -> list[str]:
    """The modules `roots` import, directly or through each other, within PACKAGES, not following the modules in
    `stop`: every import statement counts, those inside functions too (a superset of what one run executes)."""
    seen, todo = set(), list(roots)
    while todo:
        name = todo.pop()
        if name not in seen and name not in stop:
            seen.add(name)
            todo += _imports(name, PACKAGES)
    return sorted(seen)


@functools.lru_cache(maxsize=None)
def _imports(name: str, packages: tuple) -> tuple[str, ...]:
    """The modules of `packages` that module `name`'s import statements name (parsed once per process)."""
    spec = importlib.util.find_spec(name)
    tree = ast.parse(Path(spec.origin).read_text())
    pkg = name if spec.submodule_search_locations else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join([*pkg.split(".")[:len(pkg.split(".")) - node.level + 1], *filter(None, [base])])
            found = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        out += [m for m in found if m.split(".")[0] in packages and _is_module(m)]
    return tuple(dict.fromkeys(out))


@functools.lru_cache(maxsize=None)
def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ModuleNotFoundError, ValueError):
        return False


def code_fingerprint(modules) -> str:
    """sha256 over the names and source bytes of `modules`, as installed: any edit to one of them,
    or an upgrade that changes one, gives another fingerprint."""
    h = hashlib.sha256()
    for name in sorted(set(modules)):
        h.update(name.encode() + b"\0" + hashlib.sha256(Path(importlib.util.find_spec(name).origin)
                                                           .read_bytes()).digest())
    return h.hexdigest()
