"""vdmexport and the bundle a lod.json was rendered from (issue 32): lod.json records the sha256 of the bundle's
manifest (vdmrender, render.run), and vdmexport refuses a lod.json of another bundle, or of an older vdmrender that
recorded none, and numbers out of range (a band limit of 10**400 raised OverflowError before)."""
import json

import pytest

from exports import export, lod_of_one
from scenes import BALL, RENDER, bake_and_render
from vdmbake.bundle.directory import Bundle


def test_lod_of_this_bundle_exports(tmp_path, bundles):
    r = export(bundles[0], lod_of_one(bundles[0].identity), tmp_path / "x")
    assert r.exit_code == 0 and (tmp_path / "x" / "ball-a.gltf").is_file(), r.output


@pytest.mark.parametrize("which, message", [
    ("other", "was rendered from another bundle"),                 # exported without a word before
    (None, "records no bundle identity (bundle.manifest_sha256): it was written by an older vdmrender; render")])
def test_lod_of_another_bundle_or_without_identity_is_refused(tmp_path, bundles, which, message):
    r = export(bundles[0], lod_of_one(bundles[1].identity if which else None), tmp_path / "x")
    assert r.exit_code == 2 and message in r.output and "Traceback" not in r.output, r.output
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("entry, message", [
    ({"min_px": 10**400, "max_px": 10**401}, "min_px' has value 1000"),   # OverflowError before
    ({"min_px": 9, "max_px": 8}, "min_px' has value 9; allowed: at most max_px (8)"),
    ({"screen_coverage": [1e400, 0]}, "finite numbers"),
    ({"measured": [{"mean_dluv": float("nan")}]}, "finite numbers"),
    ({"measured": [{"size_px": 10**400}]}, "finite numbers")])           # found by test_fuzz_lod: OverflowError
def test_numbers_out_of_range_are_refused(tmp_path, bundles, entry, message):
    r = export(bundles[0], lod_of_one(bundles[0].identity, **entry), tmp_path / "x")
    assert r.exit_code == 2 and message in r.output and "Traceback" not in r.output, r.output


@pytest.mark.gl
def test_vdmrender_records_the_bundle_identity(tmp_path):
    scene = RENDER + "\n[render.sweep]\nsizes = [16]\n[[render.sweep.lod]]\nname = \"any\"\nmean_dluv = 1e3\n" + BALL
    result, out = bake_and_render(tmp_path, scene, "--no-flip")
    assert result.exit_code == 0, result.output[-2000:]
    lod = json.loads((out / "lod.json").read_text())
    assert lod["bundle"] == {"manifest_sha256": Bundle(tmp_path / "b.bundle").identity}
