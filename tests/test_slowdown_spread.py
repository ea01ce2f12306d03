"""--max-slowdown against a --baseline needs a spread of times to judge noise by (issue 32): a run or a baseline
timed with fewer than baseline.MIN_REPEATS renders per frame is refused before anything renders (exit 2), where
before it flagged unchanged rows as slower (with --repeats 1 the spread is 0)."""
import json

import pytest
from click.testing import CliRunner

from scenes import RENDER, bake_and_render
from vdmbake.errors import InputError
from vdmrender.deciding import baseline
from vdmrender.cli import main as render_main

BALL = """
[[objects]]
name = "ball"
primitive = "sphere"
techniques = { mesh = {} }
"""


def test_the_rule():
    baseline.check_spread({"path": "old.json", "repeats": None}, baseline.MIN_REPEATS)   # no budget: not judged
    with pytest.raises(InputError, match="at least 4 timed renders per frame .* this run times 1; give --repeats 4"):
        baseline.check_spread({"path": "old.json", "repeats": 5}, 1)
    with pytest.raises(InputError, match="the baseline old.json times 2; give a baseline rendered with --repeats 4"):
        baseline.check_spread({"path": "old.json", "repeats": 2}, 5)


def test_too_few_repeats_are_refused_before_rendering(tmp_path):
    """Failed before the fix: exit 0 or 1 by chance, with rows flagged slower under noise alone."""
    r, out = bake_and_render(tmp_path, RENDER + BALL, "--no-flip", "--repeats", "4")
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "report.json").read_text())
    assert doc["budget"]["repeats"] == 4
    for row in doc["rows"]:
        row["median_ms"] = 1e9                         # a baseline no run is slower than, whatever the load
    base = tmp_path / "base.json"
    base.write_text(json.dumps(doc))
    args = [str(tmp_path / "b.bundle"), "--no-flip", "--baseline", str(base), "--max-slowdown", "1.5"]
    r = CliRunner().invoke(render_main, [*args, "-o", str(tmp_path / "one"), "--repeats", "1"])
    assert r.exit_code == 2 and "this run times 1; give --repeats 4" in r.stderr, r.output
    assert not (tmp_path / "one").exists()
    r = CliRunner().invoke(render_main, [*args, "-o", str(tmp_path / "four"), "--repeats", "4"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(render_main, [*args[:3], str(tmp_path / "four" / "report.json"), "--max-error-increase",
                                         "1", "-o", str(tmp_path / "error-only"), "--repeats", "1"])
    assert r.exit_code == 0, r.output                  # errors are compared whatever the repeats
    old = tmp_path / "old.json"
    doc["budget"]["repeats"] = 1
    old.write_text(json.dumps(doc))
    args[args.index(str(base))] = str(old)
    r = CliRunner().invoke(render_main, [*args, "-o", str(tmp_path / "old1"), "--repeats", "4"])
    assert r.exit_code == 2 and f"the baseline {old} times 1" in r.stderr, r.output
