"""Issue 41's closing figures: three small bundles (at --resolution) and configs/lod-bunny.toml's one bundle (at its
own resolution: its references split over the workers) rendered on one machine and on a local Dask cluster of two
workers (same files apart from the times, and the wall time of each), and each cluster fault as the user meets it
(what the command prints, its exit code, its time). Writes OUT/cluster.json and OUT/cluster.md (docs/cluster.md's
tables; --publish docs/results publishes them).

    python -m bench.cluster WORK -o out/bench [--resolution 128x128] [--publish docs/results]

Also the helpers the cluster tests share: a `dask scheduler` and workers on the loopback, and the comparison of
two output folders apart from what is timing."""
from __future__ import annotations

import contextlib
import csv
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import click

from bench import publish, tables

BIN = Path(sys.executable).parent
ROOT = Path(__file__).resolve().parents[1]
ENV = {k: v for k, v in os.environ.items() if k != "VDM_CACHE"}
CONFIGS = ("bunny-coarse", "molecule-villin", "vdm-torus-bricks")   # small bundles, rendered together
LARGE = "lod-bunny"        # one bundle, two objects swept over six sizes at 16 spp: 28 references
# What a run measures in time, or where it ran: the only fields a cluster's run may change.
TIMED = re.compile(r".*_ms|.*_s|ratio_to_baseline|samples|spread_warning|warmup_frames|steady|saturated|seconds|worker"
                   r"|nvml")
# Files that hold times (their other content is compared through report.json, report.csv, lod.json, sweep.csv).
TIMING_FILES = {"report.html", "error_vs_time.png", "runs.md", "cost_vs_size.png", "lod.md", "composite.md"}


# ------------------------------------------------------------------------------------- shared with tests

def vdmrender(target: Path, out: Path, *more: str) -> list[str]:
    """The command line `vdmrender TARGET -o OUT --no-flip MORE...` (FLIP is the same on any machine: left out)."""
    return [str(BIN / "vdmrender"), str(target), "-o", str(out), "--no-flip", *more]


def render(target: Path, out: Path, *more: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """vdmrender(...) run to its end in ENV, its output captured."""
    return subprocess.run(vdmrender(target, out, *more), capture_output=True, text=True, env=ENV, timeout=timeout)


@contextlib.contextmanager
def scheduler(folder: Path):
    """A `dask scheduler` on the loopback, without workers: (its address, its process); killed after."""
    info = folder / "scheduler.json"
    info.unlink(missing_ok=True)
    sched = subprocess.Popen([str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                              "--scheduler-file", str(info)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             env=ENV)
    try:
        for _ in range(600):
            if info.is_file() and info.stat().st_size:
                break
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:"), address                  # on the loopback only
        yield address, sched
    finally:
        stop(sched)


def worker(address: str, *wrapper: str) -> subprocess.Popen:
    """A `dask worker` of one thread at `address` (its command run under `wrapper`, if any), in a process group of
    its own (the nanny and its worker process: stop() ends both)."""
    return subprocess.Popen([*wrapper, str(BIN / "dask"), "worker", address, "--host", "127.0.0.1", "--nthreads", "1",
                             "--nworkers", "1", "--no-dashboard"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=ENV, start_new_session=True)


def stop(proc: subprocess.Popen) -> None:
    """SIGKILL to the process and, where it leads a process group of its own, to the group."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            if os.getpgid(proc.pid) == proc.pid:
                os.killpg(proc.pid, signal.SIGKILL)
            else:
                proc.kill()
        proc.wait()


def blind(folder: Path) -> list[str]:
    """A command prefix that runs a process in its own mount namespace with `folder` hidden (an empty tmpfs over
    it): a machine that does not mount the share. Needs root."""
    return ["unshare", "-m", "--propagation", "private", "sh", "-c", f"mount -t tmpfs none {folder} && exec \"$@\"",
            "sh"]


def beside_a_blind_worker(cmd: list[str], hidden: Path, work: Path, handed: int,
                          timeout: float) -> tuple[subprocess.Popen, str, str, float]:
    """`cmd --scheduler ADDRESS` on a scheduler (started in `work`) whose one worker cannot see `hidden` (blind),
    until its stderr says `handed` tasks were handed back (every task sent went to that worker alone, and none is
    left for the next to take from its queue); then a worker that can see it joins. The finished process, its
    stdout and stderr, and its seconds from start to end."""
    with scheduler(work) as (address, _):
        workers = [worker(address, *blind(hidden))]
        try:
            t0 = time.perf_counter()
            p = subprocess.Popen([*cmd, "--scheduler", address], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True, env=ENV)
            said = ""
            while said.count(": handed back by ") < handed:
                said += p.stderr.readline()
                assert p.poll() is None, (said, p.communicate())
            workers.append(worker(address))
            stdout, stderr = p.communicate(timeout=timeout)
            seconds = time.perf_counter() - t0
        finally:
            for w in workers:
                stop(w)
    return p, stdout, said + stderr, seconds


def rendering(out: Path, scene: str, proc, timeout: float = 600) -> tuple[int, Path]:
    """(pid, folder) of the process rendering bundle `scene` of a many-bundle run into `out`: the staging sibling
    `.SCENE.tmp-HOST-PID` of its run folder, inside OUT's staging folder; waited for."""
    from vdmbake.bundle import staging

    pattern = re.compile(rf"\.{re.escape(scene)}\.tmp-{re.escape(staging.host())}-(\d+)")
    t0 = time.time()
    while time.time() - t0 < timeout:
        for outer in out.parent.glob(f".{out.name}.tmp-*"):
            for p in list(outer.iterdir()) if outer.is_dir() else []:
                if m := pattern.fullmatch(p.name):
                    return int(m[1]), p
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.01)
    raise AssertionError(f"no render of {scene} started")


def changed(a, b, path: str = "") -> list[str]:
    """Where two reports differ once their times are left out (untimed): the paths of the differing fields."""
    a, b = untimed(a), untimed(b)
    if isinstance(a, dict) and isinstance(b, dict):
        return [p for k in sorted(a.keys() | b.keys()) for p in changed(a.get(k), b.get(k), f"{path}/{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [p for i, (x, y) in enumerate(zip(a, b)) for p in changed(x, y, f"{path}[{i}]")]
    return [] if a == b else [path or "/"]


def untimed(x):
    if isinstance(x, dict):
        return {k: untimed(v) for k, v in x.items() if not TIMED.fullmatch(k)}
    if isinstance(x, list):
        return [untimed(v) for v in x]
    return x


def differences(a: Path, b: Path) -> list[str]:
    """The files of output folders `a` and `b` that differ: byte for byte, JSON and CSV files (report.json,
    report.csv, lod.json, sweep.csv) once their times are left out, the files of TIMING_FILES not at all; files in
    only one of them too."""
    names = lambda d: {p.relative_to(d).as_posix() for p in d.rglob("*") if p.is_file()}  # noqa: E731
    out = sorted(names(a) ^ names(b))
    for rel in sorted(names(a) & names(b)):
        x, y = a / rel, b / rel
        if x.suffix == ".json":
            same = untimed(json.loads(x.read_text())) == untimed(json.loads(y.read_text()))
        elif x.suffix == ".csv":
            rows = lambda p: [untimed(r) for r in csv.DictReader(p.open())]  # noqa: E731
            same = rows(x) == rows(y)
        else:
            same = x.name in TIMING_FILES or x.read_bytes() == y.read_bytes()
        if not same:
            out.append(rel)
    return out


# ----------------------------------------------------------------------------------------------- bench

def _run(cmd, **kw) -> tuple[int, float, str]:
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=ENV, **kw)
    return r.returncode, time.perf_counter() - t0, r.stdout + r.stderr


def _said(text: str, *needles: str) -> list[str]:
    """The lines of `text` that hold a needle, each once."""
    return list(dict.fromkeys(ln.strip() for ln in text.splitlines() if any(n in ln for n in needles)))


def _closed_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def unreachable(work: Path, bundles: Path, res: list[str]) -> dict:
    """The fault of an address where nothing listens."""
    port = _closed_port()
    code, s, text = _run(vdmrender(bundles, work / "f1", *res, "--scheduler", f"tcp://127.0.0.1:{port}"))
    return {"fault": "nothing listens at the address", "command": f"--scheduler tcp://127.0.0.1:{port}",
            "exit": code, "wall_s": round(s, 1), "said": _said(text, "error")}


def faults(work: Path, bundles: Path, res: list[str]) -> list[dict]:
    """Each cluster fault as a row: the fault, the command's options (and what was done to the run), its exit
    code, its seconds, and what it printed (the lines that say) or what it left."""
    rows = [unreachable(work, bundles, res)]

    with scheduler(work) as (address, _):
        code, s, text = _run(vdmrender(bundles, work / "f2", *res, "--scheduler", address, "--workers-wait", "5"))
    rows.append({"fault": "a scheduler without workers", "command": "--scheduler ADDRESS --workers-wait 5",
                 "exit": code, "wall_s": round(s, 1), "said": _said(text, "error")})

    out = work / "f3"
    with scheduler(work) as (address, sched):
        w = worker(address)
        try:
            p = subprocess.Popen(vdmrender(bundles, out, *res, "--scheduler", address), stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, env=ENV)
            said = ""
            while ": rendered" not in said:
                said += p.stderr.readline()
            rendering(out, CONFIGS[1], p)
            t0 = time.perf_counter()
            sched.send_signal(signal.SIGKILL)
            stdout, stderr = p.communicate(timeout=600)
            client_s = time.perf_counter() - t0
            w.wait(timeout=600)
            worker_s = time.perf_counter() - t0
        finally:
            stop(w)
    rows.append({"fault": "the scheduler killed mid-run (one worker)", "command": "--scheduler ADDRESS",
                 "then": "scheduler SIGKILL", "exit": p.returncode, "exit_after_kill_s": round(client_s, 1),
                 "worker_exit_after_kill_s": round(worker_s, 1),
                 "said": _said(said + stdout + stderr, "| failed", "| rendered", "error")})

    out = work / "f4"
    t0 = time.perf_counter()
    p = subprocess.Popen(vdmrender(bundles, out, *res, "--scheduler", "local:2"), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=ENV)
    pid, _ = rendering(out, CONFIGS[1], p)
    os.kill(pid, signal.SIGKILL)
    stdout, stderr = p.communicate(timeout=1200)
    runs = json.loads((out / "report.json").read_text())["runs"]
    rows.append({"fault": "a worker killed mid-render (local:2)", "command": "--scheduler local:2",
                 "then": f"SIGKILL to the worker rendering {CONFIGS[1]}", "exit": p.returncode,
                 "wall_s": round(time.perf_counter() - t0, 1),
                 "rendered": sum(r["status"] == "rendered" for r in runs), "bundles": len(runs),
                 "hidden_left": len(list(out.rglob(".*")))})

    p, stdout, stderr, s = beside_a_blind_worker(vdmrender(bundles, work / "f5", *res), bundles, work, len(CONFIGS),
                                                 1200)
    rows.append({"fault": "a worker that cannot see the bundles (its own mount namespace), a second one joining",
                 "command": "--scheduler ADDRESS", "exit": p.returncode, "wall_s": round(s, 1),
                 "said": _said(stdout + stderr, "| rendered", "| failed")})
    return rows


def compared(work: Path, name: str, target: Path, more: list[str]) -> list[dict]:
    """`target` (a bundle, or a folder of them) rendered on one machine and on `--scheduler local:2`: a row each
    (its report's device, wall time, the load average at its end, report rows; the serial run's seconds tracing
    references; the cluster's reference tasks, the report fields and the files that differ apart from times)."""
    walls, logs, loads = {}, {}, {}
    for run, cluster in (("one", []), ("two", ["--scheduler", "local:2"])):
        code, walls[run], logs[run] = _run(vdmrender(target, work / name / run, *more, *cluster))
        loads[run] = os.getloadavg()[0]
        assert code == 0, logs[run][-3000:]
    one, two = (json.loads((work / name / run / "report.json").read_text()) for run in ("one", "two"))
    tasks = re.search(r"tracing (\d+) references on the cluster", logs["two"])
    common = {"bundles": name, "options": more}
    return [{**common, "scheduler": None, "device": one["device"], "wall_s": round(walls["one"], 1),
             "load_end": round(loads["one"], 2), "rows": len(one["rows"]),
             "traced_s": round(sum(float(s) for s in re.findall(r"frames traced in ([\d.]+) s", logs["one"])), 1)},
            {**common, "scheduler": "local:2", "device": two["device"], "wall_s": round(walls["two"], 1),
             "load_end": round(loads["two"], 2), "rows": len(two["rows"]),
             "reference_tasks": int(tasks[1]) if tasks else 0, "changed": changed(one, two),
             "differ": differences(work / name / "one", work / name / "two"),
             "files": sum(1 for f in (work / name / "one").rglob("*") if f.is_file())}]


@click.command()
@click.argument("work", type=click.Path(path_type=Path, file_okay=False))
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"), show_default=True)
@click.option("--resolution", default="128x128", show_default=True,
              help="The three small bundles' frame size (vdmrender --resolution); lod-bunny renders at its own.")
@publish.option("cluster")
def main(work: Path, out: Path, resolution: str, publish_dir: Path | None):
    """Bake the three small configs and lod-bunny into WORK, render each on one machine and on a local cluster of
    two workers, then meet each cluster fault; write OUT/cluster.json and OUT/cluster.md (about 25 min on 2 cores)."""
    started = publish.Run("bench.cluster")
    work = work.absolute()
    for folder, configs in (("scenes", CONFIGS), ("large", (LARGE,))):
        (work / folder).mkdir(parents=True, exist_ok=True)
        for c in configs:
            (work / folder / f"{c}.toml").write_text((ROOT / "configs" / f"{c}.toml").read_text())
    code, bake_s, text = _run([str(BIN / "vdmbake"), str(work / "scenes"), "-o", str(work / "bundles"), "--jobs", "2"])
    assert code == 0, text
    code, large_s, text = _run([str(BIN / "vdmbake"), str(work / "large" / f"{LARGE}.toml"), "-o",
                                str(work / f"{LARGE}.bundle")])
    assert code == 0, text
    res = ["--resolution", resolution]
    runs = compared(work, "three small bundles", work / "bundles", res) + \
        compared(work, LARGE, work / f"{LARGE}.bundle", [])
    doc = {"device": runs[0]["device"], "resolution": resolution, "configs": list(CONFIGS), "large": LARGE,
           "bake_s": round(bake_s, 1), "large_bake_s": round(large_s, 1), "timing_files": sorted(TIMING_FILES),
           "runs": runs, "faults": faults(work, work / "bundles", res), "how": __doc__.split("\n\n")[0]}
    out.mkdir(parents=True, exist_ok=True)
    (out / "cluster.json").write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")
    (out / "cluster.md").write_text(tables.cluster(doc))
    click.echo(f"wrote {out / 'cluster.json'}, {out / 'cluster.md'}")
    if publish_dir:
        click.echo(f"published {started.publish(publish_dir, 'cluster', doc)}")


if __name__ == "__main__":
    main()
