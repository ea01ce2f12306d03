"""Every example scene in configs/ is valid, and names input files that exist."""
from pathlib import Path

import pytest

from vdmbake.bake import input_hash
from vdmbake.scene import load_scene

CONFIGS = sorted((Path(__file__).parent.parent / "configs").glob("*.toml"))


@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_example_scene_loads(path):
    scene = load_scene(path)
    assert scene.objects
    input_hash(scene, path.parent)   # resolves and hashes every input file (pkg: paths included)
