"""The batch bake's test library (a library module: it holds no tests): small and slow scenes, a folder of scene
files, the hidden staging folders a bake leaves, and finding, killing and checking a run's baking worker; shared by
test_batch and the cluster and staging tests."""
import os
import re
import signal
import time
from pathlib import Path

from vdmbake.bundle import parts, staging
from vdmbake.bundle.directory import Bundle

SMALL = """
[[objects]]
name = "{name}"
primitive = "{prim}"
techniques = {{ mesh = {{}}, coarse = {{ ratios = [0.5] }} }}
"""
# A billboard bake (visibility over 648 directions): long enough to be caught mid-bake.
SLOW = """
[[objects]]
name = "slow"
primitive = "sphere"
params = { segments = 64, rings = 32 }
techniques = { billboards = { variants = ["greedy-hit0.01"], resolution = 96 } }
"""

def write(folder: Path, **scenes) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for stem, text in scenes.items():
        (folder / f"{stem}.toml").write_text(text)
        out.append(folder / f"{stem}.toml")
    return out


def hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".")) if folder.is_dir() else []


def _wait_for_staging(folder: Path, proc=None, timeout: float = 120, stem: str = "", poll: float = 0.01) -> int:
    """The pid in the first hidden staging folder `.NAME.tmp-HOST-PID` that appears in `folder` (of bundle
    STEM.bundle, if `stem` is given): the process baking (`proc`, the command running it, if any, still running
    meanwhile); looked for every `poll` seconds."""
    t0, prefix = time.time(), f".{stem}.bundle.tmp-" if stem else "."
    while time.time() - t0 < timeout:
        for name in hidden(folder):
            if ".tmp-" in name and name.startswith(prefix):
                return int(name.rsplit("-", 1)[1])
        assert proc is None or proc.poll() is None, proc.communicate()
        time.sleep(poll)
    raise AssertionError("no bake started")


def _announced(folder: Path, stem: str, proc, timeout: float = 120) -> int:
    """The pid of the process baking scene `stem`, as the scene's own bake announces it: its bundle's staging
    folder `.STEM.bundle.tmp-HOST-PID` (vdmbake.bundle.staging names it after the writing process), waited for."""
    pattern = re.compile(rf"\.{re.escape(stem)}\.bundle\.tmp-{re.escape(staging.host())}-(\d+)")
    t0 = time.time()
    while time.time() - t0 < timeout:
        for name in hidden(folder):
            if m := pattern.fullmatch(name):
                return int(m[1])
        assert proc is None or proc.poll() is None, proc.communicate()
        time.sleep(0.005)
    raise AssertionError(f"no bake of {stem} started")


def _ancestors(pid: int) -> list[int]:
    """The pids above `pid` (its parent, the parent's parent, ...), from /proc."""
    out = []
    while pid > 1:
        pid = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
        out.append(pid)
    return out


def kill_the_baker(folder: Path, stem: str, proc) -> tuple[int, Path]:
    """SIGKILL the worker process that announced the bake of scene `stem`, while that bake's staging folder is
    still there (the bake not finished); the process must be a worker under `proc`, not `proc` itself. Returns
    the pid killed and the staging folder it left."""
    pid = _announced(folder, stem, proc)
    folder = staging.sibling(folder / f"{stem}.bundle", "tmp", pid)
    assert pid != proc.pid and proc.pid in _ancestors(pid), (pid, proc.pid)      # a worker of this run
    assert folder.is_dir()                                                        # still baking `stem`
    os.kill(pid, signal.SIGKILL)
    return pid, folder


def files(bundle: Path) -> dict:
    """The bundle's files by path, timing.json (wall times, who took what from the cache) left out."""
    return {p.relative_to(bundle).as_posix(): p.read_bytes() for p in sorted(bundle.rglob("*"))
            if p.is_file() and p.name != "timing.json"}


def whole(bundle: Path) -> dict:
    """The bundle opened as the renderer opens it, every part read through its checksum and its kind's reader;
    its files (files())."""
    b = Bundle(bundle)
    for rel, meta in b.manifest["parts"].items():
        b.read(rel, parts.KINDS[meta["kind"]])
    return files(bundle)


def redone_elsewhere(rows: dict, stem: str, killed: int, staging: Path, proc) -> None:
    """The scene `stem`, whose bake in process `killed` was killed, was baked by another process of the run: its
    row names the process that wrote its bundle (batch.bake_one's pid), which is neither the killed one nor the
    command, and that bake's log (--verbose) says it removed the staging folder the killed bake of `stem` left."""
    row = rows[stem]
    assert row["status"] == "baked", row
    assert row["pid"] != killed and row["pid"] != proc.pid, (row["pid"], killed)
    assert f"removed {staging.name}, left by a bake that did not finish (process {killed} no longer runs)" in \
        "\n".join(row["log"]), row["log"]
    assert not staging.exists() and hidden(staging.parent) == []
