"""`vdmbake --scheduler` (vdmbake/cluster.py, issue 24) on a Dask LocalCluster: the same bundles as the local
pool; a worker killed mid-task costs only that task's retry (the run completes, no torn cache entry); a worker
that cannot see the scenes hands them back (issue 41)."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from bench.cluster import beside_a_blind_worker
from test_batch import SLOW, SMALL, files, kill_the_baker, redone_elsewhere, whole, write
from vdmbake.library.cache import PartCache
from vdmbake.cli import main as bake_main

pytest.importorskip("distributed")
BIN = Path(sys.executable).parent


@pytest.mark.slow
def test_local_cluster_bakes_the_same_bundles(tmp_path):
    write(tmp_path / "s", a=SMALL.format(name="a", prim="sphere"), b=SMALL.format(name="b", prim="torus"))
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s"), "-o", str(tmp_path / "dask"), "--scheduler", "local:2",
                                       "--cache", str(tmp_path / "cache"), "--json"], env={"VDM_CACHE": None})
    assert r.exit_code == 0, r.output
    report = json.loads(r.stdout)
    assert "Dask scheduler tcp://127.0.0.1:" in report["workers"]           # on the loopback only
    assert "2 workers" in report["workers"] and [x["status"] for x in report["scenes"]] == ["baked", "baked"]
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s"), "-o", str(tmp_path / "pool"), "--jobs", "1"],
                           env={"VDM_CACHE": None})
    assert r.exit_code == 0, r.output
    for stem in "ab":
        assert files(tmp_path / "dask" / f"{stem}.bundle") == files(tmp_path / "pool" / f"{stem}.bundle")


@pytest.mark.slow
def test_worker_killed_mid_task_is_retried(tmp_path):
    """Fault test: the Dask worker process holding scene `slow` (its bake's staging folder names it) is killed
    (SIGKILL) mid-bake; the scheduler runs the task again and another worker process bakes `slow`, whose log shows
    it found the killed bake's staging folder, into the bundle the local pool bakes; the run completes (exit 0)
    and every cache entry is whole."""
    write(tmp_path / "s", slow=SLOW, a=SMALL.format(name="a", prim="sphere"), b=SMALL.format(name="b", prim="cone"))
    out, cache = tmp_path / "out", tmp_path / "cache"
    p = subprocess.Popen([str(BIN / "vdmbake"), str(tmp_path / "s"), "-o", str(out), "--scheduler", "local:2",
                          "--cache", str(cache), "--json", "--verbose"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True,
                         env={k: v for k, v in os.environ.items() if k != "VDM_CACHE"})
    killed, staging = kill_the_baker(out, "slow", p)   # a Dask worker process (its nanny starts another)
    stdout, stderr = p.communicate(timeout=400)
    assert p.returncode == 0, stderr
    report = json.loads(stdout)
    assert "Dask scheduler tcp://127.0.0.1:" in report["workers"]
    rows = {Path(r["scene"]).stem: r for r in report["scenes"]}
    # a scene the killed worker had finished, its result not yet fetched, is run again: its bundle is up to date
    assert rows["slow"]["status"] == "baked" and {rows[s]["status"] for s in "ab"} <= {"baked", "up to date"}, rows
    redone_elsewhere(rows, "slow", killed, staging, p)
    for stem in "ab":
        whole(out / f"{stem}.bundle")
    assert PartCache(cache).verify()["removed_damaged"] == 0
    assert not [q for q in (cache / "entries").rglob("*") if q.is_file() and not q.name.endswith(".tmp")
                and len(q.name) != 64]
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s" / "slow.toml"), "-o", str(tmp_path / "pool.bundle")],
                           env={"VDM_CACHE": None})
    assert r.exit_code == 0, r.output
    assert whole(out / "slow.bundle") == files(tmp_path / "pool.bundle")


def test_a_worker_that_cannot_see_the_scenes_hands_them_back(tmp_path):
    """A worker in its own mount namespace with the scenes' folder hidden hands each scene back; they are baked
    by the worker that joins later, and the closing table names who handed them back (exit 0)."""
    if not (shutil.which("unshare") and subprocess.run(["unshare", "-m", "true"]).returncode == 0):
        pytest.skip("needs unshare -m (root) to hide a folder from one worker")
    write(tmp_path / "s", a=SMALL.format(name="a", prim="sphere"), b=SMALL.format(name="b", prim="torus"))
    p, stdout, stderr, _ = beside_a_blind_worker([str(BIN / "vdmbake"), str(tmp_path / "s"), "-o", str(tmp_path / "out")],
                                                 tmp_path / "s", tmp_path, 2, 300)
    assert p.returncode == 0, stderr
    for stem in "ab":
        line = next(x for x in stdout.splitlines() if x.startswith(f"{stem}.toml"))
        assert " baked " in line and f"(cannot read {tmp_path / 's' / stem}.toml)" in line, stdout
        whole(tmp_path / "out" / f"{stem}.bundle")
