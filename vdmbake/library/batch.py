"""Many scenes per call (`vdmbake SCENE_OR_FOLDER... -o OUTDIR`): each scene baked into
OUTDIR/<scene file stem>.bundle, in parallel over local worker processes (`--jobs N`) or on a Dask
cluster (`--scheduler`, vdmbake.cluster). A failing scene never stops the others: its error is its row
of the table. docs/library.md.

The local pool is a handful of long-lived worker processes (spawned, so no thread state is forked),
each given one scene at a time, so the parent always knows which scene a worker holds: a worker that
dies (killed, out of memory) fails only that scene, which is retried once in a fresh worker, and the
pool goes on. Every bundle is written by vdmbake.bake as in a single bake (staged, swapped in whole),
so a worker killed mid-bake leaves no bundle half-written; its staging folder is removed by the next
bake of that target.
"""
from __future__ import annotations

import glob
import multiprocessing
import os
import sys
import time
from collections import deque
from dataclasses import dataclass
from multiprocessing.connection import wait
from pathlib import Path

from ..bundle import staging
from ..bundle.directory import MANIFEST
from ..cluster import WAIT_S, connected, existing, handed_back, handing_back, run_tasks
from ..errors import InputError, escaped, paragraph

GLOB_CHARS = set("*?[")


@dataclass(frozen=True)
class Task:
    scene: str
    out: str
    force: bool = False
    cache: str | None = None         # the part cache's folder (every worker opens it)
    cache_bytes: int | None = None
    verbose: bool = False            # keep the bake's log lines in the result


def default_jobs() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:            # not Linux
        return os.cpu_count() or 1


def expand(args) -> tuple[list[Path], bool]:
    """The scene files the arguments name, in order, without repeats, and whether they ask for a batch: more
    than one argument, a folder (its *.toml, sorted) or a glob pattern (sorted matches)."""
    scenes, batch = [], len(args) > 1
    for a in args:
        p = Path(a)
        if p.is_dir():
            found, batch = sorted(p.glob("*.toml")), True
            if not found:
                raise InputError(f"{p}: the folder holds no scene file (*.toml).")
        elif not p.exists() and GLOB_CHARS & set(str(a)):
            found, batch = [Path(m) for m in sorted(glob.glob(str(a)))], True
            if not found:
                raise InputError(f"{a}: the pattern matches no file.")
        elif not p.exists() and str(a).endswith(("/", os.sep)):
            raise InputError(f"{a}: folder not found (a folder of scene files, *.toml, was named).")
        else:
            found = [p]
        scenes += [f for f in found if f not in scenes]
    return scenes, batch


def targets(scenes: list[Path], outdir: Path) -> list[tuple[Path, Path]]:
    """(scene, OUTDIR/<stem>.bundle) per scene; two scenes of one stem are refused (they would write one bundle)."""
    if (outdir / "manifest.json").is_file():
        raise InputError(f"{outdir}: is a bundle; with several scenes -o names the folder their bundles go to "
                         "(OUTDIR/<scene file stem>.bundle).")
    if outdir.exists() and not outdir.is_dir():
        raise InputError(f"{outdir}: is a file; with several scenes -o names a folder (created if missing).")
    by_stem = {}
    for s in scenes:
        by_stem.setdefault(s.stem, []).append(s)
    clash = {k: v for k, v in by_stem.items() if len(v) > 1}
    if clash:
        stem, files = next(iter(clash.items()))
        raise InputError(f"scenes {', '.join(map(str, files))} would all be baked into {outdir / (stem + '.bundle')}; "
                         "give scene files different names or bake them with separate -o folders.")
    return [(s, outdir / f"{s.stem}.bundle") for s in scenes]


# ------------------------------------------------------------------------------------------- one scene

def bake_one(task: Task) -> dict:
    """Bake one scene; never raises for a bad scene or a system error: the result says `failed` and why. A
    signal (KeyboardInterrupt, vdmbake.signals.Interrupted) still propagates."""
    from ..bake import bake
    from .cache import PartCache

    lines = []
    t0 = time.perf_counter()
    row = {"scene": task.scene, "bundle": task.out, "status": "failed", "parts": 0, "baked": 0, "from_cache": 0,
           "seconds": 0.0, "reason": None, "host": _host(), "pid": os.getpid()}
    try:
        cache = PartCache(task.cache, task.cache_bytes) if task.cache else None
        stats = bake(Path(task.scene), Path(task.out), force=task.force, log=lines.append, cache=cache)
        if stats["up_to_date"]:
            row.update(status="up to date")
        else:
            cached = stats.get("parts_from_cache", 0)
            row.update(status="baked", parts=stats["parts"], baked=stats["parts"] - cached, from_cache=cached,
                       bytes=stats["bytes"], steps_from_cache=stats.get("steps_from_cache", 0),
                       steps_baked=stats.get("steps_baked", 0))
    except InputError as e:
        row["reason"] = paragraph(str(e))
    except OSError as e:
        row["reason"] = paragraph(f"{e.filename + ': ' if isinstance(e.filename, str) else ''}{e.strerror or e} "
                                  f"({type(e).__name__})")
    except Exception as e:                 # a bug, or a library's failure: this scene's row, not the batch's end
        row["reason"] = paragraph(f"internal error {type(e).__name__}: {e}")
    row["seconds"] = round(time.perf_counter() - t0, 3)
    if task.verbose or row["status"] == "failed":
        row["log"] = lines[-40:]
    return row


def _host() -> str:
    import socket

    return socket.gethostname()


# ----------------------------------------------------------------------------------------- local pool

def _worker(conn) -> None:
    """A pool process: bake the tasks it is sent until it is sent None."""
    from .. import signals

    signals.install()
    try:
        from .. import bake  # noqa: F401  (imported once per worker, not in the first scene's seconds)
        while True:
            try:
                task = conn.recv()
            except EOFError:
                return
            if task is None:
                return
            conn.send(bake_one(task))
    except (KeyboardInterrupt, signals.Interrupted) as e:
        os._exit(signals.exit_code(e))


class _Slot:
    def __init__(self, ctx):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child,), daemon=True)
        self.proc.start()
        child.close()
        self.task: tuple[int, Task] | None = None

    def stop(self, term: bool = False) -> None:
        if term and self.proc.is_alive():
            self.proc.terminate()             # SIGTERM: the bake removes its staging folder, exit 143
        else:
            try:
                self.conn.send(None)
            except OSError:
                pass
        self.proc.join(5)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()


def run_local(tasks: list[Task], jobs: int, done) -> list[dict]:
    """Bake `tasks` over `jobs` worker processes; `done(row)` hears each result as it comes. Rows in task order.
    A worker that dies fails its scene's first try only: the scene is tried once more in a fresh worker."""
    ctx = multiprocessing.get_context("spawn")
    todo = deque(enumerate(tasks))
    rows: list[dict | None] = [None] * len(tasks)
    tries = [0] * len(tasks)
    slots: list[_Slot] = []
    try:
        while todo or any(s.task for s in slots):
            while todo and sum(1 for s in slots if s.task) < jobs:
                slot = next((s for s in slots if s.task is None), None)
                if slot is None:
                    slot = _Slot(ctx)
                    slots.append(slot)
                slot.task = todo.popleft()
                tries[slot.task[0]] += 1
                slot.conn.send(slot.task[1])
            busy = [s for s in slots if s.task]
            ready = wait([s.conn for s in busy] + [s.proc.sentinel for s in busy])
            for slot in busy:
                i, task = slot.task
                if slot.conn in ready:
                    try:
                        row = slot.conn.recv()
                    except (EOFError, OSError):
                        row = None
                    if row is not None:
                        slot.task, rows[i] = None, row
                        done(row)
                        continue
                    slot.proc.join(10)                        # the pipe closed: the worker is ending
                if slot.proc.sentinel in ready or not slot.proc.is_alive():
                    slot.proc.join()
                    code = slot.proc.exitcode
                    slots.remove(slot)
                    if tries[i] < 2:
                        todo.appendleft((i, task))            # the same scene, in a fresh worker
                        continue
                    rows[i] = {"scene": task.scene, "bundle": task.out, "status": "failed", "parts": 0, "baked": 0,
                               "from_cache": 0, "seconds": 0.0,
                               "reason": f"its worker process died twice ({_death(code)}); nothing was written"}
                    done(rows[i])
    except BaseException:
        for s in slots:
            s.stop(term=True)
            if s.task:       # a worker killed after the grace (stuck in a C call, or its signal swallowed) left it
                staging.recover(Path(s.task[1].out), MANIFEST)
        raise
    for s in slots:
        s.stop()
    return rows


def _death(code) -> str:
    import signal

    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


# --------------------------------------------------------------------------------------- progress, table

class Progress:
    """A tqdm bar counting scenes on stderr when it is a terminal; otherwise one line per finished scene."""

    def __init__(self, total: int, quiet: bool = False):
        self.total, self.n, self.quiet = total, 0, quiet
        self.bar = None
        if not quiet and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="scenes", unit="scene", file=sys.stderr, dynamic_ncols=True)

    def __call__(self, row: dict) -> None:
        self.n += 1
        if self.quiet:
            return
        line = escaped(f"[{self.n}/{self.total}] {Path(row['scene']).name}: {_status(row)}")   # names are raw input
        for msg in row.get("log") or []:
            line += f"\n    {escaped(msg)}"
        self._say(line)
        if self.bar is not None:
            self.bar.update(1)

    def handed(self, task, worker: str, why: str) -> None:
        """A scene a cluster worker handed back (vdmbake.cluster.run_tasks): said as it happens, as a user waiting
        for another worker would want to know."""
        if not self.quiet:
            self._say(escaped(handing_back(Path(task.scene).name, worker, why)))

    def _say(self, line: str) -> None:
        if self.bar is not None:
            self.bar.write(line, file=sys.stderr)
        else:
            print(line, file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _status(row: dict) -> str:
    if row["status"] == "failed":
        return f"FAILED in {row['seconds']:.2f} s: {row['reason']}"
    if row["status"] == "up to date":
        return "up to date"
    return f"baked {row['parts']} parts ({row['from_cache']} from cache) in {row['seconds']:.2f} s"


def table(rows: list[dict], wall_s: float) -> str:
    """The closing table: scene, status, parts baked / from cache, seconds, the reason of a failure; then totals."""
    head = ("scene", "status", "baked", "cached", "seconds", "reason")
    body = [(escaped(Path(r["scene"]).name), r["status"], str(r.get("baked", 0)), str(r.get("from_cache", 0)),
             f"{r['seconds']:.2f}", escaped(r.get("reason") or handed_back(r))) for r in rows]
    widths = [max(len(x[i]) for x in [head, *body]) for i in range(5)]
    fmt = lambda r: "  ".join(c.ljust(w) if i in (0, 1) else c.rjust(w)  # noqa: E731
                              for i, (c, w) in enumerate(zip(r[:5], widths))) + (f"  {r[5]}" if r[5] else "")
    lines = [fmt(head).rstrip(), fmt(tuple("-" * w for w in widths) + ("",))]
    lines += [fmt(r) for r in body]
    n = {s: sum(r["status"] == s for r in rows) for s in ("baked", "up to date", "failed")}
    baked, cached = sum(r.get("baked", 0) for r in rows), sum(r.get("from_cache", 0) for r in rows)
    lines.append(f"{len(rows)} scenes: {n['baked']} baked, {n['up to date']} up to date, {n['failed']} failed; "
                 f"parts {baked} baked, {cached} from cache"
                 + (f" ({100 * cached / (baked + cached):.0f}%)" if baked + cached else "")
                 + f"; {wall_s:.1f} s wall, {sum(r['seconds'] for r in rows):.1f} s in bakes")
    return "\n".join(lines)


def _failed(task: Task, reason: str) -> dict:
    return {"scene": task.scene, "bundle": task.out, "status": "failed", "parts": 0, "baked": 0, "from_cache": 0,
            "seconds": 0.0, "reason": reason}


def run_dask(tasks: list[Task], address: str, progress: Progress,
             wait_s: float = WAIT_S) -> tuple[list[dict], str, str | None]:
    """Bake `tasks` on the cluster at `address`; `progress` hears each result and each hand-back as it comes.
    Returns the rows in task order, a line describing the cluster, and why the run stopped early (None if it did
    not)."""
    with connected(address, wait_s) as (client, about):
        rows, stopped = run_tasks(client, address, bake_one, tasks, _bake_needs, _failed, progress, wait_s, "vdmbake",
                                  progress.handed)
    return rows, about, stopped


def _bake_needs(task: Task) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """A scene's file to read; the folders its bundle and the part cache go into, to write into."""
    return (task.scene,), tuple(existing(p) for p in [Path(task.out).parent] + ([Path(task.cache)] if task.cache else []))
