"""vdmexport's glTF as engines load it (issues 33 and 34): every export kind (textured, untextured, vertex-colour;
several levels) valid for the Khronos validator without a warning, loaded by Babylon.js (MSFT_lod), three.js (level 0)
and trimesh; colours that multiply once; levels finest first, named so Blender keeps the names, each in the scene's
orientation on its own; impostor parts checked as they are copied. Bundles are baked, lod.json written by hand."""
import functools
import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from exports import MODULES, ROOT, engines, export, lod_of_levels
from gltf_files import validate
from scenes import RENDER
from vdmbake.assets import primitives
from vdmbake.bundle.directory import Bundle
from vdmbake.cli import main as bake_main
from vdmbake.export.gltf import Writer, up_to_y

COLOUR = (0.2, 0.5, 0.9)
LEVELS = [("mesh", 64, 512), ("coarse@0.3", 16, 64), ("coarse@0.1", 0, 16)]
TECHNIQUES = 'techniques = { mesh = {}, coarse = { ratios = [0.3, 0.1] } }\n'


def _assets(folder: Path) -> dict[str, str]:
    """Scene text per export kind: a textured OBJ torus, a plain torus, a glTF torus with COLOR_0 (a torus about the
    scene's up, +Z: its extent along up shows an importer's orientation of each level)."""
    s = primitives.torus(1.0, 0.35, 32, 16)
    lines = ["mtllib s.mtl", "usemtl m"] + [f"v {x} {y} {z}" for x, y, z in s.vertices] + \
        [f"vt {u} {v}" for u, v in s.uvs] + [f"vn {x} {y} {z}" for x, y, z in s.normals] + \
        [f"f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}" for a, b, c in s.faces + 1]
    (folder / "s.obj").write_text("\n".join(lines) + "\n")
    (folder / "s.mtl").write_text("newmtl m\nmap_Kd s.png\n")
    texels = np.zeros((8, 16, 3), np.uint8)
    texels[:, :8] = (200, 40, 40)
    texels[:, 8:] = (40, 40, 200)
    Image.fromarray(texels).save(folder / "s.png")
    s.colors = np.tile(COLOUR, (len(s.vertices), 1))
    w = Writer()
    w.lod([w.mesh("ball", s, w.material("white", None, (1.0, 1.0, 1.0), True))], [0.0], (0, 1, 0))
    w.save(folder / "c.gltf")
    body = '[[objects]]\nname = "ball"\n{}\nmaterial = {{ albedo = [0.8, 0.76, 0.7] }}\n'
    return {"textured": body.format('mesh = "s.obj"') + TECHNIQUES,
            "plain": body.format('primitive = "torus"') + TECHNIQUES, "colour": body.format('mesh = "c.gltf"') + TECHNIQUES}


@pytest.fixture(scope="module")
def exports(tmp_path_factory) -> dict[str, Path]:
    return build(tmp_path_factory.mktemp("engines"))


def build(tmp: Path) -> dict[str, Path]:
    """kind -> its exported .gltf (three levels each), baked and exported under `tmp`."""
    out = {}
    for kind, body in _assets(tmp).items():
        (tmp / f"{kind}.toml").write_text(RENDER + body)
        r = CliRunner().invoke(bake_main, [str(tmp / f"{kind}.toml"), "-o", str(tmp / f"{kind}.bundle")])
        assert r.exit_code == 0, r.output
        bundle = Bundle(tmp / f"{kind}.bundle")
        r = export(bundle, lod_of_levels(bundle, LEVELS, kind), tmp / "x" / kind)
        assert r.exit_code == 0, r.output
        out[kind] = tmp / "x" / kind / f"ball-{kind}.gltf"
    return out


@functools.cache



def _levels(path: Path) -> list[dict]:
    """Per level, finest first, what the file holds: vertex count, material name, its image (or None)."""
    g = json.loads(path.read_text())
    first = g["scenes"][0]["nodes"][0]
    while "mesh" not in g["nodes"][first]:   # under a parent
        first = g["nodes"][first]["children"][0]
    out = []
    for n in [first, *g["nodes"][first].get("extensions", {}).get("MSFT_lod", {}).get("ids", [])]:
        prim = g["meshes"][g["nodes"][n]["mesh"]]["primitives"][0]
        mat = g["materials"][prim["material"]]
        tex = mat["pbrMetallicRoughness"].get("baseColorTexture")
        out.append({"node": n, "mesh": g["meshes"][g["nodes"][n]["mesh"]]["name"], "vertices": g["accessors"][prim["attributes"]["POSITION"]]["count"],
                    "material": mat["name"], "image": None if tex is None else g["textures"][tex["index"]]["source"]})
    return out


def test_every_export_is_valid_without_warnings(exports):
    """The Khronos validator: 0 errors, 0 warnings and 0 hints on every export kind (issue 34). Its infos are the
    two it gives any MSFT_lod file, since it does not implement the extension: UNSUPPORTED_EXTENSION for MSFT_lod,
    and UNUSED_OBJECT for each lower level's node, which only the extension's ids refer to."""

    for kind, path in exports.items():
        issues = validate(path)["issues"]
        assert issues["numErrors"] == issues["numWarnings"] == issues["numHints"] == 0, (kind, issues["messages"])
        lower = [f"/nodes/{lv['node']}" for lv in _levels(path)[1:]]
        assert sorted((m["code"], m["pointer"]) for m in issues["messages"]) == sorted(
            [("UNSUPPORTED_EXTENSION", "/extensionsUsed/0")] + [("UNUSED_OBJECT", p) for p in lower]), kind


def test_vertex_colours_multiply_once(exports):
    """glTF 2.0 §3.9.2: base colour = baseColorFactor x texture x COLOR_0. What an engine computes from the
    export is the asset's colour, not the asset's colour times the scene material's albedo again."""
    g = json.loads(exports["colour"].read_text())
    blob = exports["colour"].with_suffix(".bin").read_bytes()
    for level in _levels(exports["colour"]):
        prim = g["meshes"][g["nodes"][level["node"]]["mesh"]]["primitives"][0]
        acc = g["accessors"][prim["attributes"]["COLOR_0"]]
        colours = np.frombuffer(blob, np.float32, acc["count"] * 3, g["bufferViews"][acc["bufferView"]]["byteOffset"])
        factor = g["materials"][prim["material"]]["pbrMetallicRoughness"].get("baseColorFactor", [1, 1, 1, 1])
        np.testing.assert_allclose(colours.reshape(-1, 3) * factor[:3], np.tile(COLOUR, (acc["count"], 1)), atol=1e-6)
    for kind in ("textured", "colour"):   # nothing multiplies a texture or COLOR_0 again
        pbr = json.loads(exports[kind].read_text())["materials"]
        assert all(m["pbrMetallicRoughness"].get("baseColorFactor", [1] * 4) == [1] * 4 for m in pbr), kind
    plain = json.loads(exports["plain"].read_text())["materials"]
    assert {tuple(m["pbrMetallicRoughness"]["baseColorFactor"]) for m in plain} == {(0.8, 0.76, 0.7, 1.0)}


def test_names_images_and_orientation_per_level(exports):
    """Issue 33: one image entry per level's material (Babylon.js with MSFT_lod breaks on a shared one); names
    without '@' and '.' (Blender renames those), one per level; every level node turns the scene's up (+Z) onto
    +Y itself, since MSFT_lod's lower levels are outside the scene's node tree and no parent's rotation reaches
    them."""
    for kind, path in exports.items():
        g = json.loads(path.read_text())
        levels = _levels(path)
        assert len(levels) == 3
        for names in ([lv["material"] for lv in levels], [g["nodes"][lv["node"]]["name"] for lv in levels],
                      [m["name"] for m in g["meshes"]]):
            assert all(re.fullmatch(r"[A-Za-z0-9_-]+", n) for n in names) and len(set(names)) == 3, names
        assert [g["nodes"][lv["node"]].get("rotation") for lv in levels] == [pytest.approx(up_to_y((0, 0, 1)))] * 3
        assert g["scenes"][0]["nodes"] == [levels[0]["node"]]
        images = [lv["image"] for lv in levels]
        assert images == ([None] * 3 if kind != "textured" else [0, 1, 2]), images


def _babylon_levels(report: dict) -> list[int]:
    return [sum(m["vertices"] for m in stage) for stage in report["stages"]]


def test_babylon_loads_every_level(exports):
    """Babylon.js (NullEngine, MSFT_lod on): each level loaded in turn, coarsest first, with the file's vertex
    count, material, texture and colour; every level turned as the scene is (the torus's up along +Y); the finest
    level's mesh carries the switch coverages (its metadata.gltf.extras)."""
    reports = engines("engine_babylon.cjs", tuple(exports.values()))
    for (kind, path), report in zip(exports.items(), reports):
        assert "error" not in report, (kind, report)
        levels = _levels(path)
        assert _babylon_levels(report) == [lv["vertices"] for lv in reversed(levels)], (kind, report)
        for stage, level in zip(report["stages"], reversed(levels)):
            (mesh,) = stage
            assert mesh["material"] == level["material"] and mesh["texture"] == (kind == "textured"), (kind, stage)
            assert np.subtract(mesh["max"], mesh["min"]) == pytest.approx([2.7, 0.7, 2.7], abs=0.1), (kind, mesh)
            if mesh is report["stages"][-1][0]:   # ExtrasAsMetadata: the switch coverages, for the application
                first = json.loads(path.read_text())["nodes"][levels[0]["node"]]
                assert mesh["extras"]["MSFT_screencoverage"] == first["extras"]["MSFT_screencoverage"]
            if kind == "colour":
                assert [a * b for a, b in zip(mesh["albedo"], mesh["first_colour"])] == pytest.approx(COLOUR, abs=1e-6)


def test_three_loads_level_zero(exports):
    """three.js's GLTFLoader has no MSFT_lod: it shows level 0, with its vertex count and material."""
    reports = engines("engine_three.cjs", tuple(exports.values()))
    for (kind, path), report in zip(exports.items(), reports):
        level = _levels(path)[0]
        assert "error" not in report, (kind, report)
        (mesh,) = report["meshes"]
        assert mesh["vertices"] == level["vertices"] and mesh["material"] == level["material"], (kind, report)
        assert mesh["name"] == json.loads(path.read_text())["nodes"][level["node"]]["name"], (kind, report)
        assert np.subtract(mesh["max"], mesh["min"]) == pytest.approx([2.7, 0.7, 2.7], abs=0.1), (kind, mesh)
        assert mesh["texture"] == (kind == "textured"), (kind, report)


def test_trimesh_reads_every_level(exports):
    """A third importer, trimesh (the project's own mesh reader): every level's geometry with its vertex count and
    material (its scene graph holds level 0 only, as three.js's)."""
    for kind, path in exports.items():
        levels = [(lv["vertices"], lv["material"], lv["image"] is not None) for lv in _levels(path)]
        assert _trimesh(path) == levels, kind


def _trimesh(path: Path) -> list[tuple[int, str, bool]]:
    """trimesh's geometries of the file in the file's level order (vertices, material, textured)."""
    import trimesh

    scene = trimesh.load(path, process=False)
    names = [lv["mesh"] for lv in _levels(path)]
    return [(len(m.vertices), m.visual.material.name, m.visual.material.baseColorTexture is not None)
            for _, m in sorted(scene.geometry.items(), key=lambda item: names.index(item[0]))]


def engine_table(exports: dict[str, Path]) -> str:
    """docs/export.md's table: each export as the file holds it and as each importer reports it (levels finest
    first; Babylon.js loads them coarsest first)."""
    import trimesh

    version = lambda p: json.loads((MODULES / p / "package.json").read_text())["version"]   # noqa: E731
    babylon = engines("engine_babylon.cjs", tuple(exports.values()))
    three = engines("engine_three.cjs", tuple(exports.values()))
    rows = ["| export | read by | levels | vertices per level | material per level | texture |", "|---|---|---|---|---|---|"]

    def row(kind, who, items):   # items: (vertices, material, textured) finest first
        rows.append(f"| {kind} | {who} | {len(items)} | {', '.join(str(v) for v, _, _ in items)} | "
                    f"{', '.join(m for _, m, _ in items)} | {'yes' if all(t for *_, t in items) else 'no'} |")

    for (kind, path), b, t in zip(exports.items(), babylon, three):
        row(kind, "the file", [(lv["vertices"], lv["material"], lv["image"] is not None) for lv in _levels(path)])
        row(kind, f"Babylon.js {version('babylonjs')} (MSFT_lod)",
            [(m["vertices"], m["material"], m["texture"]) for stage in reversed(b["stages"]) for m in stage])
        row(kind, f"three.js {version('three')}", [(m["vertices"], m["material"], m["texture"]) for m in t["meshes"]])
        row(kind, f"trimesh {trimesh.__version__}", _trimesh(path))
    return "\n".join(rows) + "\n"


def test_the_engine_table_in_the_docs_is_what_the_engines_report(exports):
    """docs/export.md's engine table is written by `python tests/test_export_engines.py` from these exports."""
    assert engine_table(exports) in (ROOT / "docs" / "export.md").read_text(), \
        "docs/export.md's engine table is not what the engines report now: paste `python tests/test_export_engines.py`"


def test_a_chain_out_of_order_is_said_and_exported_finest_first(tmp_path, exports):
    """A chain whose lower level is finer than the one above it (coarse@0.3, mesh, coarse@0.3: written as it was
    before, with the coarse mesh twice) is exported finest first, each level once, coverages falling, and the
    export says so on stderr and in export.json."""
    bundle = Bundle(exports["plain"].parents[2] / "plain.bundle")
    r = export(bundle, lod_of_levels(bundle, [("coarse@0.3", 256, 512), ("mesh", 32, 256), ("coarse@0.3", 0, 32)]),
               tmp_path / "x")
    assert r.exit_code == 0, r.output
    path = tmp_path / "x" / "ball-a.gltf"
    g = json.loads(path.read_text())
    levels = _levels(path)
    assert [g["nodes"][lv["node"]]["name"].split("_", 2)[-1] for lv in levels] == ["mesh", "coarse_0p3"]
    assert levels[0]["vertices"] > levels[1]["vertices"]
    assert g["nodes"][levels[0]["node"]]["extras"]["MSFT_screencoverage"] == [32 / 512, 0.0]
    assert "not finest first" in r.output and "coarse@0.3" in r.output
    assert json.loads(path.read_text())["asset"]["extras"]["vdmexport"][0].endswith(
        "exported finest first, each level once (mesh down to 32 px -> coarse@0.3 down to 0 px). Check the chain's "
        "costs in lod.md, or render again.")
    note = json.loads((tmp_path / "x" / "export.json").read_text())["warnings"]
    assert len(note) == 1 and "not finest first" in note[0]


def test_finest_first_keeps_each_level_once_with_falling_switch_sizes():
    """A level chosen only above a finer one is never shown once the finer takes over its band: left out, said."""
    from vdmbake.export.chain import finest_first

    e = lambda v, lo: {"variant": v, "min_px": lo}   # noqa: E731
    chain = [e("mesh", 64), e("coarse@0.3", 16), e("coarse@0.1", 0)]
    assert finest_first(chain, [300, 100, 30]) == ([(chain[0], 64), (chain[1], 16), (chain[2], 0)], None)
    out, note = finest_first([e("coarse@0.1", 256), e("mesh", 32), e("coarse@0.3", 0)], [30, 300, 100])
    assert [(x["variant"], px) for x, px in out] == [("mesh", 32), ("coarse@0.3", 0)]
    assert note.endswith("; coarse@0.1 left out, chosen only above a finer level. Check the chain's costs in "
                         "lod.md, or render again.")


BOARDS = RENDER + """
[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 12, rings = 6 }
techniques = { mesh = {}, billboards = { resolution = 8, variants = ["axis-hit0.01"] } }
"""


def test_a_damaged_impostor_part_is_refused_not_copied(tmp_path):
    """Issue 34: every part copied into the export is checked against the bundle's manifest sha256 and read by its
    kind's reader before the sidecar is written; one flipped byte ends the export (exit 2) naming the part."""
    (tmp_path / "s.toml").write_text(BOARDS)
    assert CliRunner().invoke(bake_main, [str(tmp_path / "s.toml"), "-o", str(tmp_path / "b")]).exit_code == 0
    bundle = Bundle(tmp_path / "b")
    lod = lod_of_levels(bundle, [("mesh", 16, 512), ("billboards@axis-hit0.01", 0, 16)])
    lod["chains"][0]["objects"]["ball"]["meshes_only"]["entries"] = lod["chains"][0]["objects"]["ball"]["entries"][:1]
    r = export(bundle, lod, tmp_path / "ok")
    assert r.exit_code == 0, r.output
    side = json.loads((tmp_path / "ok" / "ball-a.impostors.json").read_text())
    for f in side["impostors"][0]["files"]:
        assert hashlib.sha256((tmp_path / "ok" / f["file"]).read_bytes()).hexdigest() == f["sha256"]
    rel = next(rel for rel, meta in bundle.manifest["parts"].items() if meta["kind"] == "billboards")
    data = bytearray(bundle.part_path(rel).read_bytes())
    data[len(data) // 2] ^= 0xFF
    bundle.part_path(rel).write_bytes(bytes(data))
    r = export(bundle, lod, tmp_path / "bad")
    assert r.exit_code == 2 and Path(rel).name in r.output and "checksum" in r.output, r.output
    assert not (tmp_path / "bad").exists()


if __name__ == "__main__":   # docs/export.md's engine table
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        print(engine_table(build(Path(tmp))), end="")
