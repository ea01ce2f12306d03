"""`--scheduler ADDRESS`: vdmbake's scenes and vdmrender's bundles sent to a Dask distributed cluster
(docs/cluster.md), one mechanism for both tools.

ADDRESS is a running scheduler (`tcp://HOST:8786`, started by `dask scheduler`, its workers by
`dask worker tcp://HOST:8786` on each machine), or `local:N`, a LocalCluster of N worker processes of
one thread each on this machine's loopback. One task per scene or bundle (run_tasks): its inputs are paths,
its outputs staged folders on the shared disk (vdmbake.bundle.staging), and what comes back is its small
result row. A task never raises for bad input (its row says `failed`); a worker that dies mid-task (killed,
out of memory, its machine gone) is detected by the scheduler, which runs the task again on another worker
(up to `distributed.scheduler.allowed-failures`, 3 by default, then the task fails with KilledWorker). The
retry is safe: outputs are staged and swapped in whole, so a killed task leaves only a hidden staging folder
that a later run at that target removes (vdmbake.bundle.staging: its process gone, or its lease stale).

Faults are bounded. The address is input: `local:N` is bounded as --jobs is; an address where nothing
listens is refused within CONNECT_S (a plain TCP connect first: Dask's own would retry for its 30 s
timeout); one where something else answers is refused as no Dask scheduler; so is a scheduler without
workers for --workers-wait seconds (InputError, exit 2), and later in the run such a wait stops it. A worker
that cannot read a task's inputs or write its output folder hands the task back, and it runs on the other
workers (the row names who handed it back). A scheduler lost mid-run ends the run with what finished and
what did not in the closing table (`stopped`), and each worker, which closes when it loses its scheduler,
stops its task (SchedulerLost raised in the task's thread, so its staging folder is removed) instead of
working on for the nanny's 30 s. A finished task's future is released at once, so a worker lost later does
not make the scheduler run it again.
"""
from __future__ import annotations

import ctypes
import logging
import os
import re
import socket
import threading
import time
import uuid
from concurrent.futures import CancelledError
from contextlib import contextmanager
from pathlib import Path

from .errors import InputError, cut, escaped

LOCAL = re.compile(r"local:(\d+)")
TCP = re.compile(r"(?:tcp|tls)://\[?([^\]/]+?)\]?:(\d+)/?")
MAX_LOCAL = 1024          # worker processes of local:N, as --jobs allows
CONNECT_S = 5.0           # seconds to wait for a scheduler's address to answer at all
WAIT_S = 60.0             # --workers-wait: seconds a scheduler may have no worker
POLL_S = 0.25             # how often a task's worker and the client's scheduler are looked at
LOST = "scheduler-connection-lost"     # distributed's reason for the futures it cancels when the scheduler is gone
HAND_BACK = "hand_back"   # a task's answer when its worker cannot read its inputs


class SchedulerLost(BaseException):
    """Raised in a task's thread when its worker stops (its scheduler lost, or the worker closed): the task's
    cleanup runs (`except BaseException`: its staging folder removed) and its work ends."""


def _dask():
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise InputError("--scheduler needs Dask's distributed scheduler, which is not installed; install the "
                         "extra: pip install 'vdmbake[cluster]' (or pip install 'dask[distributed]').") from None
    return Client, LocalCluster, as_completed


def check_address(address: str) -> str:
    m = LOCAL.fullmatch(address)
    if m and not 1 <= int(m[1]) <= MAX_LOCAL:
        raise InputError(f"--scheduler {address}: local:N needs 1 to {MAX_LOCAL} worker processes (as --jobs).")
    if not m and address.startswith("local"):
        raise InputError(f"--scheduler {address!r}: write local:N (N worker processes on this machine), or a "
                         "scheduler's address such as tcp://HOST:8786.")
    return address


def _reachable(address: str) -> None:
    """Refuse within CONNECT_S a tcp:// or tls:// address where nothing accepts a connection."""
    m = TCP.fullmatch(address)
    if not m:
        return                                   # another transport: Dask's own connect says
    try:
        socket.create_connection((m[1], int(m[2])), timeout=CONNECT_S).close()
    except (OSError, ValueError, OverflowError) as e:       # refused, no such host, a port past 65535
        raise InputError(f"--scheduler {escaped(address)}: cannot reach the Dask scheduler "
                         f"({getattr(e, 'strerror', None) or e}); start one with `dask scheduler` and its workers "
                         "with `dask worker ADDRESS` (docs/cluster.md).") from None


def _quiet_distributed() -> None:
    """Dask's own log (a lost connection, once per future and reconnection try, with tracebacks) kept off the
    tool's output for the rest of the process: what went wrong is in the closing table, and Dask's threads go on
    logging after run_dask returns."""
    for name in ["distributed", "tornado", *logging.root.manager.loggerDict]:
        if name.split(".")[0] in ("distributed", "tornado"):
            logging.getLogger(name).setLevel(logging.CRITICAL)


@contextmanager
def connected(address: str, wait_s: float = WAIT_S):
    """A Dask client of the cluster at `address` (a LocalCluster for local:N) with at least one worker, and a
    line describing it; closed after."""
    Client, LocalCluster, _ = _dask()
    check_address(address)
    _quiet_distributed()
    cluster = None
    m = LOCAL.fullmatch(address)
    try:
        if m:
            cluster = LocalCluster(n_workers=int(m[1]), threads_per_worker=1, processes=True, dashboard_address=None,
                                   host="127.0.0.1", silence_logs=logging.ERROR)     # this machine's loopback only
            client = Client(cluster)
        else:
            _reachable(address)
            try:
                client = Client(address, timeout="30s")
            except Exception as e:              # another service there: Dask reads its answer as frames
                raise InputError(f"--scheduler {escaped(address)}: no Dask scheduler answers there "
                                 f"({type(e).__name__}: {cut(str(e))}); start one with `dask scheduler` and "
                                 "its workers with `dask worker ADDRESS` (docs/cluster.md).") from None
    except BaseException:
        if cluster is not None:
            cluster.close()
        raise
    try:
        try:
            client.wait_for_workers(1, timeout=wait_s)
        except Exception:                       # dask's TimeoutError, or the scheduler gone meanwhile
            raise InputError(f"--scheduler {escaped(address)}: no Dask worker joined the scheduler within {wait_s:g} s "
                             f"(--workers-wait); start workers with `dask worker {escaped(address)}` "
                             "(docs/cluster.md).") from None
        workers = client.scheduler_info(n_workers=-1).get("workers", {})
        yield client, f"Dask scheduler {client.scheduler.address}, {len(workers)} workers"
    finally:
        client.close(timeout=CONNECT_S)
        if cluster is not None:
            cluster.close()


# ------------------------------------------------------------------------------------------ on a worker

def _watch(worker, thread: int, done: threading.Event) -> None:
    """Stop the task on `thread` once its worker is no longer running (it closes when its scheduler is lost)."""
    from distributed.core import Status

    while not done.wait(POLL_S):
        if worker.status not in (Status.running, Status.paused):
            ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread), ctypes.py_object(SchedulerLost))
            return


def on_worker(fn, task, readable: tuple[str, ...], writable: tuple[str, ...]) -> dict:
    """What a worker runs: fn(task)'s row with the worker's address, or, where this worker cannot read a path of
    `readable` or write into a folder of `writable` (the shared folders not mounted here), {HAND_BACK: why}."""
    from distributed import get_worker

    worker = get_worker()
    for paths, mode, what in ((readable, os.R_OK, "read"), (writable, os.W_OK | os.X_OK, "write into")):
        for path in paths:
            if not os.access(path, mode):
                return {HAND_BACK: f"cannot {what} {path}", "worker": worker.address}
    done = threading.Event()
    threading.Thread(target=_watch, args=(worker, threading.get_ident(), done), daemon=True).start()
    try:
        row = fn(task)
    finally:
        done.set()
    return {**row, "worker": worker.address}


# ----------------------------------------------------------------------------------------- on the client

def run_tasks(client, address: str, fn, tasks: list, needs, failed, done, wait_s: float = WAIT_S,
              name: str = "task", handed=lambda task, worker, why: None) -> tuple[list[dict], str | None]:
    """fn(task) for every task on the cluster; `needs(task)` -> (paths to read, folders to write into) on the
    worker; `failed(task, reason)` is the row of one that could not run; `done(row)` hears each row as it
    comes, `handed(task, worker, why)` each hand-back. A task handed back goes to the workers that have not
    handed it back, waiting up to `wait_s` for one to join. Returns the rows in task order and, when the run stopped early (the scheduler lost, or no worker for
    `wait_s`), why: the tasks not finished then are failed with that reason."""
    *_, as_completed = _dask()
    run = uuid.uuid4().hex[:8]
    refused: list[list[tuple[str, str]]] = [[] for _ in tasks]     # per task, (worker, why) of who handed it back
    futures, parked = {}, {}              # future: task; task handed back by every worker there is: since when
    pending = as_completed()
    rows: list[dict | None] = [None] * len(tasks)

    def submit(i, workers=None):
        fut = client.submit(on_worker, fn, tasks[i], *needs(tasks[i]), key=f"{name}-{run}-{i}-{len(refused[i])}",
                            pure=False, workers=workers, allow_other_workers=False)
        futures[fut] = i
        pending.add(fut)

    def finish(i, row):
        if refused[i]:
            row["handed_back"] = [f"{w} ({why})" for w, why in refused[i]]
        rows[i] = row
        done(row)

    for i in range(len(tasks)):
        submit(i)
    stopped, alone_since = None, None
    while (futures or parked) and stopped is None:
        for i, since in list(parked.items()):     # a worker that may see the shared folders joined, or none in time
            others = sorted(set(_workers(client)) - {w for w, _ in refused[i]})
            if others or time.monotonic() - since > wait_s:
                del parked[i]
                if others:
                    submit(i, others)
                else:
                    finish(i, failed(tasks[i], "no worker could read its inputs or write its output: "
                                     + "; ".join(f"{w} {why}" for w, why in refused[i])))
        if not pending.has_ready():
            stopped, alone_since = _alone(client, address, wait_s, alone_since)
            time.sleep(POLL_S)
            continue
        fut = next(pending)
        i = futures.pop(fut)
        try:
            row = fut.result()
        except CancelledError as e:
            if getattr(e, "reason", None) == LOST:
                stopped = f"the connection to the Dask scheduler {address} was lost"
                break
            row = failed(tasks[i], f"on the cluster: cancelled ({getattr(e, 'reason', e)})")
        except Exception as e:          # KilledWorker after the allowed retries, a worker without the tool
            row = failed(tasks[i], f"on the cluster: {type(e).__name__}: {e}")
        finally:
            fut.release()               # finished: a worker lost later does not make the scheduler run it again
        if HAND_BACK in row:            # this worker cannot see the shared folders: another may
            refused[i].append((row["worker"], row[HAND_BACK]))
            handed(tasks[i], row["worker"], row[HAND_BACK])
            parked[i] = time.monotonic()
            continue
        finish(i, row)
    for i, row in enumerate(rows):
        if row is None:                 # stopped: what had not finished is named as such
            finish(i, failed(tasks[i], f"not finished: {stopped}"))
    return rows, stopped


def _workers(client) -> list[str]:
    try:
        return list(client.scheduler_info(n_workers=-1).get("workers", {}))
    except Exception:                   # the scheduler gone: the futures' cancellation says so
        return []


def _alone(client, address: str, wait_s: float, since: float | None) -> tuple[str | None, float | None]:
    """(why the run stops, or None; since when the scheduler has had no worker, or None)."""
    if _workers(client):
        return None, None
    since = since or time.monotonic()
    if time.monotonic() - since > wait_s:
        return f"no Dask worker on the scheduler {address} for {wait_s:g} s (--workers-wait)", since
    return None, since


def handed_back(row: dict) -> str:
    """Which cluster workers handed the task back, unable to read its inputs (run_tasks)."""
    return f"handed back by {', '.join(row['handed_back'])}" if row.get("handed_back") else ""


def handing_back(what: str, worker: str, why: str) -> str:
    """The line said as a task is handed back (run_tasks' `handed`), while the run waits for another worker."""
    return f"{what}: handed back by {worker} ({why}); another worker may take it"


def existing(path: Path) -> str:
    """The nearest folder at or above `path` that exists (where a task makes the rest)."""
    path = Path(path).absolute()
    while not path.exists() and path.parent != path:
        path = path.parent
    return str(path)
