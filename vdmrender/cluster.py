"""`vdmrender --scheduler ADDRESS` (docs/cluster.md): bundles rendered on a Dask cluster, one task per bundle.

Each task is vdmrender.many.render_one on a worker: the whole bundle rendered as alone, with the worker's own GL
context on its own device (VDM_GL_DEVICE in the worker's environment, or --device for every worker), into its
folder inside OUT's staging folder on the shared disk. So the times compared in one decision (a sweep's
interleaved pricing, an LOD chain, a row's ratio to its baseline technique) all come from one device; the
combined report names each run's device and worker, and several devices in its `device`, so that --baseline
compares no times across devices unless --compare-devices. Everything but the timings is what a run on one
machine writes (tests/test_render_cluster.py). One bundle given alone is rendered by one worker into OUT.

The cluster itself (the address checked, the bounded wait for workers, a task handed back by a worker that
cannot see the shared folders, tasks stopped when the scheduler is lost, a killed worker's task run again) is
vdmbake's (vdmbake.cluster); a run the cluster stopped still writes the combined report of what
finished, and the command exits 2."""
from __future__ import annotations

import os
from functools import partial
from pathlib import Path

from vdmbake.errors import InputError
from vdmbake.cluster import WAIT_S, connected, existing, run_tasks

from . import many
from .render import run


def run_many(paths: list[Path], out: Path, opts, log, address: str, wait_s: float = WAIT_S) -> dict:
    """vdmrender.many.run_many with each bundle a task on the cluster at `address`."""
    def on(jobs: list[many.Job], staged):
        with connected(address, wait_s) as (client, about):
            log(f"rendering {len(jobs)} bundles into {staged.path} on {about}")
            count = iter(range(1, len(jobs) + 1))

            def done(entry):
                r = entry["run"]
                log(f"[{next(count)}/{len(jobs)}] {r['scene']}: {r['status']}"
                    + (f" on {entry['worker']}" if entry.get("worker") else "") + (f": {r['reason']}" if r["reason"] else ""))
            entries, stopped = run_tasks(client, address, partial(_here, os.getcwd(), many.render_one), jobs, _needs,
                                         _failed, done, wait_s, "vdmrender")
        for e in entries:       # where each ran, in its runs entry (report.json, runs.md)
            e["run"].update({k: e[k] for k in ("worker", "handed_back") if k in e})
        return entries, stopped
    return many.run_many(paths, out, opts, log, on)


def run_one(path: Path, out: Path, opts, log, address: str, wait_s: float = WAIT_S) -> dict:
    """One bundle into `out`, as vdmrender.render.run, by a worker of the cluster at `address`."""
    job = many.Job(str(path), str(out), "", opts)
    with connected(address, wait_s) as (client, about):
        log(f"rendering {path} into {out} on {about}")
        (answer,), stopped = run_tasks(client, address, partial(_here, os.getcwd(), _alone), [job], _needs,
                                       lambda j, why: {"error": why}, lambda a: None, wait_s, "vdmrender")
    if stopped or "error" in answer:
        raise InputError(f"--scheduler {address}: {answer['error']}"
                         + (f" (on {answer['worker']})" if answer.get("worker") else ""))
    log(f"{path}: rendered on {answer['worker']}")
    return answer["result"]


def _here(cwd: str, fn, job: many.Job) -> dict:
    """fn(job) in the client's working folder, so that the paths it was given mean what they mean there, and the
    reports say them as a run on one machine does (a worker runs one task at a time: --nthreads 1)."""
    os.chdir(cwd)
    return fn(job)


def _alone(job: many.Job) -> dict:
    """run() on a worker; its error as the answer ({"error": paragraph}), to be raised again on the client."""
    try:
        return {"result": run(Path(job.bundle), Path(job.out), job.opts)}
    except Exception as e:
        return {"error": str(e) if isinstance(e, InputError) else f"{type(e).__name__}: {e}"}


def _needs(job: many.Job) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """A bundle's manifest to read; the folder its run's folder goes into, to write into (both as the client's
    working folder makes them absolute: the worker's check comes before _here)."""
    return (str(Path(job.bundle, "manifest.json").absolute()), os.getcwd()), (existing(Path(job.out).parent),)


def _failed(job: many.Job, reason: str) -> dict:
    return {"run": {"scene": many.name(Path(job.bundle)), "bundle": job.bundle, "status": "failed", "rows": 0,
                    "seconds": 0.0, "reason": reason}, "rows": []}
