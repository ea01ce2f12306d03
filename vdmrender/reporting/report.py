"""The error-against-time report: report.json, report.csv and error_vs_time.png (and with --baseline,
baseline.md and baseline.csv: the change against an earlier run). report.json is strict JSON, which has
no NaN or Infinity: a number that is not finite is written as null and its path listed in `non_finite`."""
from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

from ..common.markdown import cell, number, table
from ..common.plots import ERROR_LABEL, log_ticks

COLUMNS = ["object", "technique", "knob", "value", "label", "faces", "frames", "empty_frames", "median_ms", "min_ms",
           "q1_ms", "q3_ms", "spread_ms", "wall_ms", "submit_ms", "samples", "warmup_s", "warmup_frames", "steady",
           "passes_ms", "fragments_px", "fetches_px", "steps_px", "primitives", "instances", "gpu_bytes",
           "ratio_to_baseline", "baseline", "change_against", "change_dluv", "change_p95_dluv", "change_iou",
           "change_flip", "mean_dluv", "p95_dluv", "max_dluv", "iou", "flip_mean", "floor_dluv", "floor_p95_dluv", "floor_iou",
           "reference_noise_dluv",
           "aliased_mean_dluv", "aliased_p95_dluv", "aliased_iou", "coverage",
           "nonfinite", "device",
           # mesostructure objects (vdmrender.tracing.borders): pixels scored apart, and every pixel together
           "surface_px", "border_px", "inside_px", "border_fraction", "inside_fraction", "mean_dluv_apart",
           "mean_dluv_all", "iou_all"]


def add_baseline_ratios(rows: list[dict]) -> None:
    """Each row's time as a ratio to its object's baseline, measured in the same run: the `mesh`
    technique where the object has it, else the object's first variant."""
    for obj in dict.fromkeys(r["object"] for r in rows):
        mine = [r for r in rows if r["object"] == obj]
        base = next((r for r in mine if r["technique"] == "mesh"), mine[0])
        for r in mine:
            r["baseline"] = base["label"]
            r["ratio_to_baseline"] = round(r["median_ms"] / base["median_ms"], 4) if base["median_ms"] > 0 else None


def finite(report: dict) -> dict:
    """The report with every non-finite number replaced by None and `non_finite` listing where each was
    ("rows[2].mean_dluv"), so that json.dumps(..., allow_nan=False) writes it (report.json, --json)."""
    where = []

    def clean(v, path):
        if isinstance(v, float) and not math.isfinite(v):
            where.append(path)
            return None
        if isinstance(v, dict):
            return {k: clean(x, f"{path}.{k}" if path else k) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x, f"{path}[{i}]") for i, x in enumerate(v)]
        return v

    return {**clean(report, ""), "non_finite": where}


def write(folder: Path, report: dict) -> None:
    """The report's files; `report` as finite() gives it."""
    (folder / "report.json").write_text(json.dumps(report, indent=1, allow_nan=False) + "\n")
    with open(folder / "report.csv", "w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS, extrasaction="ignore")
        w.writeheader()
        w.writerows(flat(r) for r in report["rows"])
    if "baseline" in report:
        (folder / "baseline.md").write_text(baseline_table(report["baseline"]))
        (folder / "baseline.csv").write_text(baseline_csv(report["baseline"]))
    if "composite" in report:
        (folder / "composite.md").write_text(composite_table(report))
    if report["rows"] or report.get("composite"):   # nothing drawn (every bundle failed): no plot of nothing
        plot(folder / "error_vs_time.png", report)


def flat(row: dict) -> dict:
    """A row for the CSV: per-pass times as `name=ms;name=ms`, the counters per covered pixel and per run."""
    passes, px, c = row.get("passes_ms") or {}, row.get("per_pixel") or {}, row.get("counters") or {}
    return {**row, "passes_ms": ";".join(f"{k}={v}" for k, v in passes.items()),
            **{f"{k}_px": px.get(k) for k in ("fragments", "fetches", "steps")},
            "primitives": c.get("primitives"), "instances": c.get("instances"), "gpu_bytes": c.get("bytes")}


def composite_table(report: dict) -> str:
    """composite.md: per variant set of render.composite its variants, time and error (vdmrender.views.composite)."""
    lines = [f"Composite frames, {report['resolution'][0]}x{report['resolution'][1]}, {report['device']}: every object "
             "in one frame, against the reference tracing every object together; frames in composite/frames/SET/, "
             "heat maps in composite/heatmaps/SET/, the sheet in composite/overview.png.", "",
             table(["set", "variants", "median GPU ms/frame", "mean ΔLuv", "p95 ΔLuv", "IoU", "FLIP"], "rlrrrrr",
                   [[str(r["set"]), r["label"], f"{r['median_ms']:.1f}", number(r["mean_dluv"], 3),
                     number(r["p95_dluv"], 2), number(r["iou"], 4), number(r["flip_mean"], 4)]
                    for r in report["composite"]])]
    return "\n".join(lines) + "\n"


PANEL_COLUMNS = 3   # panels per row of error_vs_time.png: any number of objects stays readable
def figure(report: dict):
    """Mean delta-Luv against median ms per frame, one panel per object in a grid of up to PANEL_COLUMNS
    columns; a technique's knob values joined by a line, each point labelled on the side facing the
    panel's middle so that no label runs off the figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rows = report["rows"]
    objects = list(dict.fromkeys(r["object"] for r in rows))
    sets = report.get("composite", [])
    panels = len(objects) + bool(sets)
    ncols = min(PANEL_COLUMNS, panels)
    nrows = -(-panels // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(5.6 * ncols, 4.4 * nrows), squeeze=False)
    for ax in axes.ravel()[panels:]:
        ax.remove()
    groups = [(obj, False, [(r["technique"], r) for r in rows if r["object"] == obj]) for obj in objects]
    if sets:   # composite frames: one point per variant set (the legend names the sets' variants)
        groups.append(("composite", True, [(f"{r['set']}: {r['label']}", {**r, "label": f"set {r['set']}"})
                                           for r in sets]))
    for ax, (obj, together, mine) in zip(axes.ravel(), groups):
        points = []
        for tech in dict.fromkeys(t for t, _ in mine):
            pts = [r for t, r in mine   # in knob order; an error or time that was not finite is null
                   if t == tech and r["mean_dluv"] is not None and r["median_ms"]]
            ax.plot([r["median_ms"] for r in pts], [r["mean_dluv"] for r in pts], "o-", label=tech)
            points += pts
        ax.set_xscale("log")
        ax.margins(x=0.12, y=0.12)
        log_ticks(ax, "x")
        if points:
            logs = np.log([r["median_ms"] for r in points])
            middle = 0.5 * (logs.min() + logs.max())
            for r, x in zip(points, logs):
                right = x <= middle
                ax.annotate(r["label"], (r["median_ms"], r["mean_dluv"]), textcoords="offset points",
                            xytext=(5 if right else -5, 4), ha="left" if right else "right", fontsize=7)
        ax.set_xlabel("median GPU time per frame, timer queries [ms] (log)")
        ax.set_ylabel(ERROR_LABEL)
        ax.set_title(f"{obj}  {report['resolution'][0]}x{report['resolution'][1]}"
                     + (" (every object in one frame)" if together else ""), fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6 if together else 8)
    fig.suptitle(f"error against time on {report['device']}", fontsize=9)
    fig.tight_layout()
    return fig


def plot(path: Path, report: dict) -> None:
    import matplotlib.pyplot as plt

    fig = figure(report)
    fig.savefig(path, dpi=110)
    plt.close(fig)


BASELINE_COLUMNS = ["object", "label", "status", "old_mean_dluv", "new_mean_dluv", "d_mean_dluv", "old_p95_dluv",
           "new_p95_dluv", "d_p95_dluv", "old_flip", "new_flip", "d_flip", "old_ms", "new_ms", "time_ratio",
           "noise_ms", "counters_changed", "exceeds"]


def baseline_table(block: dict) -> str:
    """vdmrender.deciding.baseline.compare's block as a markdown table (stderr and OUT/baseline.md); a row over a threshold is marked."""
    t = block["thresholds"]
    lines = [f"change against the baseline (max error increase {t['max_error_increase']}, "
             f"max slowdown {t['max_slowdown']})", *(f"note: {cell(n)}" for n in block["notes"]), "",
             table(["object", "variant", "mean ΔLuv old → new", "Δ mean", "p95 old → new", "Δ p95", "FLIP Δ",
                    "GPU ms old → new", "time ratio", "noise ms", "exceeds"], "lllrlrrlrrl",
                   [[cell(c["object"]), cell(c["label"]),
                     f"{number(c['old_mean_dluv'], 3)} → {number(c['new_mean_dluv'], 3)}", number(c["d_mean_dluv"], 3, True),
                     f"{number(c['old_p95_dluv'], 2)} → {number(c['new_p95_dluv'], 2)}", number(c["d_p95_dluv"], 2, True),
                     number(c["d_flip"], 4, True), f"{number(c['old_ms'], 2)} → {number(c['new_ms'], 2)}",
                     number(c["time_ratio"], 2), number(c["noise_ms"], 2),
                     cell(", ".join(c["exceeds"]) or ("" if c["status"] == "compared" else c["status"]))]
                    for c in block["rows"]])]
    return "\n".join(lines) + "\n"


def baseline_csv(block: dict) -> str:
    f = io.StringIO()
    w = csv.DictWriter(f, BASELINE_COLUMNS, extrasaction="ignore")
    w.writeheader()
    w.writerows({**c, "exceeds": " ".join(c["exceeds"]),
                 "counters_changed": ";".join(f"{k}={a}->{b}" for k, (a, b) in c["counters_changed"].items())}
                for c in block["rows"])
    return f.getvalue()
