"""A hostile user's inputs (issue 21): a --baseline report that is not what it claims is refused before any
rendering, report.json is strict JSON, every variant label is unique, a composite set with nothing to
score is an error, and every error message is one paragraph."""
from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from vdmbake.cli import main as bake_main
from vdmrender.gpu import gl
from vdmrender.reporting import report
from vdmrender.cli import main as render_main

from scenes import TINY_HEAD

ROOT = Path(__file__).resolve().parents[1]
BALL = TINY_HEAD + """
[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 16, rings = 8 }
techniques = { mesh = {} }
"""
GOOD = {"time": "gpu", "device": "d", "resolution": [32, 32],
        "rows": [{"object": "ball", "label": "mesh", "mean_dluv": 0.1, "median_ms": 1.0}]}


def _bake(folder: Path, text: str) -> Path:
    scene, bundle = folder / "scene.toml", folder / "b.bundle"
    scene.write_text(text)
    r = CliRunner().invoke(bake_main, [str(scene), "-o", str(bundle)])
    assert r.exit_code == 0, r.output
    return bundle


@pytest.fixture(scope="module")
def ball(tmp_path_factory) -> Path:
    return _bake(tmp_path_factory.mktemp("ball"), BALL)


def _one_paragraph(stderr: str) -> str:
    """The error message on stderr, checked to be one line of printable characters."""
    assert "Traceback" not in stderr, stderr
    message = stderr[stderr.index("error:"):].rstrip("\n")
    assert "\n" not in message and message.isprintable(), repr(message)
    return message


# ------------------------------------------------------------------------ 1. --baseline checked first

def _nested(depth: int) -> str:
    return '{"rows": [], "x": ' + "[" * depth + "]" * depth + "}"


@pytest.mark.parametrize("text,key", [
    (json.dumps({**GOOD, "rows": [{**GOOD["rows"][0], "mean_dluv": "low"}]}), "key 'rows[0].mean_dluv'"),
    (json.dumps({**GOOD, "rows": [GOOD["rows"][0], {**GOOD["rows"][0], "median_ms": 10 ** 400}]}),
     "key 'rows[1].median_ms'"),
    (json.dumps({**GOOD, "rows": [{**GOOD["rows"][0], "mean_dluv": math.nan}]}), "key 'rows[0].mean_dluv'"),
    (json.dumps({**GOOD, "rows": [{**GOOD["rows"][0], "counters": {"fragments": "many"}}]}),
     "key 'rows[0].counters'"),
    (json.dumps({**GOOD, "device": ["d"]}), "key 'device'"),
    (json.dumps({**GOOD, "rows": {"ball": 1}}), "key 'rows'"),
    (_nested(100_000), "nested more than a report"),
])
def test_bad_baseline_refused_before_rendering(ball, tmp_path, monkeypatch, text, key):
    """Wrong types, a number beyond float's range, a NaN, deep nesting: exit 2 with one paragraph naming the
    row and key, and no GL context was made (the render never started)."""
    def started(*args, **kwargs):
        raise AssertionError("rendering started before the baseline was checked")

    monkeypatch.setattr(gl, "create_context", started)
    (tmp_path / "old.json").write_text(text)
    r = CliRunner().invoke(render_main, [str(ball), "-o", str(tmp_path / "out"), "--no-flip",
                                         "--baseline", str(tmp_path / "old.json")])
    assert r.exit_code == 2, (r.output, r.exception)
    assert key in _one_paragraph(r.stderr)
    assert not (tmp_path / "out").exists()


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))   # /dev/zero read whole must not eat the machine


@pytest.mark.parametrize("make", ["fifo", "/dev/zero", "oversized"])
def test_baseline_that_never_ends_fails_in_seconds(ball, tmp_path, make):
    """A FIFO (blocked forever before), /dev/zero (read until memory ran out) or a file over the size limit:
    refused at once, before any rendering (no output folder), in a process of its own with a timeout."""
    path = tmp_path / "old.json"
    if make == "fifo":
        os.mkfifo(path)
    elif make == "oversized":
        with open(path, "wb") as f:
            f.truncate(1 << 40)                       # sparse: a terabyte that takes no disk
    else:
        path = Path(make)
    r = subprocess.run([sys.executable, "-m", "vdmrender.cli", str(ball), "-o", str(tmp_path / "out"),
                        "--baseline", str(path)], cwd=ROOT, capture_output=True, text=True, timeout=60,
                       preexec_fn=_limit_memory)   # the timeout bounds it: a refusal reads no more than the limit
    assert r.returncode == 2, r.stderr
    message = _one_paragraph(r.stderr)
    assert "--baseline" in message and ("not a regular file" in message or "more than" in message), message
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------------ 2. report.json is strict JSON

def _strict(text: str):
    def refuse(name):
        raise ValueError(f"{name} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_report_json_has_no_nan(tmp_path):
    """A non-finite number anywhere in the report is written as null and its path listed in non_finite."""
    row = {"object": "ball", "technique": "mesh", "label": "mesh", "median_ms": 1.0, "mean_dluv": math.nan,
           "per_frame": [{"frame": 0, "mean_dluv": math.inf}]}
    data = report.finite({"device": "d", "resolution": [32, 32], "rows": [row], "clear_ms": -math.inf})
    report.write(tmp_path, data)
    written = _strict((tmp_path / "report.json").read_text())
    assert written["rows"][0]["mean_dluv"] is None and written["rows"][0]["per_frame"][0]["mean_dluv"] is None
    assert written["non_finite"] == ["rows[0].mean_dluv", "rows[0].per_frame[0].mean_dluv", "clear_ms"]
    assert report.finite(GOOD)["non_finite"] == []


# ------------------------------------------------------------------------ 3. labels are unique

def test_close_knob_values_get_distinct_labels(tmp_path):
    """Two ratios that agree to 6 digits: two labels, two frame folders, and a composite set can name either."""
    text = TINY_HEAD.replace("[render]", '[render]\ncomposite = [{ ball = "coarse@0.5000001" }]') + """
[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 16, rings = 8 }
techniques = { coarse = { ratios = [0.5, 0.5000001, 0.1, 1.0] } }
"""
    bundle = _bake(tmp_path, text)
    r = CliRunner().invoke(render_main, [str(bundle), "-o", str(tmp_path / "out"), "--no-flip", "--json"])
    assert r.exit_code == 0, r.output
    labels = [row["label"] for row in json.loads(r.stdout)["rows"]]
    assert labels == ["coarse@0.5", "coarse@0.5000001", "coarse@0.1", "coarse@1"]
    assert sorted(p.name for p in (tmp_path / "out/frames/ball").iterdir()) == sorted(labels)
    meshes = json.loads((bundle / "manifest.json").read_text())["objects"]["ball"]["techniques"]["coarse"]["meshes"]
    assert len({m["mesh"] for m in meshes}) == 4     # a part of its own per ratio, named as the label spells it


# ------------------------------------------------------------------------ 4. an empty composite set

def test_composite_set_with_nothing_to_score_exits_2(tmp_path):
    """Each tiny sphere fills its own frames, but in the composite frame, which holds both 200 units apart,
    neither covers a pixel: exit 2 as for a per-object variant with nothing to score."""
    sets = 'composite = [{ a = "impostor@direct", b = "impostor@direct" }]'
    text = TINY_HEAD.replace("[render]", f"[render]\n{sets}") + """
[[objects]]
name = "a"
spheres = [[100, 0, 0, 0.01]]
techniques = { impostor = { shading = ["direct"] } }

[[objects]]
name = "b"
spheres = [[-100, 0, 0, 0.01]]
techniques = { impostor = { shading = ["direct"] } }
"""
    bundle = _bake(tmp_path, text)
    r = CliRunner().invoke(render_main, [str(bundle), "-o", str(tmp_path / "out"), "--no-flip", "--json"])
    assert r.exit_code == 2, r.output
    assert all(row["empty_frames"] == 0 for row in json.loads(r.stdout)["rows"])
    message = _one_paragraph(r.stderr)
    assert "composite set 1 (a:impostor@direct b:impostor@direct): no frame has a pixel to score" in message


# ------------------------------------------------------------------------ 5. one paragraph

def test_path_with_a_newline_is_one_paragraph(tmp_path):
    bad = tmp_path / "line one\nline two\x1b[31m"
    r = CliRunner().invoke(bake_main, [str(bad) + ".toml", "-o", str(tmp_path / "b.bundle")])
    assert r.exit_code == 2
    _one_paragraph(r.stderr)
    r = CliRunner().invoke(render_main, [str(bad), "-o", str(tmp_path / "out")])
    assert r.exit_code == 2
    _one_paragraph(r.stderr)


def test_library_message_of_several_lines_is_one_paragraph(tmp_path):
    """gemmi's PDB error quotes the bad line after a newline (and here its control characters)."""
    (tmp_path / "bad.pdb").write_bytes(b"HETATM garbage\x1b[31m\x07\nATOM  zz\n")
    scene = tmp_path / "m.toml"
    scene.write_text(TINY_HEAD + '[[objects]]\nname = "m"\nmolecule = "bad.pdb"\ntechniques = { impostor = {} }\n')
    r = CliRunner().invoke(bake_main, [str(scene), "-o", str(tmp_path / "m.bundle")])
    assert r.exit_code == 2
    message = _one_paragraph(r.stderr)
    assert "Problem in line 1" in message and "HETATM garbage\\x1b[31m\\x07" in message, message
