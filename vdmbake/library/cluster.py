"""`vdmbake --scheduler ADDRESS`: each scene's bake sent to a Dask distributed cluster (docs/library.md).

ADDRESS is a running scheduler (`tcp://HOST:8786`, started by `dask scheduler`, its workers by
`dask worker tcp://HOST:8786` on each machine), or `local:N`, a LocalCluster of N worker processes of
one thread each on this machine. One task per scene (vdmbake.library.batch.bake_one): its inputs are paths,
its outputs the bundle in the shared output folder and the entries of the shared part cache, and what
comes back is the scene's small result row. A task never raises for a bad scene (its row says
`failed`); a worker that dies mid-task (killed, out of memory, its machine gone) is detected by the
scheduler, which runs the task again on another worker (up to `distributed.scheduler.allowed-failures`,
3 by default, then the scene fails with KilledWorker). The retry is safe: the bundle is staged and
swapped in whole, and cache entries are written to a temporary file and renamed, so a killed task
leaves no torn part, only a hidden staging folder that the retry's bake removes (same machine) and a
temporary file that cache eviction removes after an hour.

A scheduler is input too: `local:N` is bounded as --jobs is; an address where nothing listens is refused
within CONNECT_S (a plain TCP connect first: Dask's own would retry for its 30 s timeout); one where something
else answers is refused as no Dask scheduler; a scheduler lost mid-run ends the run with the scenes not
finished named in the closing table (failed, exit 1), not a traceback. A finished scene's future is released
at once, so a worker lost later does not make the scheduler bake it again.
"""
from __future__ import annotations

import logging
import re
import socket
import uuid
from concurrent.futures import CancelledError
from pathlib import Path

from .batch import Task, bake_one
from ..errors import InputError, escaped

LOCAL = re.compile(r"local:(\d+)")
TCP = re.compile(r"(?:tcp|tls)://\[?([^\]/]+?)\]?:(\d+)/?")
MAX_LOCAL = 1024          # worker processes of local:N, as --jobs allows
CONNECT_S = 5.0           # seconds to wait for a scheduler's address to answer at all
LOST = "scheduler-connection-lost"     # distributed's reason for the futures it cancels when the scheduler is gone


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
                         "with `dask worker ADDRESS` (docs/library.md).") from None


def _quiet_distributed() -> None:
    """Dask's own log (a lost connection, once per future and reconnection try, with tracebacks) kept off the
    tool's output for the rest of the process: what went wrong is in the closing table, and Dask's threads go on
    logging after run_dask returns."""
    for name in ["distributed", "tornado", *logging.root.manager.loggerDict]:
        if name.split(".")[0] in ("distributed", "tornado"):
            logging.getLogger(name).setLevel(logging.CRITICAL)


def _failed(task: Task, reason: str) -> dict:
    return {"scene": task.scene, "bundle": task.out, "status": "failed", "parts": 0, "baked": 0, "from_cache": 0,
            "seconds": 0.0, "reason": reason}


def run_dask(tasks: list[Task], address: str, done) -> tuple[list[dict], str]:
    """Bake `tasks` on the cluster at `address`; `done(row)` hears each result as it comes. Returns the rows in
    task order and a line describing the cluster."""
    Client, LocalCluster, as_completed = _dask()
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
                                 f"({type(e).__name__}: {escaped(str(e)[:200])}); start one with `dask scheduler` and "
                                 "its workers with `dask worker ADDRESS` (docs/library.md).") from None
    except BaseException:
        if cluster is not None:
            cluster.close()
        raise
    try:
        workers = client.scheduler_info().get("workers", {})
        about = f"Dask scheduler {client.scheduler.address}, {len(workers)} workers"
        run = uuid.uuid4().hex[:8]
        futures = {client.submit(bake_one, t, key=f"vdmbake-{run}-{i}-{Path(t.scene).stem}", pure=False): i
                   for i, t in enumerate(tasks)}
        rows: list[dict | None] = [None] * len(tasks)
        for fut in as_completed(list(futures)):
            i = futures.pop(fut)
            try:
                row = fut.result()
            except CancelledError as e:
                if getattr(e, "reason", None) == LOST:
                    break
                row = _failed(tasks[i], f"on the cluster: cancelled ({getattr(e, 'reason', e)})")
            except Exception as e:          # KilledWorker after the allowed retries, a worker without vdmbake
                row = _failed(tasks[i], f"on the cluster: {type(e).__name__}: {e}")
            finally:
                fut.release()               # finished: a worker lost later does not make the scheduler bake it again
            rows[i] = row
            done(row)
        for i, row in enumerate(rows):
            if row is None:                 # the scheduler was lost: what had not finished is named as such
                rows[i] = _failed(tasks[i], f"not finished: the connection to the Dask scheduler {address} was lost")
                done(rows[i])
        return rows, about
    finally:
        client.close(timeout=CONNECT_S)
        if cluster is not None:
            cluster.close()
