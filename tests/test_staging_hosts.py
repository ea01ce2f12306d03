"""Staging safe on a shared disk (issue 41): writers on two machines at one target, simulated on one by
VDM_TEST_HOSTNAME (vdmbake.bundle.staging.host). A sibling of another machine is judged by its lease, never by
asking this machine about its PID: left while the lease is fresh, removed (and named) once it went stale; the
same rule for a bundle and for a vdmrender output folder."""
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from batches import SLOW, SMALL, files, hidden, whole, write
from vdmbake.bake import bake
from vdmbake.bundle import staging
from vdmbake.bundle.staging import StagedDir

BIN = Path(sys.executable).parent


def _dead_pid() -> int:
    q = subprocess.Popen(["true"])
    q.wait()
    return q.pid


def _another_machines_folder(target: Path, host: str, pid: int, **lease) -> tuple[Path, Path]:
    """What a writer on machine `host` (process `pid` there) has at `target` mid-write: its staging folder with a
    part in it, and its lease, just touched."""
    folder = staging.sibling(target, "tmp", pid, host)
    (folder / "objects").mkdir(parents=True)
    (folder / "objects" / "part.bin").write_bytes(b"half")
    leased = staging.sibling(target, "lease", pid, host)
    leased.write_text(json.dumps({"host": host, "pid": pid, "boot": "b", "pidns": "n", **lease}))
    return folder, leased


def _age(path: Path, seconds: float) -> None:
    t = time.time() - seconds
    os.utime(path, (t, t))


def test_another_hosts_live_bake_is_left_and_its_stale_one_removed(tmp_path, monkeypatch):
    """Before the fix a bake's staging folder was `.x.bundle.tmp-PID`, and a bake on another machine sharing the
    folder removed it when no process PID ran there. Now the folder names its machine and its fresh lease keeps it
    whatever runs here; aged past LEASE_STALE_S it is removed and named."""
    monkeypatch.setenv("VDM_TEST_HOSTNAME", "host-a")
    scene = write(tmp_path / "s", a=SMALL.format(name="a", prim="sphere"))[0]
    out = tmp_path / "shared" / "x.bundle"
    out.parent.mkdir()
    pid = _dead_pid()                                        # another machine's process: not running here
    folder, leased = _another_machines_folder(out, "host-b", pid)
    lines = []
    bake(scene, out, log=lines.append)
    assert (folder / "objects" / "part.bin").read_bytes() == b"half" and leased.is_file()
    assert not [m for m in lines if folder.name in m], lines
    whole(out)
    _age(leased, staging.LEASE_STALE_S + 60)
    lines = []
    bake(scene, out, force=True, log=lines.append)
    said = [m for m in lines if f"removed {folder.name}" in m]
    assert said and f"process {pid} on host-b has not touched its lease for" in said[0], lines
    assert hidden(out.parent) == [], hidden(out.parent)      # the folder and its lease


def test_a_lease_is_judged_by_host_boot_and_pid_namespace(tmp_path, monkeypatch):
    """A sibling named after this host is this machine's only if its lease's boot and PID namespace are this
    machine's too (containers share a host name, not PIDs); otherwise the lease rule, as for another host. A
    vdmrender output folder (marker report.json) follows the same rule as a bundle."""
    monkeypatch.setenv("VDM_TEST_HOSTNAME", "host-a")
    out = tmp_path / "render"
    pid = _dead_pid()
    elsewhere, _ = _another_machines_folder(out, "host-a", pid, boot=staging._identity()["boot"],
                                            pidns="pid:[1]")           # same name and boot, another PID namespace
    mine = staging.sibling(out, "tmp", _dead_pid())                                 # this machine's, dead
    mine.mkdir()
    StagedDir(out, "report.json", "vdmrender output folder").abort()
    assert elsewhere.is_dir() and not mine.exists()
    _age(staging.sibling(out, "lease", pid, "host-a"), staging.LEASE_STALE_S + 1)
    done = staging.recover(out, "report.json")
    assert [(d, k, p) for d, k, p, _, _ in done] == [("removed", "tmp", pid)] and hidden(tmp_path) == []


def test_a_writer_touches_its_lease_until_it_is_done(tmp_path, monkeypatch):
    """The heartbeat: a staging folder's lease is touched while it is held, and gone with the folder."""
    monkeypatch.setattr(staging, "LEASE_BEAT_S", 0.05)
    monkeypatch.setattr(staging, "_beating", None)            # a heartbeat at the shorter beat
    out = tmp_path / "x"
    staged = StagedDir(out, "report.json", "vdmrender output folder")
    _age(staged.lease, 3600)
    t0 = time.time()
    while time.time() - staged.lease.stat().st_mtime > 60 and time.time() - t0 < 30:
        time.sleep(0.05)
    assert time.time() - staged.lease.stat().st_mtime < 60
    (staged.tmp / "report.json").write_text("{}")
    staged.commit()
    assert hidden(tmp_path) == [] and (out / "report.json").is_file()


def test_two_hosts_baking_one_target_at_once(tmp_path, monkeypatch):
    """Two bakes of one scene into one shared target at once, as two machines: host-b (a process) stages in a
    folder named after its machine, and host-a (this process) bakes the same target meanwhile, in its own; neither
    removes the other's (a removed staging folder fails its bake's swap), both end with a whole bundle there (the
    same bytes as a bake alone), and nothing is left beside it."""
    scene = write(tmp_path / "s", slow=SLOW.replace("resolution = 96", "resolution = 512"))[0]
    out = tmp_path / "shared" / "slow.bundle"
    b = subprocess.Popen([str(BIN / "vdmbake"), str(scene), "-o", str(out), "--force"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env={**os.environ, "VDM_TEST_HOSTNAME": "host-b"})
    t0 = time.time()
    while not list(out.parent.glob(".slow.bundle.tmp-host-b-*")) and time.time() - t0 < 120:
        assert b.poll() is None, b.communicate()
        time.sleep(0.01)
    monkeypatch.setenv("VDM_TEST_HOSTNAME", "host-a")
    lines = []
    assert b.poll() is None                                  # host-b is still baking
    bake(scene, out, force=True, log=lines.append)
    stdout, stderr = b.communicate(timeout=600)
    assert b.returncode == 0, stderr
    assert not [m for m in lines + stderr.splitlines() if "removed" in m], (lines, stderr)
    assert hidden(out.parent) == [], hidden(out.parent)
    alone = tmp_path / "alone.bundle"
    bake(scene, alone)
    assert whole(out) == files(alone)


@pytest.fixture(autouse=True)
def _no_cache(monkeypatch):
    monkeypatch.delenv("VDM_CACHE", raising=False)


def test_a_zombie_writer_is_not_alive():
    """A process killed but not yet reaped by its parent (a zombie) no longer writes: its staging folder is debris.
    A running one is alive."""
    child = subprocess.Popen(["sleep", "30"])
    try:
        assert staging.alive(child.pid)
        child.kill()
        for _ in range(200):   # the kernel marks it Z at once; give it a moment under load
            if not staging.alive(child.pid):
                break
            time.sleep(0.01)
        assert not staging.alive(child.pid)
        assert Path(f"/proc/{child.pid}").exists()   # not reaped yet: only its state says it is gone
    finally:
        child.wait()
