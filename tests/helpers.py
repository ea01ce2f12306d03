"""Helpers shared by the test files (a library module: it holds no tests): the CLIs run in-process and their error
path checked, small asset files, and edits of a bench's templates for its smoke test."""
from __future__ import annotations

import dataclasses
import importlib.util
import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner
from PIL import Image

from vdmbake.cli import main as vdmbake_main
from vdmrender import techniques
from vdmrender.cli import main as vdmrender_main

from scenes import CAMERA, RENDER


def leftovers(out: Path) -> list[str]:
    """Hidden temporary/old siblings of `out` (`.NAME.tmp-PID`, `.NAME.old-PID`)."""
    if not out.parent.is_dir():
        return []
    return sorted(p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}."))


def assert_input_error(result, needles, out: Path | None = None):
    """Exit 2 through the one-paragraph error path, naming `needles`; nothing half-written at `out`."""
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    # An uncaught exception would show up here as something other than the SystemExit of fail().
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    err = result.stderr
    assert "Traceback" not in result.output and "Traceback" not in err
    lines = err.rstrip("\n").splitlines()
    assert lines and lines[-1].startswith("error: "), err
    assert err.count("error:") == 1, err
    message = lines[-1]
    for needle in ([needles] if isinstance(needles, str) else needles):
        assert needle in message, f"{needle!r} not in {message!r}"
    if out is not None:
        assert not out.exists(), f"{out} was written"
        assert leftovers(out) == []


def bake(*args, env=None):
    """vdmbake in-process, VDM_CACHE unset unless `env` sets it (no part cache but the one a test names)."""
    return CliRunner().invoke(vdmbake_main, [str(a) for a in args], env=env or {"VDM_CACHE": None})


def render(*args):
    return CliRunner().invoke(vdmrender_main, [str(a) for a in args])


def write_scene(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def png(path: Path, colour=(200, 40, 40), size=4) -> None:
    """A size x size PNG of one colour."""
    Image.new("RGB", (size, size), colour).save(path)


QUAD_V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.1]]
QUAD_UV = [[0, 0], [1, 0], [0, 1], [1, 1]]


def obj_asset(d: Path, uv=QUAD_UV, texture_name: str = "tex.png") -> str:
    """quad.obj -> m.mtl -> tex.png (a textured quad); returns the mesh's name."""
    lines = ["mtllib m.mtl", "usemtl mat"] + [f"v {x} {y} {z}" for x, y, z in QUAD_V]
    lines += [f"vt {s} {t}" for s, t in uv] + ["f 1/1 2/2 3/3", "f 2/2 4/4 3/3"]
    (d / "quad.obj").write_text("\n".join(lines) + "\n")
    (d / "m.mtl").write_text(f"newmtl mat\nKd 1 1 1\nmap_Kd {texture_name}\n")
    if texture_name == "tex.png":
        png(d / "tex.png")
    return "quad.obj"


def gltf_asset(d: Path, texture_index: int = 0) -> str:
    """quad.gltf -> quad.bin (positions, UVs, indices) and tex.png; returns the mesh's name."""
    data = (np.asarray(QUAD_V, "<f4").tobytes() + np.asarray(QUAD_UV, "<f4").tobytes()
            + np.asarray([0, 1, 2, 1, 3, 2], "<u2").tobytes())
    (d / "quad.bin").write_bytes(data)
    png(d / "tex.png")
    views = [(0, 48), (48, 32), (80, 12)]
    tree = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": texture_index}}}],
        "textures": [{"source": 0}], "images": [{"uri": "tex.png"}],
        "buffers": [{"uri": "quad.bin", "byteLength": len(data)}],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in views],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0.1]},
                      {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
                      {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    }
    (d / "quad.gltf").write_text(json.dumps(tree))
    return "quad.gltf"


def scene(mesh: str, extra: str = "") -> str:
    return RENDER + CAMERA + f'[[objects]]\nname = "thing"\nmesh = "{mesh}"\n{extra}techniques = {{ mesh = {{}} }}\n'


# A torus with a mesostructure and a molecule: every kind of part the part cache stores (test_cache*.py).
CACHE_SCENE = """
[render]
resolution = [32, 32]

[[objects]]
name = "{name}"
primitive = "torus"
params = {{ major = 1.0, minor = 0.35, segments = 24, rings = 10 }}
material = {{ albedo = [{grey}, 0.5, 0.5] }}
[objects.mesostructure]
height = "bricks"
albedo = "bricks"
size = 16
depth = 0.05
tiling = [4, 1]
phi = 8
theta = 4
curvatures = 2
[objects.techniques]
mesh = {{}}
coarse = {{ ratios = [{ratio}] }}
relief = {{ iterations = [8] }}
vdm = {{ k = [2] }}
displaced = {{ levels = [1] }}

[[objects]]
name = "mol"
spheres = [[0, 0, 0, 0.5], [1, 0, 0, 0.3]]
cylinders = [[0, 0, 0, 1, 0, 0, 0.1]]
viewer_mesh = 1
techniques = {{ impostor = {{ shading = ["direct"] }} }}
"""


def cache_scene(tmp_path: Path, stem: str = "s", name: str = "torus", ratio: float = 0.5, grey: float = 0.5) -> Path:
    """CACHE_SCENE written to tmp_path/STEM.toml."""
    p = tmp_path / f"{stem}.toml"
    p.write_text(CACHE_SCENE.format(name=name, ratio=ratio, grey=grey))
    return p


def files(bundle: Path) -> dict:
    """Every file of a bundle but timing.json (wall times and where the parts came from), as bytes."""
    return {p.relative_to(bundle).as_posix(): p.read_bytes() for p in sorted(bundle.rglob("*"))
            if p.is_file() and p.name != "timing.json"}


def entries(cache: Path) -> list[Path]:
    """A part cache's entry files."""
    return sorted(p for p in (cache / "entries").rglob("*") if p.is_file())


# PDB files written from atoms: one water (O-H 0.96, H-O-H 104.5 degrees) as (name, element, xyz).
ANG = np.deg2rad(104.5)
WATER = [("O", "O", (0.0, 0.0, 0.0)),
         ("H1", "H", (0.96, 0.0, 0.0)),
         ("H2", "H", (0.96 * np.cos(ANG), 0.96 * np.sin(ANG), 0.0))]


def pdb_line(serial, name, element, xyz, resname="HOH", resseq=1, chain="A", altloc=" ",
             record="HETATM"):
    """One ATOM/HETATM record in the PDB's fixed columns."""
    field = f" {name:<3}" if len(name) < 4 else name
    x, y, z = xyz
    return (f"{record:<6}{serial:>5} {field}{altloc}{resname:>3} {chain}{resseq:>4}    "
            f"{x:8.3f}{y:8.3f}{z:8.3f}{1.0:6.2f}{0.0:6.2f}          {element:>2}")


def pdb_text(groups) -> str:
    """groups: [(resname, resseq, [(name, element, xyz), ...]), ...] -> a PDB file's text."""
    lines, serial = [], 1
    for resname, resseq, atoms in groups:
        for name, el, xyz in atoms:
            lines.append(pdb_line(serial, name, el, xyz, resname, resseq))
            serial += 1
    return "\n".join(lines + ["END", ""])


def edited(monkeypatch, module, name: str, old: str, new: str) -> None:
    """module.name, a text such as a bench's scene template, with `old` replaced by `new` for this test; `old`
    must be there (a template that changed fails here, not as a test that silently runs the old size)."""
    text = getattr(module, name)
    assert old in text, f"{module.__name__}.{name} no longer holds {old!r}"
    monkeypatch.setattr(module, name, text.replace(old, new))


def make_docs():
    """tools/make_docs.py as a module (tools/ is no package)."""
    spec = importlib.util.spec_from_file_location("make_docs", Path(__file__).resolve().parents[1] / "tools" / "make_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def doubled(renderer, name: str):
    """`renderer` with its pass `name` listed twice, so it runs twice: a regression a --baseline must catch. The
    same object, so the counters find its programs."""
    passes = renderer.passes
    renderer.passes = lambda camera, target: [p for p in passes(camera, target)
                                              for _ in range(2 if p[0] == name else 1)]
    return renderer


def doubling(name: str):
    """render's variants, each built doubled(pass `name`): timed, counted and read back so."""
    def variants(*args, **kwargs):
        return [dataclasses.replace(v, build=lambda ctx, b=v.build: doubled(b(ctx), name))
                for v in techniques.variants(*args, **kwargs)]
    return variants
