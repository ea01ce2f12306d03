"""The fuzzer (tests/fuzz_inputs.py) over scene files and manifests, a few hundred examples inside
`make test` (derandomised, so the suite is reproducible); `make fuzz` runs 1000+ of each, randomised."""
from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzz_inputs import SETTINGS, check_manifest, check_scene_data, check_scene_text, mutated
from test_bad_input import bake, write_scene
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
