"""`vdmrender --scheduler` splits one bundle (vdmrender/cluster.py, issue 41): every reference of its run (each
object's at each size of its sweep and at its own cameras, the composite's; filtered and pixel-centre) is a task on
any worker, traced into the shared reference cache, and the bundle's GL render on one worker finds them there. The
files are a run on one machine's apart from the timings, and a worker killed mid-trace costs only that reference's
retry."""
import json
import os
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from bench.cluster import ENV, differences, render, vdmrender
from vdmbake.bundle import staging
from vdmbake.bundle.directory import Bundle
from vdmbake.cli import main as bake_main
from vdmrender.render import Options, references

pytest.importorskip("distributed")
pytestmark = pytest.mark.gl
# Two objects swept over two sizes and drawn together: 2 x 3 view sets and the composite's, each with a filtered
# (4 spp) and a pixel-centre reference: 14 references. The chain's limit only the full mesh meets (its change is
# 0), so that the chain is decided by errors alone, not by times that differ from run to run.
SCENE = """
[render]
resolution = [48, 48]
repeats = 1
warmup = 0
shadow_map = 256
reference_spp = 4
composite = [{ ball = "coarse@0.05", cone = "mesh" }]
[render.sweep]
sizes = [32, 16]
[[render.sweep.lod]]
name = "exact"
mean_dluv = 0.0
[camera]
orbit = { count = 2 }
[[objects]]
name = "ball"
primitive = "sphere"
techniques = { mesh = {}, coarse = { ratios = [0.05] } }
[[objects]]
name = "cone"
primitive = "cone"
transform = { translate = [2.5, 0, 0] }
techniques = { mesh = {} }
"""


@pytest.fixture
def bundle(tmp_path):
    (tmp_path / "split.toml").write_text(SCENE)
    r = CliRunner().invoke(bake_main, [str(tmp_path / "split.toml"), "-o", str(tmp_path / "split.bundle")],
                           env={"VDM_CACHE": None})
    assert r.exit_code == 0, r.output
    return tmp_path / "split.bundle"


def _hidden(folder: Path) -> list[Path]:
    return list(folder.rglob(".*"))


def test_one_bundle_split_renders_what_one_machine_renders(bundle, tmp_path):
    """One bundle on a local cluster of two workers: its 14 references each a task of its own, traced into the
    cache; every file and report row (errors, counters, chains) the same as a run on one machine apart from the
    times, its references reported as traced by the run (as there). A run on one machine given that cache traces
    nothing: the keys the cluster traced under are the ones a render looks for."""
    one, two, cache = tmp_path / "one", tmp_path / "two", tmp_path / "cache"
    r = render(bundle, one)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stderr.count("frames traced in") == 14, r.stderr
    r = render(bundle, two, "--scheduler", "local:2", "--reference-cache", str(cache))
    assert r.returncode == 0, r.stderr[-3000:]
    assert "tracing 14 references on the cluster" in r.stderr, r.stderr[-3000:]
    traced = re.findall(r"\] reference split/(\S+): traced on tcp://127\.0\.0\.1:\d+", r.stderr)
    assert sorted(traced) == sorted(f for _, f, _ in references(Bundle(bundle), Options())), r.stderr[-3000:]
    assert differences(one, two) == []
    report = json.loads((two / "report.json").read_text())
    assert report["lod"]["chains"] and report["composite"] and not any(row["reference_cached"] for row in report["rows"])
    assert len(list(cache.iterdir())) == 14 and not _hidden(cache) and not _hidden(two)

    r = render(bundle, tmp_path / "three", "--reference-cache", str(cache))
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stderr.count("frames (cached)") == 14 and "frames traced in" not in r.stderr, r.stderr
    assert all(row["reference_cached"] for row in json.loads((tmp_path / "three" / "report.json").read_text())["rows"])


@pytest.mark.slow
def test_a_worker_killed_mid_trace_is_redone_elsewhere(bundle, tmp_path):
    """Fault test: the worker process tracing the ball's 64-spp reference (about a second here) is killed (SIGKILL)
    mid-trace, in the run's default cache beside OUT; the scheduler runs that reference task again on a worker, the
    run completes (exit 0), the cache is gone and nothing hidden is left, and the files are a run on one
    machine's."""
    more = ("--resolution", "96x96", "--reference-spp", "64")
    b = Bundle(bundle)
    view = next(v for v, folder, _ in references(b, Options(resolution=(96, 96), reference_spp=64))
                if folder == "reference/ball")
    key = view.source(b, b.scene, 64)[0]
    one, two = tmp_path / "one", tmp_path / "two"
    p = subprocess.Popen(vdmrender(bundle, two, *more, "--scheduler", "local:2"), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=ENV)
    staged = re.compile(rf"\.{key}\.tmp-{re.escape(staging.host())}-(\d+)")
    t0, found = time.time(), []
    while not found:
        assert time.time() - t0 < 300 and p.poll() is None, p.communicate()
        found = [q for q in tmp_path.glob(f".two.references.tmp-*/.{key}.tmp-*") if staged.fullmatch(q.name)]
        time.sleep(0.01)
    pid = int(staged.fullmatch(found[0].name)[1])
    os.kill(pid, signal.SIGKILL)
    assert not (found[0].parent / key).exists()       # killed before its entry was in place: mid-trace
    stdout, stderr = p.communicate(timeout=600)
    assert p.returncode == 0, stderr[-3000:]
    assert not staging.alive(pid)
    assert re.search(r"\] reference split/reference/ball: traced on tcp://127\.0\.0\.1:\d+", stderr), stderr[-3000:]
    assert not list(tmp_path.glob(".two.*")) and not _hidden(two), (list(tmp_path.glob(".two.*")), _hidden(two))
    r = render(bundle, one, *more)
    assert r.returncode == 0, r.stderr[-3000:]
    assert differences(one, two) == []
