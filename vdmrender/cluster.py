"""`vdmrender --scheduler ADDRESS` (docs/cluster.md): bundles rendered on a Dask cluster, in two rounds of tasks.

First every reference the runs trace (vdmrender.render.references: each object's at each size of its sweep and at
its own cameras, filtered and pixel-centre, and the composite's), one task each, traced on any worker into the
reference cache by content key (refcache.Shared: --reference-cache, or by default a hidden sibling of OUT removed
at the end) on the shared disk; a reference the run folder being replaced already holds is not traced. Then one
task per bundle, vdmrender.many.render_one on a worker: the whole bundle rendered as alone, with the worker's own GL
context on its own device (VDM_GL_DEVICE in the worker's environment, or --device for every worker), into its folder
inside OUT's staging folder, finding every reference in the cache. So a bundle's CPU-heavy reference spreads over
the workers, while every GL time of a bundle (a sweep's interleaved pricing, an LOD chain, a row's ratio to its
baseline technique: compared within the bundle) comes from one device; the combined report names each run's device
and worker, and several devices in its `device`, so that --baseline compares no times across devices unless
--compare-devices. Everything but the timings is what a run on one machine writes (tests/test_render_cluster.py).
One bundle given alone is rendered by one worker into OUT.

The cluster itself (the address checked, the bounded wait for workers, a task handed back by a worker that
cannot see the shared folders, tasks stopped when the scheduler is lost, a killed worker's task run again) is
vdmbake's (vdmbake.cluster); a run the cluster stopped still writes the combined report of what
finished, and the command exits 2. A reference task that fails leaves its reference to the bundle's own task."""
from __future__ import annotations

import dataclasses
import os
import uuid
from contextlib import contextmanager
from functools import partial
from pathlib import Path

from vdmbake.bundle import budget as memory
from vdmbake.bundle.directory import Bundle
from vdmbake.bundle.staging import StagedDir
from vdmbake.errors import InputError, paragraph
from vdmbake.cluster import WAIT_S, connected, existing, handed_back, handing_back, run_tasks

from . import many, render
from .tracing import refcache
from .render import run


def run_many(paths: list[Path], out: Path, opts, log, address: str, wait_s: float = WAIT_S) -> dict:
    """vdmrender.many.run_many with each bundle a task on the cluster at `address`."""
    def on(jobs: list[many.Job], staged):
        with connected(address, wait_s) as (client, about), shared_cache(out, opts.reference_cache) as cache:
            log(f"rendering {len(jobs)} bundles into {staged.path} on {about}")
            jobs = [dataclasses.replace(j, opts=dataclasses.replace(j.opts, reference_cache=cache)) for j in jobs]
            stopped = trace_references(client, address, jobs, wait_s, log)
            if stopped:
                return [_failed(j, f"not finished: {stopped}") for j in jobs], stopped
            count = iter(range(1, len(jobs) + 1))

            def done(entry):
                r = entry["run"]
                log(f"[{next(count)}/{len(jobs)}] {r['scene']}: {r['status']}"
                    + (f" on {entry['worker']}" if entry.get("worker") else "") + (f": {r['reason']}" if r["reason"] else ""))
            entries, stopped = run_tasks(client, address, partial(_here, os.getcwd(), many.render_one), jobs, _needs,
                                         _failed, done, wait_s, "vdmrender",
                                         lambda j, worker, why: log(handing_back(j.bundle, worker, why)))
        for e in entries:       # where each ran, in its runs entry (report.json, runs.md)
            e["run"].update({k: e[k] for k in ("worker", "handed_back") if k in e})
        return entries, stopped
    return many.run_many(paths, out, opts, log, on)


def run_one(path: Path, out: Path, opts, log, address: str, wait_s: float = WAIT_S) -> dict:
    """One bundle into `out`, as vdmrender.render.run, by a worker of the cluster at `address`."""
    with connected(address, wait_s) as (client, about), shared_cache(out, opts.reference_cache) as cache:
        log(f"rendering {path} into {out} on {about}")
        job = many.Job(str(path), str(out), str(out), dataclasses.replace(opts, reference_cache=cache))
        stopped = trace_references(client, address, [job], wait_s, log)
        answer = {"error": stopped}
        if not stopped:
            (answer,), stopped = run_tasks(client, address, partial(_here, os.getcwd(), _alone), [job], _needs,
                                           lambda j, why: {"error": why}, lambda a: None, wait_s, "vdmrender")
    if stopped or "error" in answer:
        raise InputError(f"--scheduler {address}: {answer['error']}"
                         + (f" (on {answer['worker']})" if answer.get("worker") else ""))
    log(f"{path}: rendered on {answer['worker']}")
    return answer["result"]


@contextmanager
def shared_cache(out: Path, given: refcache.Shared | None):
    """The reference cache of a cluster run: `given` (--reference-cache), else a hidden sibling of OUT on the shared
    disk (staged as an output folder is: `.OUT.references.tmp-HOST-PID`, with its lease), removed after the run."""
    if given is not None:
        yield given
        return
    scratch = StagedDir(Path(out).absolute().with_name(Path(out).name + ".references"), "", "reference cache")
    try:
        yield refcache.Shared(str(scratch.tmp), uuid.uuid4().hex)
    finally:
        scratch.abort()      # never committed: the references went into the run folders


@dataclasses.dataclass(frozen=True)
class Trace:
    """A reference task: reference `folder` of a bundle's run (render.references': its view set, at `spp`),
    traced into opts.reference_cache under `key`, unless the run folder being replaced (`previous`) holds it."""
    bundle: str
    previous: str
    opts: object
    view: render.ViewSet
    folder: str
    spp: int
    key: str


def trace_references(client, address: str, jobs: list[many.Job], wait_s: float, log) -> str | None:
    """The first round: every reference of the runs of `jobs` traced on the cluster, each key once; why the run
    stopped, or None. A bundle that cannot be opened or is refused as input has none here: its own task says why."""
    tasks = {}
    for job in jobs:
        try:
            bundle = Bundle(Path(job.bundle))
            wanted = render.references(bundle, job.opts)
        except Exception:       # the bundle's render task meets the same error and reports it
            continue
        for view, folder, spp in wanted:
            key = view.source(bundle, bundle.scene, spp)[0]
            tasks.setdefault(key, Trace(job.bundle, job.previous, job.opts, view, folder, spp, key))
    if not tasks:
        return None
    log(f"tracing {len(tasks)} references on the cluster into {jobs[0].opts.reference_cache.folder}")
    count = iter(range(1, len(tasks) + 1))

    def done(row):
        log(f"[{next(count)}/{len(tasks)}] reference {row['reference']}: {row['status']}"
            + (f" on {row['worker']}" if row.get("worker") else "")
            + (f" in {row['trace_s']:.2f} s" if "trace_s" in row else "")
            + (f": {row['reason']}" if row.get("reason") else "")
            + (f" ({handed_back(row)})" if row.get("handed_back") else ""))
    _, stopped = run_tasks(client, address, partial(_here, os.getcwd(), _trace), list(tasks.values()), _trace_needs,
                           lambda t, why: {"reference": _named(t), "status": "failed", "reason": why}, done, wait_s,
                           "reference", lambda t, worker, why: log(handing_back(f"reference {_named(t)}", worker, why)))
    return stopped


def _named(task: Trace) -> str:
    return f"{many.name(Path(task.bundle))}/{task.folder}"


def _trace(task: Trace) -> dict:
    """A reference task on a worker: {"reference", "status": traced, in the cache, in the previous run's folder, or
    failed (and why: the bundle's task then traces it itself)}."""
    row = {"reference": _named(task)}
    if refcache.previously(Path(task.previous), task.folder, task.key, len(task.view.cams)):
        return {**row, "status": "in the previous run's folder"}
    try:
        bundle = Bundle(Path(task.bundle))
        scene = bundle.scene
        opts = render.filtering(task.opts, scene)
        memory.check_render(render.memory_need(bundle, *(opts.resolution or scene.render.resolution), opts))
        key, trace = task.view.source(bundle, scene, task.spp)
        info = refcache.share(task.opts.reference_cache, key, task.view.cams, trace, task.view.named(task.spp))
    except Exception as e:
        return {**row, "status": "failed", "reason": paragraph(str(e) if isinstance(e, InputError)
                                                               else f"{type(e).__name__}: {e}")}
    return {**row, "status": "in the cache"} if info is None else {**row, "status": "traced", "trace_s": info["trace_s"]}


def _trace_needs(task: Trace) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The bundle's manifest to read; the reference cache to write into (absolute, as _needs')."""
    return (str(Path(task.bundle, "manifest.json").absolute()), os.getcwd()), \
        (existing(Path(task.opts.reference_cache.folder)),)


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
