"""Time per frame that holds on any device: GL timer queries per pass, after a warm-up that reaches a
steady state, sampled until both a count and a time budget are met.

On a real GPU, wall time around ctx.finish() adds driver latency, and clocks idle low until about a
second of sustained work (docs/timing.md). So a frame's time is the sum of its passes' GL_TIME_ELAPSED
queries; wall time (first call to finish) and CPU submit time (the renderer's calls returning) are kept
beside it. The harness clears the target before every frame, outside every query, and times that clear
apart (measure.Harness): it is the harness's cost, not the technique's.
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass

import numpy as np

from vdmbake.scene import Render

from ..common import progress

# moderngl reads a query's result as 32 bits: a pass over 4.29 s (llvmpipe's slowest benches) saturates there.
SATURATED_NS = 2**32 - 1
SPREAD_WARNING = 0.10   # a row whose within-camera spread exceeds this share of its median is flagged


@dataclass(frozen=True)
class Budget:
    """How long to warm up and how much to sample. The defaults keep llvmpipe runs short; on a GPU, ask
    for seconds (--warmup-s, --sample-s): its clocks need about one second of sustained work."""
    warmup: int = Render.warmup     # untimed renders per camera, at least (the scene's default)
    warmup_s: float = 0.1       # warm-up time, at least
    warmup_max_s: float = 2.0   # then stop waiting for agreement (the row says steady: false)
    tolerance: float = 0.05     # successive warm-up windows' median GPU times agree within this ratio
    repeats: int = Render.repeats   # timed renders per camera, at least (the scene's default)
    sample_s: float = 0.0       # sampling time, at least


@dataclass
class Sample:
    camera: int
    gpu_ms: float               # sum of the passes' timer queries
    wall_ms: float              # first call to ctx.finish() returning
    submit_ms: float            # the renderer's calls returning (CPU time to issue the frame)
    passes: dict                # pass name -> GPU ms (a pass run twice sums)
    saturated: bool = False     # a pass's query saturated: gpu_ms is the wall time, that pass the remainder
    cpu_ms: float = 0.0         # the process's CPU time over the frame, every thread (llvmpipe's rasterisers are the
                                # process's own: the work done, barely inflated by other processes, unlike wall time)


class FrameTimer:
    """Times renderers' frames (vdmrender.techniques: `passes(camera, target)` -> [(name, run)]): each pass
    inside its own timer query, into the target's kept view after the harness's clear. One per run: its
    queries are reused (moderngl frees them with the context)."""

    def __init__(self, ctx, target):
        self.ctx, self.target, self.view = ctx, target, target.kept()
        self.queries = []

    def _query(self, k: int):
        while len(self.queries) <= k:
            self.queries.append(self.ctx.query(time=True))
        return self.queries[k]

    def frame(self, renderer, camera, index: int = 0) -> Sample:
        c0 = time.process_time()
        self.target.clear()
        self.ctx.finish()
        timed = []
        t0 = time.perf_counter()
        for name, run in renderer.passes(camera, self.view):
            q = self._query(len(timed))
            with q:
                run()
            timed.append((name, q))
        t1 = time.perf_counter()
        self.ctx.finish()
        t2 = time.perf_counter()
        passes, over = {}, []
        for name, q in timed:
            ns = q.elapsed
            passes[name] = passes.get(name, 0.0) + ns * 1e-6
            if ns >= SATURATED_NS:
                over.append(name)
        wall = (t2 - t0) * 1e3
        if over:   # its true time is unknown: the frame's is its wall time, the pass the rest of it
            rest = wall - sum(v for k, v in passes.items() if k not in over)
            passes.update({k: max(rest, 0.0) / len(over) for k in over})
        return Sample(index, wall if over else sum(passes.values()), wall, (t1 - t0) * 1e3, passes, bool(over),
                      (time.process_time() - c0) * 1e3)

    def read(self, renderer, camera, index: int = 0):
        """One frame of `renderer`, untimed, read back (linear RGBA float32, row 0 at the top)."""
        self.frame(renderer, camera, index)
        return self.target.read()

    def clear_ms(self, count: int = 5) -> float:
        """The harness's own clear of the target, timed apart (median GPU ms of `count`)."""
        q, out = self._query(0), []
        for _ in range(count):
            self.ctx.finish()
            with q:
                self.target.clear()
            out.append(q.elapsed * 1e-6)
        return statistics.median(out)


def _window(cameras: int) -> int:
    """Frames per warm-up window: whole rounds over the cameras, at least 3 frames."""
    return cameras * math.ceil(3 / cameras)


def warm_up(timer: FrameTimer, renderer, cams, budget: Budget) -> dict:
    """Render round after round over the cameras until at least `warmup` rounds and `warmup_s` have passed
    and the median GPU time of the last window agrees with the window before within `tolerance`; stop
    waiting at `warmup_max_s` (steady: false). Nothing when no warm-up is asked for."""
    if budget.warmup == 0 and budget.warmup_s == 0:
        return {"warmup_s": 0.0, "warmup_frames": 0, "steady": None, "windows_ms": None}
    n, w = len(cams), _window(len(cams))
    gpu, t0 = [], time.perf_counter()
    while True:
        for k, cam in enumerate(cams):
            gpu.append(timer.frame(renderer, cam, k).gpu_ms)
        elapsed = time.perf_counter() - t0
        if len(gpu) < max(budget.warmup * n, 2 * w) or elapsed < budget.warmup_s:
            continue
        a, b = statistics.median(gpu[-2 * w:-w]), statistics.median(gpu[-w:])
        steady = abs(b - a) <= budget.tolerance * max(a, b)
        if steady or elapsed >= budget.warmup_max_s:
            return {"warmup_s": round(elapsed, 3), "warmup_frames": len(gpu), "steady": steady,
                    "windows_ms": [round(a, 4), round(b, 4)]}


def warm_up_each(timer: FrameTimer, renderers: dict, cams, budget: Budget) -> dict[str, dict]:
    """Every renderer of an interleaved comparison ({label: renderer}) warmed up in turn by the same rule as a
    row (warm_up), so the tool's rows and the interleaved loop (vdmrender.measuring.interleaved: the sweep's pricing,
    the benches) start timing from the same state."""
    return {k: warm_up(timer, r, cams, budget) for k, r in renderers.items()}


def sample(timer: FrameTimer, renderer, cams, budget: Budget, desc: str) -> list[Sample]:
    """Rounds over the cameras until at least `repeats` rounds and `sample_s` have passed."""
    out, t0 = [], time.perf_counter()
    for _ in progress.bar(range(budget.repeats), desc, unit="round"):
        out += [timer.frame(renderer, cam, k) for k, cam in enumerate(cams)]
    while time.perf_counter() - t0 < budget.sample_s:
        out += [timer.frame(renderer, cam, k) for k, cam in enumerate(cams)]
    return out


def summarise(samples: list[Sample], warm: dict, sample_s: float) -> dict:
    """A row's timing: the GPU median and quartiles over every sample, each camera's median, the within-camera
    spread (the median over cameras of each camera's interquartile range: what repeating a frame varies by;
    the cameras' differences are the scene, not noise), wall and submit medians, per-pass medians, and how
    many frames had a saturated query (timed by wall time)."""
    gpu = np.array([s.gpu_ms for s in samples])
    q1, med, q3 = np.percentile(gpu, [25, 50, 75])
    cams = sorted({s.camera for s in samples})
    per = [[s.gpu_ms for s in samples if s.camera == c] for c in cams]
    spread = statistics.median(float(np.subtract(*np.percentile(p, [75, 25]))) for p in per)
    names = list(dict.fromkeys(n for s in samples for n in s.passes))
    return {"median_ms": round(float(med), 4), "min_ms": round(float(gpu.min()), 4),
            "q1_ms": round(float(q1), 4), "q3_ms": round(float(q3), 4), "spread_ms": round(spread, 4),
            "camera_ms": [round(statistics.median(p), 4) for p in per],
            "spread_warning": bool(med > 0 and spread > SPREAD_WARNING * med),
            "wall_ms": round(statistics.median(s.wall_ms for s in samples), 4),
            "submit_ms": round(statistics.median(s.submit_ms for s in samples), 4),
            "samples": len(samples), "saturated": sum(s.saturated for s in samples), "sample_s": round(sample_s, 3),
            **warm,
            "passes_ms": {n: round(statistics.median(s.passes.get(n, 0.0) for s in samples), 4) for n in names}}


def time_variant(timer: FrameTimer, renderer, cams, budget: Budget, desc: str = "render") -> tuple[dict, list]:
    """One renderer: warm up, sample, and read back each camera's frame (rendered once more, untimed).
    Returns the timing summary (summarise) and the frames (linear RGBA float32)."""
    warm = warm_up(timer, renderer, cams, budget)
    t0 = time.perf_counter()
    samples = sample(timer, renderer, cams, budget, desc)
    stats = summarise(samples, warm, time.perf_counter() - t0)
    return stats, [timer.read(renderer, cam, k) for k, cam in enumerate(cams)]
