"""What a switch changes (issue 39): every row's frames against its object's full asset drawn the same way
(vdmrender.comparing.change), the floor and the reference's noise beside it, and render settings that do not re-bake."""
from __future__ import annotations

import json
import os

import pytest
from click.testing import CliRunner

from scenes import BRICK_PLANE, RENDER, bake_and_render, scan_sweep
from vdmbake.cli import main as bake_main
from vdmrender.cli import main as render_main

SCENE = RENDER + """reference_spp = 4
antialias = "msaa4"
composite = [{ ball = "coarse@0.3", atoms = "tessellated@1", p = "pom@8" }]
[camera]
orbit = { count = 2 }

[[objects]]
name = "ball"
primitive = "sphere"
techniques = { mesh = {}, coarse = { ratios = [0.3] } }

[[objects]]
name = "atoms"
spheres = [[0.0, 0.0, 0.0, 0.55], [0.6, 0.2, 0.1, 0.4]]
techniques = { tessellated = { levels = [1] } }
""" + BRICK_PLANE


def test_every_row_is_measured_against_its_full_asset_drawn_the_same_way(tmp_path):
    """The full mesh, the ray-cast quadrics and the truly displaced surface are the full assets (named in each row's
    change_against), drawn under the run's anti-aliasing whether or not the scene names them: the mesh row changes
    nothing (0 ΔLuv, IoU 1), every other row changes something; each row carries the full asset's own error against
    the reference (the floor) and the reference's noise, and so does each composite row."""
    r, out = bake_and_render(tmp_path, SCENE)
    assert r.exit_code == 0, r.output
    report = json.loads((out / "report.json").read_text())
    rows = {(row["object"], row["label"]): row for row in report["rows"]}
    # the plane's edges span 8 texels of the tiled height field (a quarter of its side, 2 tiles of 16): 4 halvings
    # bring them under half a texel, the reference's displaced surface
    assert {k: row["change_against"] for k, row in rows.items()} == {
        ("ball", "mesh"): "mesh", ("ball", "coarse@0.3"): "mesh", ("atoms", "tessellated@1"): "impostor@direct",
        ("p", "pom@8"): "displaced@4", ("p", "bump"): "displaced@4"}
    mesh = rows["ball", "mesh"]
    assert (mesh["change_dluv"], mesh["change_p95_dluv"], mesh["change_iou"], mesh["change_flip"]) == (0.0, 0.0, 1.0, 0.0)
    assert mesh["floor_dluv"] == mesh["mean_dluv"]   # the full asset's own row: its fidelity is the floor
    for key, row in rows.items():
        assert row["reference_noise_dluv"] > 0 and row["floor_dluv"] > 0, key
        if key != ("ball", "mesh"):
            assert row["change_dluv"] > 0 and row["change_iou"] < 1, key
    assert rows["ball", "coarse@0.3"]["floor_dluv"] == mesh["mean_dluv"]
    (c,) = report["composite"]
    assert c["change_against"] == "ball:mesh atoms:impostor@direct p:displaced@4" and c["change_dluv"] > 0


def test_a_render_setting_does_not_bake_again(tmp_path):
    """Anti-aliasing, the reference's samples, the sweep, the resolution and the timing are not read by the bake:
    changing them leaves the bundle's parts as they are and rewrites only the scene the manifest holds (which
    vdmrender renders with); changing what the bake reads bakes again."""
    scene, bundle = tmp_path / "s.toml", tmp_path / "b"
    text = RENDER + '[[objects]]\nname = "ball"\nprimitive = "sphere"\ntechniques = { coarse = { ratios = [0.3] } }\n'
    scene.write_text(text)
    assert CliRunner().invoke(bake_main, [str(scene), "-o", str(bundle)]).exit_code == 0
    parts = {p: p.stat().st_mtime_ns for p in (bundle / "objects").rglob("*") if p.is_file()}
    changed = (text.replace("repeats = 1", 'repeats = 2\nreference_spp = 4\nantialias = "ssaa2"')
               .replace("[32, 32]", "[40, 40]").replace("shadow_map = 256\n", "shadow_map = 256\n[render.sweep]\nsizes = [24, 8]\n"))
    scene.write_text(changed)
    r = CliRunner().invoke(bake_main, [str(scene), "-o", str(bundle)])
    assert r.exit_code == 0 and "up to date" in r.output and "render settings rewritten" in r.output, r.output
    assert {p: p.stat().st_mtime_ns for p in parts} == parts
    assert not [p for p in bundle.iterdir() if p.name.startswith(".")]
    render = json.loads((bundle / "manifest.json").read_text())["scene"]["render"]
    assert (render["antialias"], render["reference_spp"], render["sweep"]["sizes"], render["resolution"]) == (
        "ssaa2", 4, [24, 8], [40, 40])
    r = CliRunner().invoke(render_main, [str(bundle), "-o", str(tmp_path / "o"), "--json", "--no-flip"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["filtering"]["antialias"] == "ssaa2"
    again = CliRunner().invoke(bake_main, [str(scene), "-o", str(bundle)])
    assert "up to date" in again.output and "rewritten" not in again.output, again.output
    scene.write_text(changed.replace("ratios = [0.3]", "ratios = [0.2]"))
    r = CliRunner().invoke(bake_main, [str(scene), "-o", str(bundle)])
    assert r.exit_code == 0 and "baking (inputs or settings changed)" in r.output, r.output


SCAN = scan_sweep(128, reference_spp=4, orbits=2)   # at 128 px the frame is a crop of the 512-px bunny


@pytest.mark.slow
def test_what_the_scans_coarsest_mesh_changes_falls_with_its_size(tmp_path):
    """configs/lod-bunny.toml's finding: the scanned bunny's 1% mesh does not come closer to the reference as it
    shrinks (the full mesh's own error grows as fast), but what it changes against the full mesh, drawn the same
    way and supersampled, falls well below its change at 512 px: its facets are a dozen pixels wide at 512 px and
    under half a pixel at 16, where a pixel averages 16 shading samples of each. (Under MSAA the change does not
    fall: each pixel shades a few samples, and the full scan's fine normals differ from the coarse mesh's smooth
    ones at any size: docs/change.md.)"""
    r, out = bake_and_render(tmp_path, SCAN, "--no-flip", "--no-counters")
    assert r.exit_code == 0, r.output
    rows = {row["size_px"]: row for row in json.loads((out / "report.json").read_text())["sweep"]["rows"]}
    assert rows[512]["change_against"] == "mesh"
    assert rows[16]["change_dluv"] < 0.6 * rows[512]["change_dluv"], (rows[16]["change_dluv"], rows[512]["change_dluv"])
    assert rows[16]["floor_dluv"] > 4 * rows[512]["floor_dluv"]   # the full mesh's own error grows as it shrinks
    assert os.path.isfile(out / "sizes" / "16px" / "reference" / "scan" / "000.exr")
