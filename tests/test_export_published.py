"""Issue 43, item 5: what the reader now applies (wrap modes, texture transforms, the atlas of several pictures and
unpictured parts) is carried into vdmexport's glTF, baked into its UVs and picture: the exported file is valid for the
Khronos validator, three.js and Babylon.js load it with its texture, and read back it gives every vertex the albedo
the source file gives it."""
from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from exports import engines, export, lod_of_levels
from gltf_files import CLAMP, MIRROR, PICTURE, UV, Gltf, validate
from scenes import RENDER
from vdmbake.assets.meshes import load_mesh_file
from vdmbake.bundle.directory import Bundle
from vdmbake.cli import main as bake_main
from vdmbake.common import texture


def _source(path):
    """A mirrored-and-clamped picture over UVs of [-0.5, 1.5], a second picture scaled 2 by KHR_texture_transform
    (REPEAT), and a factor-only quad: one atlas."""
    g = Gltf()
    g.node(mesh=g.mesh(g.primitive(material=g.material(picture=PICTURE, sampler={"wrapS": MIRROR, "wrapT": CLAMP}),
                                   uv=UV * 2 - 0.5)))
    g.node(mesh=g.mesh(g.primitive(material=g.material(picture=PICTURE[::-1], info={"extensions": {
        "KHR_texture_transform": {"scale": [2, 2]}}}), uv=UV)), translation=[2.0, 0, 0])
    g.node(mesh=g.mesh(g.primitive(material=g.material([0.6, 0.4, 0.2, 1.0]))), translation=[4.0, 0, 0])
    g.tree["extensionsUsed"] = ["KHR_texture_transform"]
    return g.write(path)


def _albedos(m) -> np.ndarray:
    """Every vertex's albedo (COLOR_0 x the map at its UV), sorted: what the file gives, whatever the vertex order."""
    a = (m.colors if m.colors is not None else 1.0) * texture.sample(m.texture, m.uvs)
    return a[np.lexsort(a.T[::-1])]


def test_the_export_carries_wrap_modes_and_transforms(tmp_path):
    _source(tmp_path / "w.gltf")
    body = '[[objects]]\nname = "ball"\nmesh = "w.gltf"\ntechniques = { mesh = {} }\n'
    (tmp_path / "s.toml").write_text(RENDER + body)
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s.toml"), "-o", str(tmp_path / "b.bundle")])
    assert r.exit_code == 0, r.output
    bundle = Bundle(tmp_path / "b.bundle")
    r = export(bundle, lod_of_levels(bundle, [("mesh", 0, 512)]), tmp_path / "x")
    assert r.exit_code == 0, r.output
    (path,) = (tmp_path / "x").glob("*.gltf")
    issues = validate(path)["issues"]
    assert issues["numErrors"] == issues["numWarnings"] == issues["numHints"] == 0, issues["messages"]
    tree = json.loads(path.read_text())
    assert "KHR_texture_transform" not in json.dumps(tree) and all("wrapS" not in s for s in tree["samplers"])
    exported, source = load_mesh_file(path), load_mesh_file(tmp_path / "w.gltf")
    assert np.allclose(_albedos(exported), _albedos(source), rtol=0, atol=1e-6)
    for script in ("engine_three.cjs", "engine_babylon.cjs"):
        (report,) = engines(script, (path,))
        assert "error" not in report, (script, report)
