"""vdmexport and the bundle a lod.json was rendered from (issue 32): lod.json records the sha256 of the bundle's
manifest (vdmrender, render.run), and vdmexport refuses a lod.json of another bundle, or of an older vdmrender that
recorded none, and numbers out of range (a band limit of 10**400 raised OverflowError before)."""
import json

import pytest
from click.testing import CliRunner

from scenes import RENDER, bake_and_render
from vdmbake.bundle.directory import Bundle
from vdmbake.cli import main as bake_main
from vdmbake.export.cli import main as export_main

BALL = """
[[objects]]
name = "ball"
primitive = "sphere"
techniques = { mesh = {} }
"""


def _lod(identity, **entry) -> dict:
    e = {"variant": "mesh", "technique": "mesh", "min_px": 0, "max_px": 8, "meets": True,
         "screen_coverage": [0.25, 0.0], "measured": [], **entry}
    lod = {"device": "d", "resolution": [32, 32], "chains": [{"name": "a", "objects": {"ball": {
        "entries": [e], "meshes_only": {"entries": [e]}}}}]}
    if identity is not None:
        lod["bundle"] = {"manifest_sha256": identity}
    return lod


@pytest.fixture
def bundles(tmp_path):
    """Two bundles of two scenes: (this one, another one)."""
    out = []
    for name, grey in (("b", 0.5), ("other", 0.7)):
        scene = tmp_path / f"{name}.toml"
        scene.write_text(RENDER + BALL + f"material = {{ albedo = [{grey}, 0.5, 0.5] }}\n")
        assert CliRunner().invoke(bake_main, [str(scene), "-o", str(tmp_path / name)]).exit_code == 0
        out.append(Bundle(tmp_path / name))
    return out


def _export(tmp_path, bundle, lod: dict):
    (tmp_path / "lod.json").write_text(json.dumps(lod))
    return CliRunner().invoke(export_main, [str(bundle.path), "--lod", str(tmp_path / "lod.json"), "-o",
                                            str(tmp_path / "x")])


def test_lod_of_this_bundle_exports(tmp_path, bundles):
    r = _export(tmp_path, bundles[0], _lod(bundles[0].identity))
    assert r.exit_code == 0 and (tmp_path / "x" / "ball-a.gltf").is_file(), r.output


@pytest.mark.parametrize("which, message", [
    ("other", "was rendered from another bundle"),                 # exported without a word before
    (None, "records no bundle identity (bundle.manifest_sha256): it was written by an older vdmrender; render")])
def test_lod_of_another_bundle_or_without_identity_is_refused(tmp_path, bundles, which, message):
    r = _export(tmp_path, bundles[0], _lod(bundles[1].identity if which else None))
    assert r.exit_code == 2 and message in r.output and "Traceback" not in r.output, r.output
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("entry, message", [
    ({"min_px": 10**400, "max_px": 10**401}, "min_px' has value 1000"),   # OverflowError before
    ({"min_px": 9, "max_px": 8}, "min_px' has value 9; allowed: at most max_px (8)"),
    ({"screen_coverage": [1e400, 0]}, "finite numbers"),
    ({"measured": [{"mean_dluv": float("nan")}]}, "finite numbers"),
    ({"measured": [{"size_px": 10**400}]}, "finite numbers")])           # found by test_fuzz_lod: OverflowError
def test_numbers_out_of_range_are_refused(tmp_path, bundles, entry, message):
    r = _export(tmp_path, bundles[0], _lod(bundles[0].identity, **entry))
    assert r.exit_code == 2 and message in r.output and "Traceback" not in r.output, r.output


@pytest.mark.gl
def test_vdmrender_records_the_bundle_identity(tmp_path):
    scene = RENDER + "\n[render.sweep]\nsizes = [16]\n[[render.sweep.lod]]\nname = \"any\"\nmean_dluv = 1e3\n" + BALL
    result, out = bake_and_render(tmp_path, scene, "--no-flip")
    assert result.exit_code == 0, result.output[-2000:]
    lod = json.loads((out / "lod.json").read_text())
    assert lod["bundle"] == {"manifest_sha256": Bundle(tmp_path / "b.bundle").identity}
