"""The renderer's rooms and the imports between them, read from the source (docs/architecture.md §2).

`python tools/rooms.py [PACKAGE_DIR]` writes docs/results/rooms.json (for vdmrender/, the default) or prints the
same figures for another tree, e.g. an old checkout's vdmrender/ to compare with. A room is a folder of the
package (the modules at its top form the room "(top)"); a module's floor is 0 when it imports nothing of the
package and one above the highest module it imports otherwise, counting imports inside functions too.
Lines are not counted, so the file changes only when the structure does. The ast is read, nothing is imported: `make docs` runs this on the system Python."""
from __future__ import annotations

import ast
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOP = "(top)"


def modules(package: Path) -> dict[str, Path]:
    """Dotted name (package-relative, '' for the package) -> file."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = list(path.relative_to(package).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def imports(name: str, path: Path, known: dict[str, Path], root: str) -> set[str]:
    """The package's modules that module `name` imports (a `from X import m` of a submodule m counts m)."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    if name == "":
        package = []
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = package[:len(package) - node.level + 1] + (node.module.split(".") if node.module else [])
            target = ".".join(base)
            for alias in node.names:
                sub = f"{target}.{alias.name}".lstrip(".")
                out.add(sub if sub in known else target)
        elif isinstance(node, ast.Import | ast.ImportFrom):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            for n in names:
                if n == root or n.startswith(root + "."):
                    out.add(n[len(root) + 1:])
    return {m for m in out if m in known and m != name}


def docstring_only(path: Path) -> bool:
    body = ast.parse(path.read_text()).body
    return len(body) == 1 and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)


def room(name: str, rooms: set[str]) -> str:
    first = name.split(".")[0]
    return first if first in rooms else TOP


def survey(package: Path) -> dict:
    known = modules(package)
    graph = {m: imports(m, p, known, package.name) for m, p in known.items()}
    floors: dict[str, int] = {}

    def floor(m, seen=()):
        if m not in floors:
            floors[m] = 1 + max((floor(d, seen + (m,)) for d in graph[m] if d not in seen), default=-1)
        return floors[m]

    for m in graph:
        floor(m)
    folders = {m for m, p in known.items() if p.name == "__init__.py" and m}
    rooms: dict[str, dict] = {}
    for m, path in known.items():
        if m == "" or m in folders and docstring_only(path):
            continue
        home = room(m, folders)
        r = rooms.setdefault(home, {"modules": [], "imports": set()})
        r["modules"].append(m.split(".", 1)[1] if "." in m else "__init__" if home != TOP else m)
        r["imports"] |= {room(d, folders) for d in graph[m] if room(d, folders) != home and d != ""}
    return {"package": package.name,
            "modules": sum(len(r["modules"]) for r in rooms.values()),
            "floors": 1 + max(floors.values()),
            "rooms": {k: {"modules": sorted(v["modules"]), "imports": sorted(v["imports"])}
                      for k, v in sorted(rooms.items())},
            "highest": sorted(m for m, f in floors.items() if f == max(floors.values()))}


def main(argv: list[str]) -> int:
    package = Path(argv[0]) if argv else ROOT / "vdmrender"
    doc = survey(package)
    text = json.dumps(doc, indent=1, ensure_ascii=False) + "\n"
    if argv:
        sys.stdout.write(text)
    else:
        (ROOT / "docs" / "results" / "rooms.json").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
