"""Issue 41's closing figures: three small bundles (at --resolution) and configs/lod-bunny.toml's one bundle (at its
own resolution: its references split over the workers) rendered on one machine and on a local Dask cluster of two
workers (same files apart from the times, and the wall time of each), and each cluster fault as the user meets it
(what the command prints, its exit code, its time). Writes docs/results/cluster.json (docs/cluster.md's tables).

    python -m bench.cluster WORK [--resolution 128x128]

Also the helpers the cluster tests share: a `dask scheduler` and workers on the loopback, and the comparison of
two output folders apart from what is timing."""
from __future__ import annotations

import argparse
import contextlib
import csv
import datetime
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

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


def _said(text: str, *needles: str) -> str:
    """The lines of `text` that hold a needle, joined, for a table cell."""
    lines = [ln.strip() for ln in text.splitlines() if any(n in ln for n in needles)]
    return " / ".join(dict.fromkeys(lines)).replace("|", "\\|")


def _closed_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def faults(work: Path, bundles: Path, res: list[str]) -> list[list[str]]:
    rows = []
    render = [str(BIN / "vdmrender"), str(bundles), "--no-flip", *res]

    port = _closed_port()
    code, s, text = _run(render + ["-o", str(work / "f1"), "--scheduler", f"tcp://127.0.0.1:{port}"])
    rows.append(["nothing listens at the address", f"`--scheduler tcp://127.0.0.1:{port}`", str(code), f"{s:.1f} s",
                 _said(text, "error")])
    with scheduler(work) as (address, _):
        code, s, text = _run(render + ["-o", str(work / "f2"), "--scheduler", address, "--workers-wait", "5"])
    rows.append(["a scheduler without workers", "`--scheduler ADDRESS --workers-wait 5`", str(code), f"{s:.1f} s",
                 _said(text, "error")])

    out = work / "f3"
    with scheduler(work) as (address, sched):
        w = worker(address)
        try:
            p = subprocess.Popen(render + ["-o", str(out), "--scheduler", address], stdout=subprocess.PIPE,
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
    rows.append(["the scheduler killed mid-run (one worker)", "`--scheduler ADDRESS`, scheduler SIGKILL",
                 str(p.returncode), f"{client_s:.1f} s to exit after the kill (the worker: {worker_s:.1f} s)",
                 _said(said + stdout + stderr, "| failed", "| rendered", "error")])

    out = work / "f4"
    t0 = time.perf_counter()
    p = subprocess.Popen(render + ["-o", str(out), "--scheduler", "local:2"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=ENV)
    pid, _ = rendering(out, CONFIGS[1], p)
    os.kill(pid, signal.SIGKILL)
    stdout, stderr = p.communicate(timeout=1200)
    runs = json.loads((out / "report.json").read_text())["runs"]
    rows.append(["a worker killed mid-render (local:2)", f"`--scheduler local:2`, SIGKILL to the worker rendering "
                 f"{CONFIGS[1]}", str(p.returncode), f"{time.perf_counter() - t0:.1f} s",
                 f"{sum(r['status'] == 'rendered' for r in runs)} of {len(runs)} bundles rendered, "
                 f"{len(list(out.rglob('.*')))} hidden files left"])

    p, stdout, stderr, s = beside_a_blind_worker(render + ["-o", str(work / "f5")], bundles, work, len(CONFIGS), 1200)
    rows.append(["a worker that cannot see the bundles (its own mount namespace), a second one joining",
                 "`--scheduler ADDRESS`", str(p.returncode), f"{s:.1f} s", _said(stdout + stderr, "| rendered", "| failed")])
    return rows


def _compared(work: Path, name: str, target: Path, more: list[str]) -> list[list[str]]:
    """`target` (a bundle, or a folder of them) rendered on one machine and on `--scheduler local:2`: a table row
    each (wall time, the load average at its end, the reference tasks; the cluster's: what differs apart from
    times)."""
    walls, logs, loads = {}, {}, {}
    for run, cluster in (("one", []), ("two", ["--scheduler", "local:2"])):
        code, walls[run], logs[run] = _run([str(BIN / "vdmrender"), str(target), "-o", str(work / name / run),
                                            "--no-flip", *more, *cluster])
        loads[run] = os.getloadavg()[0]
        assert code == 0, logs[run][-3000:]
    one, two = (json.loads((work / name / run / "report.json").read_text()) for run in ("one", "two"))
    diff = differences(work / name / "one", work / name / "two")
    fields = changed(one, two)
    files = sum(1 for f in (work / name / "one").rglob("*") if f.is_file())
    traced = sum(float(s) for s in re.findall(r"frames traced in ([\d.]+) s", logs["one"]))
    tasks = re.search(r"tracing (\d+) references on the cluster", logs["two"])
    what = f"{name} (`{' '.join(more)}`)" if more else name
    return [[what, "one machine", f"{walls['one']:.1f} s", f"{loads['one']:.1f}", str(len(one["rows"])),
             f"- ({traced:.1f} s of it tracing references)", "-", "-"],
            [what, "`--scheduler local:2`", f"{walls['two']:.1f} s", f"{loads['two']:.1f}", str(len(two["rows"])),
             f"{tasks[1] if tasks else 0} reference tasks", "all" if not fields else f"NO: {', '.join(fields[:5])}",
             f"{len(diff)} of {files}" + (f" ({', '.join(diff[:5])})" if diff else "")]]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("work", type=Path)
    ap.add_argument("--resolution", default="128x128")
    args = ap.parse_args(argv)
    work = args.work.absolute()
    for folder, configs in (("scenes", CONFIGS), ("large", (LARGE,))):
        (work / folder).mkdir(parents=True, exist_ok=True)
        for c in configs:
            (work / folder / f"{c}.toml").write_text((ROOT / "configs" / f"{c}.toml").read_text())
    code, bake_s, text = _run([str(BIN / "vdmbake"), str(work / "scenes"), "-o", str(work / "bundles"), "--jobs", "2"])
    assert code == 0, text
    code, large_s, text = _run([str(BIN / "vdmbake"), str(work / "large" / f"{LARGE}.toml"), "-o",
                                str(work / f"{LARGE}.bundle")])
    assert code == 0, text
    res = ["--resolution", args.resolution]
    table = _compared(work, "three small bundles", work / "bundles", res) + \
        _compared(work, LARGE, work / f"{LARGE}.bundle", [])
    doc = {"about": "docs/cluster.md's measured tables (bench/cluster.py)",
           "measured_by": f"python -m bench.cluster WORK --resolution {args.resolution} (the small bundles: configs "
                          f"{', '.join(CONFIGS)}, baked with --jobs 2 in {bake_s:.0f} s; {LARGE} baked in "
                          f"{large_s:.0f} s)",
           "device": "llvmpipe on the project's shared 2-core machine, shared with other jobs (the load average at "
                     "the end of each run beside it): every worker and the serial run on the same two CPUs",
           "when": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
           "tables": {
               "serial-vs-cluster": {
                   "header": ["bundles", "run", "wall", "load average (1 min) at its end", "rows", "references",
                              "reports (rows, sweep, chains) the same apart from times",
                              f"files that differ (apart from {', '.join(sorted(TIMING_FILES))})"],
                   "align": ["---", "---", "---:", "---:", "---:", "---", "---", "---"], "rows": table},
               "faults": {
                   "header": ["fault", "command", "exit", "wall", "what it prints (the lines that say)"],
                   "align": ["---", "---", "---:", "---", "---"], "rows": faults(work, work / "bundles", res)}}}
    (ROOT / "docs" / "results" / "cluster.json").write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")
    print(json.dumps(doc, indent=1, ensure_ascii=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
