"""Which of several variants is cheaper, decided so that two runs decide alike (issue 31).

Rows are timed one after another, and on a shared machine the load moves between them: medians of the same
variant moved 14-42% between runs on the 2-core llvmpipe machine, so a fixed margin on separately measured
medians flips choices. Here the candidates are timed interleaved (each round: every camera, every candidate in
turn), so each frame of one has a frame of the other beside it under the same load, and a pair is compared by
the median of the log-ratios of those paired frames with its distribution-free 95% confidence interval (order
statistics of the binomial sign test). Rounds go on until every candidate's interval against the fastest is
either wholly above log(1 + EQUAL) (slower) or wholly below it (the same cost within EQUAL), or MAX_ROUNDS
pass (then it counts as the same: the difference could not be shown). Equal costs are broken by the smaller
error (vdmrender.deciding.lod.cheapest), which does not vary between runs."""
from __future__ import annotations

import math

import numpy as np

from ..measuring import measure, timing

EQUAL = 0.10        # costs within 10% of each other are the same cost
Z = 1.96            # 95% confidence
MIN_ROUNDS, MAX_ROUNDS = 4, 24
NEAR = 4.0          # only variants within this factor of the fastest by their own (separately timed) medians are timed
                    # again: a median can move 2x under load between rows, a factor of 4 in cost does not


def median_interval(x: np.ndarray) -> tuple[float, float, float]:
    """The median of x and a distribution-free ~95% confidence interval for it: the order statistics at
    n/2 -+ Z sqrt(n)/2 (the sign test's normal approximation), clamped to the sample."""
    s = np.sort(np.asarray(x, float))
    n = len(s)
    half = Z * math.sqrt(n) / 2
    lo, hi = max(int(math.floor(n / 2 - half)), 0), min(int(math.ceil(n / 2 + half)) - 1, n - 1)
    return float(np.median(s)), float(s[lo]), float(s[hi])


def verdicts(times: dict[str, np.ndarray]) -> dict[str, str]:
    """Each candidate against the fastest (the smallest median of its paired frames): "fastest", "slower"
    (the log-ratio's interval above log(1 + EQUAL)), "same" (below it) or "open" (straddling it)."""
    fastest = min(times, key=lambda k: (float(np.median(times[k])), k))
    edge = math.log1p(EQUAL)
    out = {}
    for k, t in times.items():
        if k == fastest:
            out[k] = "fastest"
            continue
        _, lo, hi = median_interval(np.log(np.maximum(t, 1e-9) / np.maximum(times[fastest], 1e-9)))
        out[k] = "slower" if lo > edge else "same" if hi < edge else "open"
    return out


def interleaved(harness: measure.Harness, builds: dict, cams) -> dict[str, list[float]]:
    """GPU ms per frame of each build ({label: build()}), timed interleaved over the cameras after each is warmed
    up by the run's rule (timing.warm_up_each), round by round until verdicts has none open (at least MIN_ROUNDS, at most MAX_ROUNDS): {label:
    [ms of round r, camera c, ...]}, aligned across labels."""
    renderers = {k: harness.as_shipped(measure.built(b)) for k, b in builds.items()}
    times = {k: [] for k in renderers}
    try:
        timing.warm_up_each(harness.timer, renderers, cams, harness.budget)
        for n in range(MAX_ROUNDS):
            order = list(renderers)[n % len(renderers):] + list(renderers)[:n % len(renderers)]   # no fixed order
            for c, cam in enumerate(cams):
                for k in order:
                    times[k].append(harness.timer.frame(renderers[k], cam, c).gpu_ms)
            if n + 1 >= MIN_ROUNDS and "open" not in verdicts({k: np.array(v) for k, v in times.items()}).values():
                break
    finally:
        for r in renderers.values():
            r.release()
    return {k: [round(x, 4) for x in v] for k, v in times.items()}

