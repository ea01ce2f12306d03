"""`vdmbake --scheduler` (vdmbake/cluster.py, issue 24) on a Dask LocalCluster: the same bundles as the local
pool; a worker killed mid-task costs only that task's retry (the run completes, no torn cache entry)."""
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from test_batch import SLOW, SMALL, _wait_for_staging, hidden, write
from vdmbake.bundle.directory import Bundle
from vdmbake.library.cache import PartCache
from vdmbake.cli import main as bake_main

pytest.importorskip("distributed")
BIN = Path(sys.executable).parent


def files(bundle: Path) -> dict:
    return {p.relative_to(bundle).as_posix(): p.read_bytes() for p in sorted(bundle.rglob("*"))
            if p.is_file() and p.name != "timing.json"}


def test_local_cluster_bakes_the_same_bundles(tmp_path):
    write(tmp_path / "s", a=SMALL.format(name="a", prim="sphere"), b=SMALL.format(name="b", prim="torus"))
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s"), "-o", str(tmp_path / "dask"), "--scheduler", "local:2",
                                       "--cache", str(tmp_path / "cache"), "--json"], env={"VDM_CACHE": None})
    assert r.exit_code == 0, r.output
    report = json.loads(r.stdout)
    assert "2 workers" in report["workers"] and [x["status"] for x in report["scenes"]] == ["baked", "baked"]
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s"), "-o", str(tmp_path / "pool"), "--jobs", "1"],
                           env={"VDM_CACHE": None})
    assert r.exit_code == 0, r.output
    for stem in "ab":
        assert files(tmp_path / "dask" / f"{stem}.bundle") == files(tmp_path / "pool" / f"{stem}.bundle")


def test_worker_killed_mid_task_is_retried(tmp_path):
    """Fault test: the Dask worker baking a scene is killed (SIGKILL) mid-bake; the scheduler runs the task again,
    the run completes (exit 0), every bundle reads back and every cache entry is whole."""
    write(tmp_path / "s", slow=SLOW, a=SMALL.format(name="a", prim="sphere"), b=SMALL.format(name="b", prim="cone"))
    out, cache = tmp_path / "out", tmp_path / "cache"
    p = subprocess.Popen([str(BIN / "vdmbake"), str(tmp_path / "s"), "-o", str(out), "--scheduler", "local:2",
                          "--cache", str(cache), "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env={k: v for k, v in os.environ.items() if k != "VDM_CACHE"})
    pid = _wait_for_staging(out, p, timeout=240)
    assert pid != p.pid
    os.kill(pid, signal.SIGKILL)                        # a Dask worker process (its nanny starts another)
    stdout, stderr = p.communicate(timeout=400)
    assert p.returncode == 0, stderr
    rows = json.loads(stdout)["scenes"]
    assert [r["status"] for r in rows] == ["baked"] * 3, rows
    for r in rows:
        Bundle(Path(r["bundle"]))
    assert PartCache(cache).verify()["removed_damaged"] == 0
    assert not [q for q in (cache / "entries").rglob("*") if q.is_file() and not q.name.endswith(".tmp")
                and len(q.name) != 64]
    slow = next(r for r in rows if Path(r["scene"]).stem == "slow")
    assert slow["pid"] != pid                           # baked again, by another worker process
    assert hidden(out) == []                            # the killed bake's staging folder removed by the retry
