"""`vdmrender --scheduler` (vdmrender/cluster.py, issue 41): bundles rendered on Dask workers write what a run on
one machine writes, apart from the timings; a worker killed mid-render costs only its bundle's retry; the faults
(no worker, the scheduler lost, a worker that cannot see the bundles) end bounded and named."""
import json
import os
import re
import shutil
import signal
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner

from scenes import BRICK_PLANE, TINY_HEAD
from bench.cluster import ENV, beside_a_blind_worker, differences, render, rendering, scheduler, stop, vdmrender, worker
from batches import _ancestors
from vdmbake.bundle import staging
from vdmbake.cli import main as bake_main

pytest.importorskip("distributed")
pytestmark = pytest.mark.gl
SCENES = {"ball": TINY_HEAD + '[[objects]]\nname = "ball"\nprimitive = "sphere"\n'
                              'techniques = { mesh = {}, coarse = { ratios = [0.2] } }\n',
          "cone": TINY_HEAD + '[[objects]]\nname = "cone"\nprimitive = "cone"\ntechniques = { mesh = {} }\n',
          "plane": TINY_HEAD + BRICK_PLANE}


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """The three scenes baked once for the module."""
    d = tmp_path_factory.mktemp("library")
    (d / "scenes").mkdir()
    for name, text in SCENES.items():
        (d / "scenes" / f"{name}.toml").write_text(text)
    r = CliRunner().invoke(bake_main, [str(d / "scenes"), "-o", str(d / "bundles"), "--jobs", "1"],
                           env={"VDM_CACHE": None})
    assert r.exit_code == 0, r.output
    return d / "bundles"


@pytest.fixture
def library(baked, tmp_path):
    """Each test's own copy of the baked bundles (tests add bundles and renders may write beside them)."""
    return Path(shutil.copytree(baked, tmp_path / "bundles"))


def test_a_local_cluster_renders_what_one_machine_renders(library, tmp_path):
    """Three bundles and a broken one on a local cluster of two workers: every frame, reference, heat map and
    overview the same bytes as a run on one machine, every report row, count and error the same apart from the
    times; each run names the worker it ran on and its device."""
    (library / "zzz.bundle").mkdir()
    (library / "zzz.bundle" / "manifest.json").write_text("{}")
    one, two = tmp_path / "one", tmp_path / "two"
    r = render(library, one)
    assert r.returncode == 1 and "1 of 4 bundles failed: zzz" in r.stderr, r.stderr[-3000:]
    r = render(library, two, "--scheduler", "local:2")
    assert r.returncode == 1 and "1 of 4 bundles failed: zzz" in r.stderr, r.stderr[-3000:]
    assert "rendering 4 bundles into" in r.stderr and "Dask scheduler tcp://127.0.0.1:" in r.stderr
    assert differences(one, two) == []
    report = json.loads((two / "report.json").read_text())
    assert len(report["rows"]) == 5 and all(row["mean_dluv"] is not None for row in report["rows"])
    for run in report["runs"]:
        assert run["worker"].startswith("tcp://127.0.0.1:"), run
        assert run["status"] == "failed" if run["scene"] == "zzz" else run["device"] == report["device"], run


def test_times_from_several_devices_are_not_compared():
    """Runs on workers with different devices make a combined report whose device names them all: a baseline from
    any one device does not compare its times with it (nor it with another one), unless --compare-devices."""
    from vdmrender.deciding import baseline
    from vdmrender import many

    gpu = {"time": "gpu", "device": "NVIDIA H200"}
    assert many.device(["NVIDIA H200", "NVIDIA H200"]) == "NVIDIA H200"
    both = {"time": "gpu", "device": many.device(["NVIDIA H200", "llvmpipe"])}
    assert baseline.times_comparable(gpu, both) and baseline.times_comparable(both, gpu)
    assert baseline.times_comparable(gpu, both, across_devices=True) is None


def test_one_bundle_renders_on_a_worker(library, tmp_path):
    """One bundle given alone renders on one worker into OUT as without a cluster; its bad input is refused as
    on one machine (exit 2, one paragraph), though found on the worker."""
    one, two = tmp_path / "one", tmp_path / "two"
    assert render(library / "cone.bundle", one).returncode == 0
    r = render(library / "cone.bundle", two, "--scheduler", "local:1")
    assert r.returncode == 0 and "cone.bundle: rendered on tcp://127.0.0.1:" in r.stderr, r.stderr[-3000:]
    assert differences(one, two) == []
    r = render(library / "cone.bundle", tmp_path / "three", "--scheduler", "local:1", "-t", "vdm")
    assert r.returncode == 2 and "--technique 'vdm': no object of this bundle's scene names it" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "three").exists()


def test_a_worker_killed_mid_render_is_redone_elsewhere(library, tmp_path):
    """Fault test: the worker process rendering `ball` is killed (SIGKILL) mid-render; the scheduler runs the bundle
    again on a worker, the run completes (exit 0) with every bundle rendered, nothing hidden is left in OUT, and
    ball's files are a run on one machine's."""
    out = tmp_path / "two"
    p = subprocess.Popen(vdmrender(library, out, "--sample-s", "2", "--scheduler", "local:2"),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    pid, folder = rendering(out, "ball", p)
    assert pid != p.pid and p.pid in _ancestors(pid), (pid, p.pid)          # a worker of this run
    os.kill(pid, signal.SIGKILL)
    stdout, stderr = p.communicate(timeout=600)
    assert p.returncode == 0, stderr[-3000:]
    runs = {r["scene"]: r for r in json.loads((out / "report.json").read_text())["runs"]}
    assert {r["status"] for r in runs.values()} == {"rendered"}, runs
    assert not [q for q in out.rglob(".*")], list(out.rglob(".*"))
    one = tmp_path / "one"
    r = render(library / "ball.bundle", one)      # --sample-s changes only what differences() leaves out: times
    assert r.returncode == 0, r.stderr[-3000:]
    assert differences(one, out / "ball") == []


def test_no_worker_within_the_wait(library, tmp_path):
    """A scheduler without workers: exit 2 after --workers-wait, the scheduler named, no output folder."""
    with scheduler(tmp_path) as (address, _):
        r = render(library, tmp_path / "out", "--scheduler", address, "--workers-wait", "1")
    assert r.returncode == 2, r.stderr[-3000:]
    assert f"--scheduler {address}: no Dask worker joined the scheduler within 1 s (--workers-wait)" in r.stderr
    assert not (tmp_path / "out").exists() and staging.recover(tmp_path / "out", "runs.md") == []


def test_a_scheduler_lost_mid_render(library, tmp_path):
    """The scheduler killed while a worker renders: the command exits 2 with the closing table (what finished, and
    the rest `not finished: the connection ... was lost`) and the combined report of what finished; the worker
    stops the render it holds and exits."""
    out = tmp_path / "out"
    with scheduler(tmp_path) as (address, sched):
        w = worker(address)
        try:
            p = subprocess.Popen(vdmrender(library, out, "--sample-s", "2", "--scheduler", address),
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
            said = ""
            while "ball: rendered" not in said:                   # one bundle finished, its row on the client
                said += p.stderr.readline()
                assert p.poll() is None, (said, p.communicate())
            rendering(out, "cone", p)
            sched.send_signal(signal.SIGKILL)
            stdout, stderr = p.communicate(timeout=120)
            stderr = said + stderr
            w.wait(timeout=120)
        finally:
            stop(w)
    assert p.returncode == 2, stderr[-3000:]
    assert "Traceback" not in stderr, stderr[-3000:]
    assert "error: the run stopped: the connection to the Dask scheduler" in stderr, stderr[-3000:]
    runs = {r["scene"]: r for r in json.loads((out / "report.json").read_text())["runs"]}
    assert "not finished: the connection to the Dask scheduler" in runs["cone"]["reason"], runs
    assert runs["ball"]["status"] == "rendered" and (out / "ball" / "report.json").is_file()
    assert "| cone | failed |" in stderr and not (out / "cone").exists()
    assert not [q for q in out.rglob(".*")], list(out.rglob(".*"))


def test_a_worker_that_cannot_see_the_bundles_hands_them_back(library, tmp_path):
    """A worker in its own mount namespace with the bundles' folder hidden (a machine without the share) hands
    back each reference task (all of them sent while it is alone) and each bundle it is given; they run on the worker
    that joins later, and the log and the closing table name who handed back."""
    if not (shutil.which("unshare") and subprocess.run(["unshare", "-m", "true"]).returncode == 0):
        pytest.skip("needs unshare -m (root) to hide a folder from one worker")
    out = tmp_path / "out"
    p, stdout, stderr, _ = beside_a_blind_worker(vdmrender(library, out), library, tmp_path, 3, 600)
    assert p.returncode == 0, stderr[-3000:]
    runs = json.loads((out / "report.json").read_text())["runs"]
    assert {r["status"] for r in runs} == {"rendered"}, runs
    for r in runs:
        assert all(f"cannot read {library.absolute() / r['scene']}.bundle/manifest.json" in h and r["worker"] not in h
                   for h in r.get("handed_back", [])), r
    refs = re.findall(r"\] reference (\w+)/reference/\w+: traced on (\S+) in [\d.]+ s \(handed back by (\S+) \(cannot read "
                      r"(\S+)/manifest\.json\)\)", stderr)
    assert sorted(s for s, *_ in refs) == sorted(r["scene"] for r in runs), stderr[-3000:]
    for scene, seeing, blind, manifest in refs:
        assert seeing != blind and manifest == f"{library.absolute() / scene}.bundle", (scene, seeing, blind, manifest)


def test_bench_rows_render_as_the_docs_show_them(library, tmp_path):
    """bench.cluster's rows (a bundle on one machine and on local:2, and the fault of an address where nothing
    listens), published with their provenance and rendered by the docs' view as the bench's cluster.md has them."""
    from bench import cluster, publish
    from helpers import make_docs

    runs = cluster.compared(tmp_path, "cone", library / "cone.bundle", [])
    doc = {"device": runs[0]["device"], "timing_files": sorted(cluster.TIMING_FILES), "runs": runs,
           "faults": [cluster.unreachable(tmp_path, library, [])]}
    published = json.loads(publish.Run("bench.cluster").publish(tmp_path / "results", "cluster", doc).read_text())
    view = make_docs().VIEWS["cluster"]
    assert "`python -m bench.cluster" in view(published, "provenance")
    table = view(published, "serial-vs-cluster")
    assert table.count("\n") == 4 and "| one machine |" in table and "| `--scheduler local:2` |" in table
    files = runs[1]["files"]   # the same report and files apart from the times
    assert f"| all | 0 of {files} |" in table and files > 0
    faults = view(published, "faults")
    assert "| nothing listens at the address | `--scheduler tcp://127.0.0.1:" in faults
    assert "| 2 |" in faults and "cannot reach the Dask scheduler" in faults
