"""GPU time by timer queries (vdmrender.measuring.timing): the warm-up's steady-state rule, the within-camera spread,
the harness's clear kept out of every technique's time, --baseline that knows noise (on scripted reports), and
a doubled pass (every variant built by helpers.doubled) caught exactly by the counters."""
from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from helpers import doubled, doubling
from scenes import TINY_HEAD, bake_and_render
from vdmrender.deciding import baseline
from vdmrender.reporting import report
from vdmrender.gpu import gl
from vdmrender.measuring import timing
from vdmrender.cli import main as render_main
from vdmrender import render


class Scripted:
    """A stand-in FrameTimer whose frames take the scripted GPU times, in order."""

    def __init__(self, times):
        self.times, self.k = list(times), 0

    def frame(self, renderer, camera, index=0):
        t = self.times[min(self.k, len(self.times) - 1)]
        self.k += 1
        return timing.Sample(index, t, t, 0.0, {"frame": t})


def test_warm_up_waits_for_clocks_to_settle():
    """A GPU ramping up its clock (times falling, then flat): the warm-up ends only once two successive
    windows agree, not after a fixed number of frames."""
    ramp = [8.0, 6.0, 4.5, 3.5, 2.8, 2.3, 2.0, 1.9] + [1.8] * 20
    t = Scripted(ramp)
    warm = timing.warm_up(t, None, [0, 1], timing.Budget(warmup=1, warmup_s=0.0, tolerance=0.05))
    # windows of 4 frames (2 rounds of 2 cameras): after 14 frames [2.0, 1.9, 1.8, 1.8] against [1.8] * 4
    assert warm["steady"] is True and warm["warmup_frames"] == 14 and warm["windows_ms"] == [1.85, 1.8]


def test_warm_up_gives_up_and_says_so():
    t = Scripted([10.0, 1.0] * 50)    # never settles: successive windows' medians are 10 and 1
    warm = timing.warm_up(t, None, [0], timing.Budget(warmup=1, warmup_s=0.0, warmup_max_s=0.0, tolerance=0.01))
    assert warm["steady"] is False and warm["warmup_frames"] == 6 and warm["windows_ms"] == [10.0, 1.0]


def test_no_warm_up_when_none_is_asked_for():
    t = Scripted([1.0])
    assert timing.warm_up(t, None, [0], timing.Budget(warmup=0, warmup_s=0.0))["warmup_frames"] == 0
    assert t.k == 0


def test_spread_is_within_a_camera_not_between_cameras():
    """Two views of different cost (10 and 20 ms) each repeating within ±0.1 ms: the spread is the
    repetition's (0.1 ms), not the views' difference (10 ms), though the quartiles span both."""
    rng = np.random.default_rng(1)
    samples = [timing.Sample(c, base + rng.uniform(-0.1, 0.1), 0.0, 0.0, {"frame": base})
               for _ in range(20) for c, base in ((0, 10.0), (1, 20.0))]
    s = timing.summarise(samples, {"warmup_s": 0.0, "warmup_frames": 0, "steady": None, "windows_ms": None}, 0.0)
    assert s["spread_ms"] < 0.2 and s["q3_ms"] - s["q1_ms"] > 9.0
    assert not s["spread_warning"] and s["samples"] == 40 and s["passes_ms"] == {"frame": 15.0}


class Probe:
    """A renderer of one pass that records what it finds in the target before it draws."""

    def __init__(self, target):
        self.target, self.seen, self.views = target, [], []

    def passes(self, camera, view):
        def run():
            self.views.append(view)
            view.begin()
            self.seen.append(float(view.read()[..., 3].max()))
            view.ctx.clear(1.0, 1.0, 1.0, 1.0)      # leave coverage behind for the next frame to find
        return [("frame", run)]


def test_the_harness_clears_outside_the_passes():
    """Every frame starts from a cleared target, cleared by the harness before the first pass (a technique's
    begin() on the view binds without clearing), and the clear is timed apart."""
    ctx = gl.create_context()
    target = gl.Target(ctx, 16, 16)
    try:
        timer, probe = timing.FrameTimer(ctx, target), Probe(target)
        for k in range(3):
            s = timer.frame(probe, None, k)
            assert set(s.passes) == {"frame"} and s.gpu_ms >= 0 and s.wall_ms >= s.submit_ms >= 0
        assert probe.seen == [0.0, 0.0, 0.0]
        assert all(isinstance(v, gl.Kept) for v in probe.views)
    finally:
        target.release()
        ctx.release()


def test_the_clear_is_timed_apart_as_the_median_of_its_queries(ctx):
    """clear_ms: `count` clears of the harness's target, each inside its own timer query; the median in ms."""
    class Query:
        def __init__(self, ns):
            self.ns, self.elapsed, self.seen = list(ns), None, []

        def __enter__(self):
            self.seen.append(float(target.read()[..., 3].max()))   # what the clear inside the query finds

        def __exit__(self, *exc):
            self.elapsed = self.ns.pop(0)

    target = gl.Target(ctx, 16, 16)
    try:
        timer = timing.FrameTimer(ctx, target)
        timer.queries = [Query([5e6, 1e6, 4e6, 2.5e6, 3e6])]
        target.fbo.clear(1.0, 1.0, 1.0, 1.0)
        assert timer.clear_ms() == 3.0              # the median of 5, 1, 4, 2.5 and 3 ms, not their mean (3.1)
        assert timer.queries[0].seen == [1.0, 0.0, 0.0, 0.0, 0.0] and target.read().max() == 0.0
    finally:
        target.release()


def test_a_pass_listed_twice_runs_twice_timed_under_its_name():
    """The timer runs every pass a renderer lists (doubled lists one twice) and times them under their names."""
    ctx = gl.create_context()
    target = gl.Target(ctx, 16, 16)
    try:
        probe = Probe(target)
        s = timing.FrameTimer(ctx, target).frame(doubled(probe, "frame"), None)
        assert len(probe.views) == 2 and list(s.passes) == ["frame"]
    finally:
        target.release()
        ctx.release()


def test_a_saturated_query_falls_back_to_wall_time(monkeypatch):
    """moderngl reads 32-bit query results: a pass over 4.29 s reads 2^32 - 1 ns. That frame is timed by its
    wall time, the saturated pass by the rest of it, and the sample says so."""
    class Saturated:
        elapsed = timing.SATURATED_NS

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    ctx = gl.create_context()
    target = gl.Target(ctx, 8, 8)
    try:
        timer = timing.FrameTimer(ctx, target)
        monkeypatch.setattr(timer, "_query", lambda k: Saturated())
        s = timer.frame(Probe(target), None)
        assert s.saturated and s.gpu_ms == s.wall_ms and s.passes["frame"] <= s.wall_ms
        assert timing.summarise([s], {"warmup_s": 0.0, "warmup_frames": 0, "steady": None, "windows_ms": None},
                                0.0)["saturated"] == 1
    finally:
        target.release()
        ctx.release()


# ------------------------------------------------------------------------------ baseline under noise

def _row(label, ms, spread, **extra):
    return {"object": "o", "label": label, "mean_dluv": 0.1, "p95_dluv": 0.2, "flip_mean": 0.01,
            "median_ms": ms, "spread_ms": spread, **extra}


def _report(device="gpu A", **rows):
    return {"device": device, "resolution": [8, 8], "time": "gpu", "rows": [_row(k, *v) for k, v in rows.items()]}


def test_slowdown_fails_only_beyond_noise_and_threshold():
    old = _report(a=(1.0, 0.05), b=(1.0, 0.5), c=(1.0, 0.05))
    new = _report(a=(1.5, 0.05), b=(1.5, 0.5), c=(1.1, 0.01))
    by = {c["label"]: c for c in baseline.compare(old, new, None, 1.25)["rows"]}
    assert by["a"]["exceeds"] == ["time"]       # 50% slower, noise 0.1 ms
    assert by["b"]["exceeds"] == []             # 50% slower, but within the runs' spread (1.0 ms)
    assert by["c"]["exceeds"] == []             # beyond the noise, under the threshold
    assert by["b"]["noise_ms"] == 1.0


def test_counters_compared_exactly():
    old = _report(a=(1.0, 0.1))
    new = _report(a=(1.0, 0.1))
    old["rows"][0]["counters"] = {"fragments": 100, "fetches": 300}
    new["rows"][0]["counters"] = {"fragments": 100, "fetches": 301}
    b = baseline.compare(old, new, None, None)
    assert b["rows"][0]["counters_changed"] == {"fetches": [300, 301]}
    assert any("fetches 300 -> 301" in n for n in b["notes"])
    assert "fetches=300->301" in report.baseline_csv(b)


def test_times_across_devices_are_refused_unless_asked():
    old, new = _report("gpu A", a=(1.0, 0.0)), _report("gpu B", a=(3.0, 0.0))
    b = baseline.compare(old, new, None, 1.25)
    assert b["rows"][0]["time_ratio"] is None and b["failed"] == [] and any("--compare-devices" in n for n in b["notes"])
    assert baseline.compare(old, new, None, 1.25, across_devices=True)["failed"] == ["o: a"]
    wall = {**old, "device": "gpu B"}
    del wall["time"]
    assert "wall times" in baseline.times_comparable(wall, new)


SCENE = TINY_HEAD.replace("repeats = 1", "repeats = 4") + """
[[objects]]
name = "plane"
primitive = "plane"
[objects.mesostructure]
height = "bricks"
depth = 0.08
[objects.techniques]
pom = { steps = [16] }
"""
COUNTS = ("fragments", "fetches", "steps", "searches", "primitives", "draws", "instances")


def test_a_doubled_pass_doubles_its_counters_exactly(tmp_path, monkeypatch):
    """Against a baseline of the same bundle, a run changes no counter; a run with its frame pass run twice (the
    variants built by `doubled`) has that pass's every counter exactly doubled, the other passes' the same,
    and --baseline reports exactly that change of the totals. No time is compared: two timings on a shared
    machine need not agree (a doubled pass's time is not asserted to exceed any ratio)."""
    r, out = bake_and_render(tmp_path, SCENE, "--no-flip")
    assert r.exit_code == 0, r.output
    old = json.loads((out / "report.json").read_text())["rows"][0]
    frame = old["counters_per_pass"]["frame"]
    assert set(old["counters_per_pass"]) == {"shadow", "frame"} and all(frame[k] > 0 for k in COUNTS), old
    args = [str(tmp_path / "b.bundle"), "--no-flip", "--baseline", str(out / "report.json")]
    r = CliRunner().invoke(render_main, [*args, "-o", str(tmp_path / "same")])
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "same" / "report.json").read_text())["baseline"]["rows"][0]["counters_changed"] == {}
    monkeypatch.setattr(render, "variants", doubling("frame"))
    r = CliRunner().invoke(render_main, [*args, "-o", str(tmp_path / "doubled")])
    assert r.exit_code == 0, r.output                        # counters are reported, not a threshold
    report = json.loads((tmp_path / "doubled" / "report.json").read_text())
    new = report["rows"][0]
    assert new["counters_per_pass"] == {"shadow": old["counters_per_pass"]["shadow"],
                                        "frame": {k: 2 * v for k, v in frame.items()}}
    assert report["baseline"]["rows"][0]["counters_changed"] == {
        k: [old["counters"][k], old["counters"][k] + frame[k]] for k in frame if frame[k]}


def test_max_slowdown_refuses_another_device(tmp_path):
    """--max-slowdown against another device's report: exit 2 naming --compare-devices; with it, the times are
    compared (against a baseline whose every time is 10^9 ms, which no run exceeds whatever the machine's load)."""
    r, out = bake_and_render(tmp_path, SCENE, "--no-flip")
    report = json.loads((out / "report.json").read_text())
    report["device"] = "another GPU"
    for row in report["rows"]:
        row["median_ms"] = 1e9
    (tmp_path / "other.json").write_text(json.dumps(report))
    args = [str(tmp_path / "b.bundle"), "--no-flip", "--baseline", str(tmp_path / "other.json"),
            "-o", str(tmp_path / "n"), "--max-slowdown", "1.5"]
    r = CliRunner().invoke(render_main, args)
    assert r.exit_code == 2 and "--compare-devices" in r.stderr
    r = CliRunner().invoke(render_main, [*args, "--compare-devices"])
    assert r.exit_code == 0, r.output
    block = json.loads((tmp_path / "n" / "report.json").read_text())["baseline"]
    assert all(c["time_ratio"] is not None and c["time_ratio"] < 1 and not c["exceeds"] for c in block["rows"]), block
