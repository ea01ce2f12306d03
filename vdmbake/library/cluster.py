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
"""
from __future__ import annotations

import logging
import re
import uuid
from pathlib import Path

from .batch import Task, bake_one
from ..errors import InputError

LOCAL = re.compile(r"local:(\d+)")


def _dask():
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise InputError("--scheduler needs Dask's distributed scheduler, which is not installed; install the "
                         "extra: pip install 'vdmbake[cluster]' (or pip install 'dask[distributed]').") from None
    return Client, LocalCluster, as_completed


def check_address(address: str) -> str:
    m = LOCAL.fullmatch(address)
    if m and int(m[1]) < 1:
        raise InputError(f"--scheduler {address}: local:N needs N >= 1 worker processes.")
    if not m and address.startswith("local"):
        raise InputError(f"--scheduler {address!r}: write local:N (N worker processes on this machine), or a "
                         "scheduler's address such as tcp://HOST:8786.")
    return address


def run_dask(tasks: list[Task], address: str, done) -> tuple[list[dict], str]:
    """Bake `tasks` on the cluster at `address`; `done(row)` hears each result as it comes. Returns the rows in
    task order and a line describing the cluster."""
    Client, LocalCluster, as_completed = _dask()
    check_address(address)
    cluster = None
    m = LOCAL.fullmatch(address)
    try:
        if m:
            cluster = LocalCluster(n_workers=int(m[1]), threads_per_worker=1, processes=True, dashboard_address=None,
                                   silence_logs=logging.ERROR)
            client = Client(cluster)
        else:
            try:
                client = Client(address, timeout="30s")
            except (OSError, TimeoutError, ValueError) as e:
                raise InputError(f"--scheduler {address}: cannot reach the Dask scheduler ({e}); start one with "
                                 "`dask scheduler` and its workers with `dask worker ADDRESS` (docs/library.md).") \
                    from None
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
        for fut in as_completed(futures):
            i = futures[fut]
            try:
                row = fut.result()
            except Exception as e:          # KilledWorker after the allowed retries, a worker without vdmbake
                t = tasks[i]
                row = {"scene": t.scene, "bundle": t.out, "status": "failed", "parts": 0, "baked": 0,
                       "from_cache": 0, "seconds": 0.0, "reason": f"on the cluster: {type(e).__name__}: {e}"}
            rows[i] = row
            done(row)
        return rows, about
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
