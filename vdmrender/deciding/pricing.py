"""When one time is more than another: the one statistic for timing noise, used by the rows' LOD chains
(vdmrender.deciding.lod), the sweep's pricing (vdmrender.render), the regression gate (vdmrender.deciding.baseline)
and the benchmarks (bench/); the frames it judges are timed by the one interleaved loop
(vdmrender.measuring.interleaved). docs/timing.md says how each use maps onto it.

Rows are timed one after another, and on a shared machine the load moves between them: medians of the same
variant moved 14-42% between runs on the 2-core llvmpipe machine, so a fixed margin on separately measured
medians flips choices (issue 31). Where candidates are timed interleaved (each round: every camera, every
candidate in turn), each frame of one has a frame of the other beside it under the same load, and a pair is
compared by the median of the log-ratios of those paired frames with its distribution-free 95% confidence
interval (order statistics of the binomial sign test). Rounds go on until every candidate's interval against the
fastest is either wholly above log(1 + EQUAL) (slower) or wholly below it (the same cost within EQUAL), or
MAX_ROUNDS pass (then it counts as the same: the difference could not be shown). Equal costs are broken by the
smaller error (vdmrender.deciding.lod.cheapest), which does not vary between runs. Where there are no paired
frames (rows of separately timed medians, two runs of a baseline), one is slower than another when the
difference of their medians exceeds both their spreads together (each a within-camera interquartile range) and a
share of the faster: EQUAL, or the slowdown a user allows."""
from __future__ import annotations

import math

import numpy as np

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


def paired(times, base) -> tuple[float, float, float]:
    """Frames timed beside `base`'s (aligned: frame i of each under the same load) as a ratio to them: the median
    log-ratio and its ~95% interval (median_interval)."""
    t, b = (np.maximum(np.asarray(x, float), 1e-9) for x in (times, base))
    return median_interval(np.log(t / b))


def ratio(times, base) -> dict:
    """paired as ratios, rounded for a table: {ratio, low, high}."""
    return dict(zip(("ratio", "low", "high"), (round(math.exp(v), 4) for v in paired(times, base))))


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
        _, lo, hi = paired(t, times[fastest])
        out[k] = "slower" if lo > edge else "same" if hi < edge else "open"
    return out


def settled(times: dict[str, list[float]]) -> bool:
    """Interleaved rounds may stop: no candidate's verdict is open."""
    return "open" not in verdicts({k: np.array(v) for k, v in times.items()}).values()


def noise_ms(a: dict, b: dict) -> float:
    """What two separately timed rows' medians move by under noise: their within-camera spreads together."""
    return (a.get("spread_ms") or 0.0) + (b.get("spread_ms") or 0.0)


def slower(fast: dict, slow: dict, share: float = EQUAL) -> bool:
    """Row `slow` costs more than row `fast` by their separately timed medians: the difference exceeds their noise
    (noise_ms) and `share` of the faster's median (EQUAL; a baseline's allowed slowdown less 1)."""
    return slow["median_ms"] - fast["median_ms"] > max(noise_ms(fast, slow), share * fast["median_ms"])
