"""Copies the reference cannot hold are refused like a single far object (issue 32): a copy placed 1e20 from the
object was drawn by GL but missing from the reference, exit 0. Every copy's bounding sphere gets the range check
of a single object's (bundle.parts.kind.check_extent), and each copy must be at least instances.MIN_SHARE of the
sphere holding them all; at bake time and in the manifest check the renderer makes."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from scenes import FAR_COPIES
from vdmbake.bundle.directory import Bundle
from vdmbake.cli import main as bake_main
from vdmbake.common import instances
from vdmbake.errors import InputError


def _pair(far: float) -> np.ndarray:
    m = np.tile(np.eye(4), (2, 1, 1))
    m[1, 0, 3] = far
    return m


def test_the_rule():
    instances.check(_pair(1e4), np.zeros(3), 1.0, "o")                        # a forest's spread: fine
    with pytest.raises(InputError, match=r"o: the copies spread over a sphere of radius 5e\+19 \(copy 1 at "
                                         r"\[1e\+20, 0.0, 0.0\] the farthest .*\), so copy 0 \(radius 1\) is 2e-20"):
        instances.check(_pair(1e20), np.zeros(3), 1.0, "o")
    with pytest.raises(InputError, match="o: copy 1: the bounding sphere .* is out of range"):
        instances.check(_pair(1e31), np.zeros(3), 1.0, "o")


def test_bake_refuses_a_copy_far_from_the_others(tmp_path):
    """Failed before the fix: exit 0, and vdmrender drew the far copy in GL only."""
    (tmp_path / "s.toml").write_text(FAR_COPIES.replace("FAR", "1e20"))
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s.toml"), "-o", str(tmp_path / "b")], env={"VDM_CACHE": None})
    assert r.exit_code == 2 and "object 'b': the copies spread over a sphere of radius" in r.output, r.output
    assert "copy 1 at [1e+20, 0.0, 0.0] the farthest" in r.output
    assert "Traceback" not in r.output and not (tmp_path / "b").exists()


def test_the_renderer_refuses_such_a_bundle(tmp_path):
    """A bundle whose manifest places the copies so (baked before the check, or edited) is refused on opening."""
    (tmp_path / "s.toml").write_text(FAR_COPIES.replace("FAR", "3"))
    assert CliRunner().invoke(bake_main, [str(tmp_path / "s.toml"), "-o", str(tmp_path / "b")]).exit_code == 0
    Bundle(tmp_path / "b")
    manifest = json.loads((tmp_path / "b" / "manifest.json").read_text())
    manifest["scene"]["objects"][0]["instances"]["placements"][1]["translate"] = [1e20, 0, 0]
    (tmp_path / "b" / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(InputError, match=r"key 'objects.b': the copies spread .* less than 1.53e-05"):
        Bundle(tmp_path / "b")
