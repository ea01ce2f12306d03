"""Many scenes per call (vdmbake/batch.py, issue 24): OUTDIR/<stem>.bundle per scene, a failing scene never
stops the others, the closing table and the exit codes, a worker killed mid-bake, a signal to the batch;
and the library of 100+ scenes (bench/library_scenes.py)."""
import concurrent.futures
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from vdmbake.bundle.directory import Bundle
from vdmbake.cli import main as bake_main

from batches import SLOW, SMALL, _wait_for_staging, files, hidden, kill_the_baker, redone_elsewhere, whole, write

BIN = Path(sys.executable).parent

BAD = """
[[objects]]
name = "x"
primitive = "sphere"
techniques = { coarse = { ratios = [1e-8] } }
"""


def bake(*args):
    return CliRunner().invoke(bake_main, [str(a) for a in args], env={"VDM_CACHE": None})


def test_many_scenes_one_failing(tmp_path):
    write(tmp_path / "s", a=SMALL.format(name="a", prim="sphere"), b=SMALL.format(name="b", prim="torus"), bad=BAD)
    out = tmp_path / "out"
    r = bake(tmp_path / "s", "-o", out, "--jobs", "2")
    assert r.exit_code == 1, r.output
    assert "1 of 3 scenes failed" in r.stderr and str(tmp_path / "s" / "bad.toml") in r.stderr
    rows = {line.split()[0]: line for line in r.stdout.splitlines() if line.endswith(".toml") or ".toml " in line}
    assert rows["a.toml"].split()[1] == "baked" and rows["b.toml"].split()[1] == "baked"
    assert "failed" in rows["bad.toml"] and "leaves no face" in rows["bad.toml"]
    assert "3 scenes: 2 baked, 0 up to date, 1 failed" in r.stdout
    for stem in "ab":
        Bundle(out / f"{stem}.bundle")
    assert not (out / "bad.bundle").exists() and hidden(out) == []
    again = bake(tmp_path / "s", "-o", out, "--json")                 # up to date; still one failure
    rows = {Path(x["scene"]).stem: x for x in json.loads(again.stdout)["scenes"]}
    assert again.exit_code == 1 and rows["a"]["status"] == "up to date" and rows["bad"]["status"] == "failed"


def test_glob_folder_and_usage_errors(tmp_path):
    write(tmp_path / "s", a=SMALL.format(name="a", prim="sphere"), b=SMALL.format(name="b", prim="cone"))
    write(tmp_path / "t", a=SMALL.format(name="a", prim="torus"))
    out = tmp_path / "out"
    r = bake(str(tmp_path / "s" / "*.toml"), "-o", out, "--jobs", "1", "--json")
    assert r.exit_code == 0, r.output
    assert sorted(Path(x["bundle"]).name for x in json.loads(r.stdout)["scenes"]) == ["a.bundle", "b.bundle"]
    r = bake(tmp_path / "s", tmp_path / "t", "-o", tmp_path / "o2")
    assert r.exit_code == 2 and "would all be baked into" in r.output                   # two a.toml
    assert bake(tmp_path / "s", "-o", out / "a.bundle").exit_code == 2                  # -o is a bundle
    assert bake(tmp_path / "s").exit_code == 2                                          # no -o
    assert bake(tmp_path / "s", "-o", out, "--jobs", "0").exit_code == 2
    (tmp_path / "empty").mkdir()
    assert bake(tmp_path / "empty", "-o", out).exit_code == 2
    assert bake(str(tmp_path / "nothing-*.toml"), "-o", out).exit_code == 2
    assert bake(tmp_path / "s", "-o", out, "--scheduler", "localhost").exit_code == 2


def test_the_bake_names_what_a_dead_bake_left(tmp_path):
    """The next bake of a target names in its log each staging folder of a process no longer running that it
    removed, or put back as the bundle (a complete one, the target lost); a running process's is left, unnamed."""
    from vdmbake.bake import bake as bake_scene

    scene = write(tmp_path / "s", a=SMALL.format(name="a", prim="sphere"))[0]
    out = tmp_path / "a.bundle"
    bake_scene(scene, out)
    q = subprocess.Popen(["true"])
    q.wait()
    dead, running = q.pid, os.getppid()
    out.rename(tmp_path / f".a.bundle.tmp-{dead}")             # killed between its manifest and the swap
    lines = []
    assert bake_scene(scene, out, log=lines.append)["up_to_date"]
    said = f"left by a bake that did not finish (process {dead} no longer runs)"
    assert f"{out}: put back .a.bundle.tmp-{dead}, {said}" in lines, lines
    (tmp_path / f".a.bundle.tmp-{dead}" / "objects").mkdir(parents=True)       # killed mid-bake
    (tmp_path / f".a.bundle.tmp-{running}").mkdir()
    lines = []
    bake_scene(scene, out, log=lines.append)
    assert f"{out}: removed .a.bundle.tmp-{dead}, {said}" in lines, lines
    assert (tmp_path / f".a.bundle.tmp-{running}").is_dir() and not [m for m in lines if str(running) in m]


def test_worker_killed_mid_bake_is_retried(tmp_path):
    """Fault test: the worker process holding scene `slow` (its bake's staging folder names it) is killed
    (SIGKILL) mid-bake; `slow` is baked again by another worker process, whose log shows it found the killed
    bake's staging folder, into a bundle identical to an uninterrupted bake's; the other scene is baked; exit 0,
    no staging folder left."""
    write(tmp_path / "s", slow=SLOW, a=SMALL.format(name="a", prim="sphere"))
    out = tmp_path / "out"
    p = subprocess.Popen([str(BIN / "vdmbake"), str(tmp_path / "s"), "-o", str(out), "--jobs", "2", "--json",
                          "--verbose"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env={k: v for k, v in os.environ.items() if k != "VDM_CACHE"})
    killed, staging = kill_the_baker(out, "slow", p)
    stdout, stderr = p.communicate(timeout=300)
    assert p.returncode == 0, stderr
    rows = {Path(r["scene"]).stem: r for r in json.loads(stdout)["scenes"]}
    assert [r["status"] for r in rows.values()] == ["baked", "baked"], rows
    redone_elsewhere(rows, "slow", killed, staging, p)
    r = bake(tmp_path / "s" / "slow.toml", "-o", tmp_path / "uninterrupted.bundle")
    assert r.exit_code == 0, r.output
    assert whole(out / "slow.bundle") == files(tmp_path / "uninterrupted.bundle")
    whole(out / "a.bundle")


def test_signal_stops_the_batch_and_its_workers(tmp_path):
    write(tmp_path / "s", slow=SLOW)
    out = tmp_path / "out"
    p = subprocess.Popen([str(BIN / "vdmbake"), str(tmp_path / "s"), "-o", str(out), "--jobs", "1"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for_staging(out, p)
    p.send_signal(signal.SIGTERM)
    _, stderr = p.communicate(timeout=120)
    assert p.returncode == 143, stderr
    assert "interrupted" in stderr
    time.sleep(0.5)
    assert hidden(out) == [] and not (out / "slow.bundle").exists()


def test_a_worker_deaf_to_the_signal_leaves_nothing(tmp_path):
    """Fault test: the batch is stopped while a worker cannot act on its SIGTERM (stopped here by SIGSTOP, as a
    long C call or a swallowed signal would hold it past the grace); it is killed, and the staging folder and lease
    it left are removed by the batch, which re-raises the stop."""
    from vdmbake.library.batch import Task, run_local

    scenes = write(tmp_path / "s", slow=SLOW, a=SMALL.format(name="a", prim="sphere"))
    out = tmp_path / "out"
    tasks = [Task(str(s), str(out / f"{s.stem}.bundle")) for s in scenes]

    def stop_the_batch(row):
        assert Path(row["scene"]).stem == "a", row
        stopped.result(timeout=120)
        raise KeyboardInterrupt

    # slow's worker is stopped as soon as its staging folder appears, so that it is still baking however late
    # a's worker starts on a loaded machine; the batch is stopped when a's row comes
    with concurrent.futures.ThreadPoolExecutor(1) as watcher, pytest.raises(KeyboardInterrupt):
        stopped = watcher.submit(lambda: os.kill(_wait_for_staging(out, stem="slow", poll=0.001), signal.SIGSTOP))
        run_local(tasks, 2, stop_the_batch)
    assert hidden(out) == [] and not (out / "slow.bundle").exists()


def test_library_has_100_varied_scenes(tmp_path):
    from bench import library_scenes as library
    from vdmbake.bake import input_hash
    from vdmbake.scene import load_scene

    files = library.write(tmp_path)
    assert len(files) >= 100 and len({f.stem.split("-")[1] for f in files}) >= 5
    sources, techniques = set(), set()
    for f in files:
        scene = load_scene(f)
        input_hash(scene, f.parent)                         # every pkg: asset resolves
        for o in scene.objects:
            sources.add("mesh" if o.mesh else "molecule" if o.molecule else o.primitive or "inline")
            techniques |= set(o.techniques)
    assert {"mesh", "molecule", "inline", "torus", "teapot", "plane"} <= sources
    assert {"coarse", "billboards", "octahedral", "relief", "vdm", "displaced", "impostor"} <= techniques
    assert [f.read_text() for f in library.write(tmp_path)] == [f.read_text() for f in files]   # deterministic


@pytest.mark.slow
def test_library_sample_bakes_and_shares_the_cache(tmp_path):
    """One scene of each family baked on two workers through a cache, then again: every step from the cache."""
    from bench import library_scenes as library

    scenes = tmp_path / "scenes"
    scenes.mkdir()
    picked = {}
    for name, text in library.scenes():
        picked.setdefault(name.split("-")[1].rstrip("0123456789"), (name, text))
    for name, text in picked.values():
        (scenes / name).write_text(text)
    cache = tmp_path / "cache"
    r = bake(scenes, "-o", tmp_path / "cold", "--jobs", "2", "--cache", cache, "--json")
    assert r.exit_code == 0, r.output
    r = bake(scenes, "-o", tmp_path / "warm", "--jobs", "2", "--cache", cache, "--json")
    rows = json.loads(r.stdout)["scenes"]
    assert r.exit_code == 0 and all(x["baked"] == 0 and x["from_cache"] == x["parts"] for x in rows), rows
