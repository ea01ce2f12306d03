"""Alternatives measured against each other in one process, interleaved (vdmrender.measuring.interleaved, the loop
vdmrender's pricing times with), for the benchmarks: on a shared machine a sequential run gives each variant
different neighbours. Per frame,
the GPU time of its passes by timer queries (vdmrender/measuring/timing.py, as vdmrender reports it), the wall
time and the process's CPU time (llvmpipe's rasteriser threads are the process's own, so CPU time is
the work done, much less disturbed by other processes than wall time), and each variant's
error against the reference frames of a previous vdmrender run. Also each variant's device-independent
costs (vdmrender/measuring/counters.py: fragments, texture fetches, search steps and searches)."""
from __future__ import annotations

import statistics
from pathlib import Path
from typing import Callable

import numpy as np

from vdmbake.formats import exr
from vdmbake.bundle.directory import Bundle

from vdmrender.measuring import counters, interleaved
from vdmrender.gpu import gl
from vdmrender.common import images
from vdmrender.measuring.timing import Budget, FrameTimer
from vdmrender.common.camera import cameras_for
from vdmrender.comparing.metrics import compare, pooled


def scene_of(bundle_path: Path):
    """The bundle, its scene, first object, that object's manifest entry and its cameras."""
    bundle = Bundle(Path(bundle_path))
    scene = bundle.scene
    obj = scene.objects[0]
    entry = bundle.manifest["objects"][obj.name]
    w, h = scene.render.resolution
    return bundle, scene, obj, entry, cameras_for(scene.camera, entry["centre"], entry["radius"], w, h)


def reference8(render_dir: Path, name: str, count: int, background) -> list[np.ndarray]:
    """A vdmrender output folder's reference frames of object `name`, encoded as the frames are."""
    out = []
    for k in range(count):
        ch = exr.read(Path(render_dir) / f"reference/{name}/{k:03d}.exr")["reference"]
        out.append(images.encode(np.stack([ch[c] for c in "RGBA"], -1), background))
    return out


def measure(ctx, builds: dict[str, Callable], cams, ref8, background, rounds: int = 5,
            score: bool = True, budget: Budget = Budget()) -> dict[str, dict]:
    """Each build(ctx) -> renderer timed through the one interleaved loop (vdmrender.measuring.interleaved.frames:
    warmed up as vdmrender warms up a row, with `budget`, then `rounds` rounds of every camera, every variant in
    turn): medians over all timed frames, each frame's GPU ms (`interleaved_ms`, aligned across variants: the paired
    frames vdmrender.deciding.pricing judges), and the error pooled over all frames (metrics.pooled, thesis eq. 2.2)
    unless not `score` (no reference: the error fields are None)."""
    target = gl.Target(ctx, cams[0].width, cams[0].height)
    timer = FrameTimer(ctx, target)
    renderers = {k: b(ctx) for k, b in builds.items()}
    samples, warm = interleaved.frames(timer, renderers, cams, budget, rounds)
    rows = {}
    for k, r in renderers.items():
        s = samples[k]
        gpu = [x.gpu_ms for x in s]
        rows[k] = {"median_ms": round(statistics.median(gpu), 2), "min_ms": round(min(gpu), 2),
                   "median_wall_ms": round(statistics.median(x.wall_ms for x in s), 2),
                   "median_cpu_ms": round(statistics.median(x.cpu_ms for x in s), 2),
                   "steady": warm[k]["steady"], "interleaved_ms": [round(x, 4) for x in gpu],
                   "mean_dluv": None, "p95_dluv": None, "iou": None}
        if score:
            rows[k].update(pooled([compare(images.encode(timer.read(r, cam, c), background), r8)
                                   for c, (cam, r8) in enumerate(zip(cams, ref8))]))
        r.release()
    target.release()
    return rows


def costs(ctx, build: Callable, cams) -> dict:
    """build(ctx) built with the cost counters on, one frame per camera: counters.count_frames (divide by
    "covered" for figures per covered pixel), and the GPU bytes it holds then (counters.resident_bytes)."""
    target = gl.Target(ctx, cams[0].width, cams[0].height)
    with counters.counting(ctx):
        r = build(ctx)
    try:
        return {**counters.count_frames(ctx, r, cams, target), "bytes": counters.resident_bytes(r)}
    finally:
        r.release()
        target.release()
