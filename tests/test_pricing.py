"""Deciding which variant is cheaper so that two runs decide alike (vdmrender.deciding.pricing, the one timing
statistic): the median's confidence interval, the verdicts on paired frames under a load that moves, the rule for
rows timed apart, and the LOD chain's choice from them."""
from __future__ import annotations

import numpy as np

from vdmrender.deciding import lod, pricing


def test_median_interval_holds_the_median_at_its_stated_rate():
    """Over many samples of a skewed distribution, the interval holds the true median about 95% of the time."""
    rng = np.random.default_rng(0)
    true = np.log(2.0)   # the median of an exponential of scale 1
    held = [lo <= true <= hi for lo, hi in (pricing.median_interval(rng.exponential(size=40))[1:] for _ in range(2000))]
    assert 0.93 <= np.mean(held) <= 0.99


def load(n: int, seed: int) -> np.ndarray:
    """A shared machine's load: frame times scaled by a factor that drifts between 1x and 2.5x."""
    return np.exp(np.cumsum(np.random.default_rng(seed).normal(0, 0.15, n)).clip(0, np.log(2.5)))


def test_paired_frames_decide_under_a_moving_load():
    """Paired under the same load, 1.5x is slower, 1.02x the same as the fastest, whatever the load does; 1.1x
    (on the edge) stays open."""
    for seed in range(5):
        k = load(48, seed)
        noise = lambda s: np.random.default_rng(s).normal(1, 0.02, 48)   # noqa: E731
        v = pricing.verdicts({"a": 10 * k * noise(1), "b": 15 * k * noise(2), "c": 10.2 * k * noise(3)})
        assert v == {"a": "fastest", "b": "slower", "c": "same"}
        assert pricing.verdicts({"a": 10 * k * noise(1), "d": 11 * k * noise(4)})["d"] == "open"


def row(label, ms, dluv, times=None):
    """A row whose change against the full asset and error against the reference are both `dluv`."""
    return {"label": label, "median_ms": ms, "spread_ms": 0.1, "mean_dluv": dluv, "change_dluv": dluv,
            **({"interleaved_ms": list(times)} if times is not None else {})}


def test_the_chain_takes_the_more_accurate_of_equal_costs_however_the_medians_fell():
    """Separately timed medians under a moving load said coarse was 30% cheaper than mesh; their interleaved frames
    say they cost the same: the more accurate is taken. Where the frames show coarse is slower, mesh is cheapest."""
    k = load(24, 7)
    same = [row("mesh", 10.0, 0.2, 10 * k), row("coarse@0.1", 7.0, 0.9, 10.3 * k)]
    assert lod.cheapest(same)["label"] == "mesh"
    assert lod.cheapest([{**r, "interleaved_ms": None} for r in same])["label"] == "coarse@0.1"   # medians alone
    slower = [row("mesh", 10.0, 0.2, 10 * k), row("coarse@0.1", 7.0, 0.1, 14 * k)]
    assert lod.cheapest(slower)["label"] == "mesh"


def test_contenders_are_within_some_chains_limits_and_near_its_fastest():
    from vdmbake.scene import Thresholds

    rows = [{**row("mesh", 10.0, 0.2), "iou": 1}, {**row("coarse@0.1", 4.0, 0.9), "iou": 1},
            {**row("boards", 30.0, 0.5), "iou": 1}, {**row("coarse@0.01", 1.0, 5.0), "iou": 1}]
    sets = (Thresholds(name="a", mean_dluv=1.0), Thresholds(name="b", mean_dluv=0.3))
    assert lod.contenders(rows, sets) == {"coarse@0.1", "mesh"}


class _Timer:
    """A frame timer that records which renderer drew each frame; every frame 1 ms (steady at once)."""

    def __init__(self):
        self.drawn = []

    def frame(self, renderer, camera, index=0):
        from vdmrender.measuring.timing import Sample

        self.drawn.append(renderer.label)
        return Sample(index, 1.0, 1.0, 0.0, {"frame": 1.0})


class _Renderer:
    def __init__(self, label):
        self.label = label

    def release(self):
        pass


def test_interleaved_pricing_warms_up_each_candidate_by_the_rows_rule():
    """The sweep's pricing (interleaved.gpu_ms, until pricing.settled) warms every candidate up as a row is warmed up
    (timing.warm_up with the run's budget: at least `warmup` rounds over the cameras, one candidate after the other)
    before the first interleaved round, then rotates the order by round; with no warm-up asked for, it times from
    the first frame."""
    from types import SimpleNamespace

    from vdmrender.measuring import interleaved
    from vdmrender.measuring.timing import Budget

    cams = ["c0", "c1"]
    for budget, warm in ((Budget(warmup=5, warmup_s=0.0), 10), (Budget(warmup=0, warmup_s=0.0), 0)):
        timer = _Timer()
        harness = SimpleNamespace(timer=timer, budget=budget, as_shipped=lambda r: r)
        times = interleaved.gpu_ms(harness, {k: (lambda k=k: _Renderer(k)) for k in "ab"}, cams, pricing.MAX_ROUNDS,
                                   pricing.settled, pricing.MIN_ROUNDS)
        assert timer.drawn[:2 * warm] == ["a"] * warm + ["b"] * warm
        assert timer.drawn[2 * warm:2 * warm + 8] == ["a", "b", "a", "b", "b", "a", "b", "a"]   # two rounds, rotated
        # equal frames are the same cost at once: the fewest rounds
        assert len(times["a"]) == len(times["b"]) == (len(timer.drawn) - 2 * warm) // 2
        assert len(times["a"]) == pricing.MIN_ROUNDS * len(cams)


def test_separately_timed_rows_are_slower_beyond_their_spreads_and_the_share():
    """Without paired frames (rows timed apart, a baseline's two runs) one row is slower than another only where the
    difference of medians exceeds both their spreads together and the share (EQUAL for chains, the allowed slowdown
    for a baseline)."""
    fast = {"median_ms": 10.0, "spread_ms": 0.2}
    assert not pricing.slower(fast, {"median_ms": 10.9, "spread_ms": 0.2})                # within EQUAL
    assert pricing.slower(fast, {"median_ms": 11.2, "spread_ms": 0.2})
    assert not pricing.slower(fast, {"median_ms": 11.2, "spread_ms": 1.1})                # within the spreads
    assert not pricing.slower(fast, {"median_ms": 11.2, "spread_ms": None}, share=0.5)    # within a 1.5x slowdown
    assert pricing.slower(fast, {"median_ms": 15.1, "spread_ms": None}, share=0.5)
