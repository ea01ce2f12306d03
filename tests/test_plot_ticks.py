"""The report's PNG plots stay readable (issue 44): on a log axis over any span, from a few percent (the torus's
times, where matplotlib labelled every minor tick: "2.1×10²2.2×10²…") to several decades, no two tick labels'
boxes overlap, as matplotlib's renderer lays them out, and at least two are labelled; no label cites an equation
number instead of saying what it plots; lod.png's legend names the hatch; no title runs into another."""
from __future__ import annotations

import itertools

import matplotlib
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from vdmrender.common import plots
from vdmrender.reporting import chains
from vdmrender.reporting import report
from vdmrender.views import sweep

# (lowest, highest) time in ms: a few percent, within one decade, a decade and a half, several decades
SPANS = [(100.0, 100.6), (210.0, 229.0), (21.0, 60.0), (3.0, 70.0), (0.05, 500.0), (0.002, 4000.0)]


def spread(lo: float, hi: float, n: int = 5) -> list[float]:
    return [lo * (hi / lo) ** (k / (n - 1)) for k in range(n)]


def time_report(lo: float, hi: float) -> dict:
    rows = [{"object": obj, "technique": tech, "label": f"{tech}@{k}", "median_ms": ms, "mean_dluv": 1.0 + k}
            for obj in ("torus", "villin")
            for k, (tech, ms) in enumerate(zip(("vdm", "pom", "relief", "bump", "mesh"), spread(lo, hi)))]
    return {"rows": rows, "resolution": [128, 128], "device": "llvmpipe"}


def sweep_report(lo: float, hi: float) -> dict:
    rows = [{"object": "torus", "label": label, "size_px": size, "median_ms": ms, "mean_dluv": 2.0}
            for label, times in (("vdm@8", spread(lo, hi, 4)), ("bump", spread(lo, hi, 4)[::-1]))
            for size, ms in zip((128, 64, 32, 16), times)]
    return {"sweep": {"rows": rows}, "resolution": [128, 128], "device": "llvmpipe"}


def texts(fig) -> dict[str, list]:
    """Per axis of the drawn figure its tick labels inside the axes' span, with their boxes; and the titles and
    axis labels."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    out = {}
    for i, ax in enumerate(fig.axes):
        box = ax.get_window_extent(r)
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            labels = []
            for t in axis.get_ticklabels(which="both"):
                if not (t.get_visible() and t.get_text()):
                    continue
                e = t.get_window_extent(r)
                centre = (e.x0 + e.x1) / 2 if name == "x" else (e.y0 + e.y1) / 2
                if (box.x0 - 1 <= centre <= box.x1 + 1) if name == "x" else (box.y0 - 1 <= centre <= box.y1 + 1):
                    labels.append((t.get_text(), e))
            out[f"panel {i} {name}"] = labels
    out["titles"] = [(t.get_text(), t.get_window_extent(r)) for t in
                     [fig._suptitle] + [ax.title for ax in fig.axes] + [ax.xaxis.label for ax in fig.axes]
                     + [ax.yaxis.label for ax in fig.axes] if t is not None and t.get_text()]
    return out


def overlapping(labels: list) -> list:
    return [(a, b) for (a, p), (b, q) in itertools.combinations(labels, 2)
            if p.x0 < q.x1 and q.x0 < p.x1 and p.y0 < q.y1 and q.y0 < p.y1]


def check(fig, log_axes: list[str]) -> None:
    found = texts(fig)
    try:
        for where, labels in found.items():
            assert overlapping(labels) == [], (where, [t for t, _ in labels])
        for where in log_axes:
            assert len(found[where]) >= 2, (where, [t for t, _ in found[where]])
            assert all("×" not in t and "^" not in t for t, _ in found[where]), found[where]   # plain numbers
        assert not any("eq." in t for t, _ in found["titles"]), [t for t, _ in found["titles"]]
        edge = fig.bbox
        for t, e in found["titles"]:   # no title or axis label cut off at the figure's edge
            assert edge.x0 <= e.x0 and e.x1 <= edge.x1 and edge.y0 <= e.y0 and e.y1 <= edge.y1, t
    finally:
        plt.close(fig)


@pytest.mark.parametrize("lo,hi", SPANS)
def test_error_against_time_ticks(lo, hi):
    check(report.figure(time_report(lo, hi)), ["panel 0 x", "panel 1 x"])


@pytest.mark.parametrize("lo,hi", SPANS)
def test_cost_against_size_ticks(lo, hi):
    check(sweep.figure(sweep_report(lo, hi), "median_ms", "median GPU time [ms] (log)", True), ["panel 0 y"])


def test_error_against_size_labels():
    """The error plot's axis said in words, and what its lines compare (the reference's samples, the frames'
    anti-aliasing) in the title, within the figure."""
    r = {**sweep_report(1.0, 2.0), "filtering": {"reference_spp": 16, "antialias": "msaa4"}}
    fig = sweep.figure(r, "mean_dluv", plots.ERROR_LABEL, False)
    assert "reference 16 spp, frames AA msaa4" in fig.get_suptitle()
    check(fig, [])


def test_the_lod_legend_names_the_hatch():
    """A chain over its limit at its smallest band: the hatch named in the legend, and the two-line title clear of
    the panels' titles."""
    entries = [{"variant": "relief@32", "min_px": 16, "max_px": 64, "meets": True, "switch_px": [14.4, 17.6],
                "measured": [{"size_px": 64, "change_dluv": 0.8}, {"size_px": 32, "change_dluv": 0.9}]},
               {"variant": "bump", "min_px": 0, "max_px": 16, "meets": False,
                "measured": [{"size_px": 16, "change_dluv": 8.0, "pop_dluv": 4.6}]}]
    chain = {"name": "dluv1", "limit_on": "change", "limits": {"change_dluv": 1.0},
             "objects": {"torus": {"entries": entries}}}
    rows = [{"object": "torus", "label": label, "size_px": s, "change_dluv": d}
            for label, ds in (("relief@32", (0.8, 0.9, 2.0)), ("bump", (6.0, 7.0, 8.0)))
            for s, d in zip((64, 32, 16), ds)]
    lodj = {"chains": [chain, {**chain, "name": "dluv3"}], "sizes_px": [64, 32, 16], "device": "llvmpipe",
            "error": {"reference_spp": 4, "antialias": "msaa4"}}
    fig = chains.figure(lodj, rows)
    legends = [t.get_text() for ax in fig.axes for t in ax.get_legend().get_texts()]
    assert sum("hatched: over the limits" in t for t in legends) == 2, legends
    check(fig, [])
