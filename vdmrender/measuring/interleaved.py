"""The one interleaved timing loop: alternatives timed against each other in one process, round by round, each
round every camera and on it every alternative in turn, the order rotated by round (A B C, B C A, C A B, ...), so
each frame of one has a frame of every other beside it under the same load and no alternative always follows the
same neighbour. The sweep's pricing (vdmrender.render) and every benchmark that compares alternatives (bench/) time
through it; what it times is judged by the one statistic, vdmrender.deciding.pricing (paired log-ratios), which
the caller passes in as `settled` (measuring does not decide)."""
from __future__ import annotations

from typing import Callable

from . import measure, timing


def rounds(labels, step: Callable, count: int, cameras: int = 1, settled: Callable | None = None,
           least: int = 1) -> dict[str, list]:
    """Up to `count` rounds of step(label, camera index) for every camera index below `cameras` and on it every
    label in turn, rotated by round: {label: [step's results in order]}, aligned across labels (result i of each
    from the same round and camera). settled({label: results}) is asked after each round from round `least` on:
    True stops the loop."""
    labels = list(labels)
    out = {k: [] for k in labels}
    for n in range(count):
        order = labels[n % len(labels):] + labels[:n % len(labels)]
        for c in range(cameras):
            for k in order:
                out[k].append(step(k, c))
        if settled is not None and n + 1 >= least and settled(out):
            break
    return out


def frames(timer: timing.FrameTimer, renderers: dict, cams, budget: timing.Budget, count: int,
           settled: Callable | None = None, least: int = 1,
           seen: Callable | None = None) -> tuple[dict[str, list[timing.Sample]], dict[str, dict]]:
    """GL renderers ({label: renderer}) timed by `timer` (each pass in its own timer query) by `rounds`, after each
    is warmed up by a row's rule (timing.warm_up_each with `budget`). settled gets {label: [GPU ms]};
    seen(label, camera index, sample) runs after each frame while it is still in the timer's target (a bench scores
    the frame it timed). Returns the samples, aligned across labels, and each renderer's warm-up."""
    warm = timing.warm_up_each(timer, renderers, cams, budget)

    def step(k, c):
        s = timer.frame(renderers[k], cams[c], c)
        if seen is not None:
            seen(k, c, s)
        return s

    gpu = None if settled is None else lambda out: settled({k: [s.gpu_ms for s in v] for k, v in out.items()})
    return rounds(renderers, step, count, len(cams), gpu, least), warm


def gpu_ms(harness: measure.Harness, builds: dict, cams, count: int, settled: Callable,
           least: int) -> dict[str, list[float]]:
    """GPU ms per frame of each build ({label: build()}) as the run ships it, timed by `frames` with the run's timer
    and budget until `settled` (from round `least`, at most `count` rounds): {label: [ms of round r, camera c, ...]},
    aligned across labels."""
    renderers = {k: harness.as_shipped(b()) for k, b in builds.items()}
    try:
        samples, _ = frames(harness.timer, renderers, cams, harness.budget, count, settled, least)
    finally:
        for r in renderers.values():
            r.release()
    return {k: [round(s.gpu_ms, 4) for s in v] for k, v in samples.items()}
