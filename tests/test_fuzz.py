"""The fuzzer (tests/fuzz_inputs.py) over scene files and manifests and, since issue 21, over textured meshes
(OBJ + MTL + PNG, glTF + .bin + PNG), baseline reports, composite sets and octahedral and pyramid parts, and since
issue 32 over part cache entries as hostile files, stats.log lines and glTF accessors' layouts, and since issue 42
over file references spelt to leave the scene's folder and glTF node trees (tests/fuzz_untrusted.py): a few
hundred examples of each inside `make test` (derandomised, so the suite is reproducible; each target well
under 60 s on 2 cores); `make fuzz` runs 1000+ of each, randomised (VDM_FUZZ_EXAMPLES)."""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st

from fuzz_inputs import (CACHE_SCENE, SETTINGS, TEXTURES_SETTING, DamagedPart, Quiet, accessor_case, baseline_text,
                         bundle_files, cache_entry_case, check_accessors, check_baseline, check_cache_bake,
                         check_composite_bake, check_manifest, check_part, check_scene_data, check_scene_text,
                         check_stats, check_textured_bake, composite_sets, examples, gltf_case, mutated, obj_case,
                         part_case, stats_lines, ADDRESS, check_address_text)
from fuzz_untrusted import (check_compressed, check_node_tree, check_reference, compressed_case, node_tree_case,
                            reference_case)
from helpers import bake, write_scene
from scenes import TINY_HEAD

ROOT = Path(__file__).resolve().parent.parent
FUZZ_SCENE = TINY_HEAD + """
[light]
direction = [1e-200, 0, 1e-200]

[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 12, rings = 6 }
techniques = { mesh = {}, coarse = { ratios = [0.5, 0.25] }, billboards = { resolution = 16, variants = ["greedy-improved+coarse", "axis-hier"] } }

[[objects]]
name = "atoms"
spheres = [[0, 0, 0, 1], [1, 0, 0, 0.5]]
cylinders = [[0, 0, 0, 1, 0, 0, 0.2]]
techniques = { impostor = {}, tessellated = { levels = [0] } }

[[objects]]
name = "tile"
primitive = "torus"
params = { segments = 12, rings = 6 }
mesostructure = { height = "bricks", size = 8, phi = 4, theta = 2, curvatures = 2 }
techniques = { vdm = { k = [2] }, relief = { iterations = [4] }, displaced = { levels = [1] }, bump = {} }
"""
SCENES = [tomllib.loads(FUZZ_SCENE)] + [tomllib.loads(p.read_text()) for p in sorted((ROOT / "configs").glob("*.toml"))]


@pytest.fixture(scope="module")
def fuzz_bundle(tmp_path_factory) -> tuple[Path, dict]:
    import json

    d = tmp_path_factory.mktemp("fuzz")
    out = d / "fuzz.bundle"
    r = bake(write_scene(d, FUZZ_SCENE), "-o", out)
    assert r.exit_code == 0, r.output
    return out, json.loads((out / "manifest.json").read_text())


@given(data=st.sampled_from(SCENES).flatmap(mutated))
@SETTINGS
def test_fuzz_scene_data(data):
    check_scene_data(data)


@given(text=st.tuples(st.just(FUZZ_SCENE), st.lists(st.tuples(st.integers(0, len(FUZZ_SCENE)), st.integers(0, 3),
                                                             st.text(max_size=6)), min_size=1, max_size=3)))
@SETTINGS
def test_fuzz_scene_text(tmp_path_factory, text):
    base, edits = text
    for at, cut, insert in edits:
        base = base[:at] + insert + base[at + cut:]
    check_scene_text(tmp_path_factory.mktemp("t") / "scene.toml", base)


@given(data=st.data())
@SETTINGS
def test_fuzz_manifest(fuzz_bundle, tmp_path_factory, data):
    bundle, manifest = fuzz_bundle
    check_manifest(bundle, data.draw(mutated(manifest)))


def test_fuzz_bundle_is_accepted_unmutated(fuzz_bundle):
    bundle, manifest = fuzz_bundle
    check_manifest(bundle, manifest)


# ------------------------------------------------------------------ issue 21: textures and references

@given(case=obj_case(), textures=TEXTURES_SETTING)
@examples(200)
@pytest.mark.slow
def test_fuzz_textured_obj(tmp_path_factory, case, textures):
    files, touched = case
    check_textured_bake(tmp_path_factory.mktemp("obj"), "quad.obj", files, touched, textures)


@given(case=gltf_case(), textures=TEXTURES_SETTING)
@examples(200)
@pytest.mark.slow
def test_fuzz_textured_gltf(tmp_path_factory, case, textures):
    files, touched = case
    check_textured_bake(tmp_path_factory.mktemp("gltf"), "quad.gltf", files, touched, textures)


@pytest.mark.parametrize("textures", [None, '"ignore"'])
@pytest.mark.parametrize("mesh", ["quad.obj", "quad.gltf"])
def test_fuzz_textured_assets_are_accepted_unmutated(tmp_path, mesh, textures):
    """The assets the texture fuzzer starts from bake, with their picture's texels as the albedo map (or, ignored,
    without one): every rule of check_textured_bake holds for them."""
    import json

    from fuzz_assets import BIN, GLTF, MTL, OBJ, PNG

    files = {"quad.obj": OBJ, "m.mtl": MTL} if mesh == "quad.obj" else {"quad.gltf": json.dumps(GLTF), "quad.bin": BIN}
    check_textured_bake(tmp_path, mesh, {**files, "tex.png": PNG}, {"png"}, textures)


# --------------------------------------------------------------------------------- issue 21: baselines

BASELINE_SCENE = TINY_HEAD + """
[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 12, rings = 6 }
techniques = { mesh = {}, coarse = { ratios = [0.5] } }
"""


@pytest.fixture(scope="session")
def fuzz_report(tmp_path_factory) -> dict:
    """The report.json of one tiny render (once per session): what the baseline fuzzer damages."""
    import json

    from scenes import bake_and_render
    from vdmbake.errors import InputError
    from vdmrender.gpu import gl

    try:
        gl.create_context(None).release()
    except InputError as e:
        pytest.skip(f"no OpenGL 4.3 context through EGL here: {e}")
    result, out = bake_and_render(tmp_path_factory.mktemp("report"), BASELINE_SCENE, "--no-flip")
    assert result.exit_code == 0, result.output[-2000:]
    return Quiet("fuzz_report", (json.loads((out / "report.json").read_text()),))


@given(data=st.data())
@examples(300)
def test_fuzz_baseline(fuzz_report, tmp_path_factory, data):
    report, = fuzz_report
    check_baseline(tmp_path_factory.mktemp("baseline") / "report.json", data.draw(baseline_text(fuzz_report)), report)


def test_fuzz_baseline_is_accepted_unmutated(fuzz_report, tmp_path):
    import json

    from vdmrender.deciding import baseline

    report, = fuzz_report
    (tmp_path / "report.json").write_text(json.dumps(report))
    assert [r["label"] for r in baseline.load(tmp_path / "report.json")["rows"]] == ["mesh", "coarse@0.5"]
    check_baseline(tmp_path / "report.json", json.dumps(report), report)


# ---------------------------------------------------------------------------- issue 21: composite sets

@given(sets=composite_sets())
@examples(300)
@pytest.mark.slow
def test_fuzz_composite_sets(tmp_path_factory, sets):
    check_composite_bake(tmp_path_factory.mktemp("composite"), sets)


def test_fuzz_composite_scene_is_accepted_unmutated(tmp_path):
    from fuzz_assets import COMPOSITE_SETS

    check_composite_bake(tmp_path, COMPOSITE_SETS)


# --------------------------------------------------------------- issue 21: octahedral and pyramid parts

@pytest.fixture(scope="module")
def parts_bundle(tmp_path_factory):
    """A tiny bundle with octahedral atlases (one with colour), a relief pyramid and bordered billboards with
    pyramids: (manifest, {part: (its EXR tables, its manifest entry)}, {part: the value its kind reads})."""
    import json

    from fuzz_assets import PARTS_FILES, PARTS_SCENE, parts_under_test, write_files
    from vdmbake.bundle.directory import Bundle
    from vdmbake.bundle.parts import KINDS
    from vdmbake.formats import exr

    d = tmp_path_factory.mktemp("parts")
    write_files(d, PARTS_FILES)
    out = d / "parts.bundle"
    r = bake(write_scene(d, PARTS_SCENE), "-o", out)
    assert r.exit_code == 0, r.output
    manifest = json.loads((out / "manifest.json").read_text())
    b = Bundle(out)
    rels = parts_under_test(manifest)
    parts = {rel: (exr.read((out / rel).read_bytes()), manifest["parts"][rel]) for rel in rels}
    values = {rel: b.read(rel, KINDS[manifest["parts"][rel]["kind"]]) for rel in rels}
    return Quiet("parts_bundle", (manifest, parts, values))


@given(data=st.data())
@examples(400)
@pytest.mark.slow
def test_fuzz_parts(parts_bundle, tmp_path_factory, data):
    manifest, parts, values = parts_bundle
    case = data.draw(part_case(parts_bundle))
    check_part(tmp_path_factory.mktemp("part"), manifest, case, values[case.rel])


def test_fuzz_parts_are_accepted_unmutated(parts_bundle, tmp_path_factory):
    from vdmbake.formats import exr

    manifest, parts, values = parts_bundle
    assert {m["kind"] for _, m in parts.values()} == {"octahedral", "pyramid", "bordered-billboards"}
    assert any(m.get("albedo") for _, m in parts.values())
    for rel, (tables, meta) in parts.items():
        case = DamagedPart(rel, exr.to_bytes(tables), meta, {}, ["reorder"])
        check_part(tmp_path_factory.mktemp("part"), manifest, case, values[rel])


# ---------------------------------------------------------------------------- issue 22: lod.json for vdmexport

LOD_SCENE = TINY_HEAD + """
[render.sweep]
sizes = [24, 8]
[[render.sweep.lod]]
name = "any"
mean_dluv = 1e3
[[objects]]
name = "ball"
primitive = "sphere"
techniques = { mesh = {}, coarse = { ratios = [0.3] }, octahedral = { variants = ["full-4x32-march"] } }
"""


@pytest.fixture(scope="module")
def fuzz_lod(tmp_path_factory):
    from scenes import bake_and_render

    d = tmp_path_factory.mktemp("lod")
    result, out = bake_and_render(d, LOD_SCENE, "--no-flip")
    assert result.exit_code == 0, result.output[-2000:]
    return Quiet("fuzz_lod", (d / "b.bundle", json.loads((out / "lod.json").read_text())))


def check_export(bundle: Path, lod_path: Path, out: Path) -> None:
    """vdmexport with a hostile lod.json: exit 0 with export.json written, or exit 2 through the one-paragraph
    error path with nothing written."""
    from vdmbake.export.cli import main as export_main

    r = CliRunner().invoke(export_main, [str(bundle), "--lod", str(lod_path), "-o", str(out)])
    assert r.exit_code in (0, 2), (r.exit_code, r.output[-3000:], repr(r.exception))
    if r.exit_code == 0:
        assert (out / "export.json").is_file()
        return
    assert isinstance(r.exception, SystemExit) and "Traceback" not in r.output, r.output[-3000:]
    assert r.output.rstrip("\n").splitlines()[-1].startswith("error: "), r.output[-3000:]
    assert not out.exists()


def test_fuzz_lod_is_accepted_unmutated(fuzz_lod, tmp_path):
    bundle, lod = fuzz_lod
    (tmp_path / "lod.json").write_text(json.dumps(lod))
    check_export(bundle, tmp_path / "lod.json", tmp_path / "x")
    assert (tmp_path / "x" / "ball-any.gltf").is_file()


@given(data=st.data())
@examples(300)
@pytest.mark.slow
def test_fuzz_lod(fuzz_lod, tmp_path_factory, data):
    bundle, lod = fuzz_lod
    d = tmp_path_factory.mktemp("export")
    (d / "lod.json").write_text(json.dumps(data.draw(mutated(lod))))
    check_export(bundle, d / "lod.json", d / "x")


# ------------------------------------------------------------------------- issue 32: the part cache as input

@pytest.fixture(scope="module")
def fuzz_cache(tmp_path_factory):
    """A small scene, the bundle a bake without a cache makes of it (every file but timing.json), and the entries
    a bake through a cache stores: (scene text, {file: bytes}, {key: entry bytes})."""
    d = tmp_path_factory.mktemp("cache")
    scene = write_scene(d, CACHE_SCENE)
    assert bake(scene, "-o", d / "plain.bundle").exit_code == 0
    r = bake(scene, "-o", d / "cached.bundle", "--cache", d / "cache")
    assert r.exit_code == 0, r.output
    entries = {p.name: p.read_bytes() for p in (d / "cache" / "entries").rglob("*") if p.is_file()}
    assert len(entries) == 2                          # the object's own step and coarse's
    return Quiet("fuzz_cache", (CACHE_SCENE, bundle_files(d / "plain.bundle"), entries))


@given(data=st.data())
@examples(60)
def test_fuzz_cache_entries(fuzz_cache, tmp_path_factory, data):
    check_cache_bake(tmp_path_factory.mktemp("hostile"), fuzz_cache, data.draw(cache_entry_case(fuzz_cache)))


def test_fuzz_cache_is_accepted_unmutated(fuzz_cache, tmp_path):
    scene, plain, entries = fuzz_cache
    key = sorted(entries)[0]
    check_cache_bake(tmp_path, fuzz_cache, (key, "swap", entries[key]))


@given(lines=stats_lines())
@examples(300)
def test_fuzz_stats_log(tmp_path_factory, lines):
    check_stats(tmp_path_factory.mktemp("stats"), lines)


@given(case=accessor_case())
@examples(300)
def test_fuzz_gltf_accessors(tmp_path_factory, case):
    check_accessors(tmp_path_factory.mktemp("accessors"), case)


def test_fuzz_gltf_accessors_are_accepted_unmutated(tmp_path):
    from fuzz_inputs import _with_colour

    check_accessors(tmp_path, _with_colour())


@given(address=ADDRESS)
@examples(200)
def test_fuzz_scheduler_address(address):
    pytest.importorskip("distributed")
    check_address_text(address)


# ------------------------------------------------------------------ issue 42: file references and node trees

@given(case=reference_case())
@examples(150)
def test_fuzz_file_references(tmp_path_factory, case):
    check_reference(tmp_path_factory.mktemp("refs"), case)


@pytest.mark.parametrize("slot", ["buffer", "image", "mtllib", "map_Kd"])
@pytest.mark.parametrize("name", ["", "../textures/"])
def test_fuzz_file_references_are_accepted_plainly_spelt(tmp_path, slot, name):
    """The plain spellings load, a sibling folder of the scene's tree too: every rule of check_reference holds."""
    check_reference(tmp_path, (slot, name + {"buffer": "quad.bin", "mtllib": "m.mtl"}.get(slot, "tex.png")))


@given(case=node_tree_case())
@examples(150)
def test_fuzz_gltf_node_trees(tmp_path_factory, case):
    check_node_tree(tmp_path_factory.mktemp("nodes"), case)


@given(case=compressed_case())
@examples(150)
def test_fuzz_compressed_gltf(tmp_path_factory, case):
    """Draco and meshopt streams damaged at random (tests/fuzz_untrusted.py): each loads or is refused in one line."""
    check_compressed(tmp_path_factory.mktemp("packed"), case)
