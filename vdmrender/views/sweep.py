"""Error and cost against screen size (issue 22): every view again from the distance at which the object's
bounding sphere spans a given number of pixels on screen, the frame size kept; and the plots of both against
that size, one line per variant."""
from __future__ import annotations

import csv
import math
import textwrap
from pathlib import Path

import numpy as np

from ..common.camera import Camera, clip_planes
from ..common.plots import ERROR_LABEL, log_ticks
from ..deciding.baseline import POINT
from ..reporting.report import flat as report_flat

COLUMNS = ["object", "size_px", "distance_radii", "label", "technique", "value", "median_ms", "spread_ms", "q1_ms",
           "q3_ms", "fragments_px", "fetches_px", "steps_px", "change_against", "change_dluv", "change_p95_dluv",
           "change_iou", "change_flip", "mean_dluv", "p95_dluv", "flip_mean", "iou", "floor_dluv", "reference_noise_dluv",
           "aliased_mean_dluv", "aliased_p95_dluv", "aliased_iou", "empty_frames", "frames", "device"]


def distance_for(size_px: float, radius: float, fov_deg: float, height: int) -> float:
    """The eye's distance from the centre of a sphere of `radius` at which its silhouette, seen at the image centre,
    is `size_px` across: the tangent cone's half-angle is asin(r/d), so the silhouette's radius on the image
    plane is f r / sqrt(d^2 - r^2) with f = (H/2) / tan(fov/2) pixels; solved for d."""
    f = 0.5 * height / math.tan(math.radians(fov_deg) / 2)
    return radius * math.hypot(1.0, f / (0.5 * size_px))


def sized(views: list[Camera], centre, radius: float, size_px: float) -> list[Camera]:
    """Each view moved along its line of sight (and aimed at the sphere's centre) to where the bounding sphere
    spans `size_px` pixels; field of view, up and frame size kept, near and far hugging the sphere."""
    centre = np.asarray(centre, float)
    cams = []
    for c in views:
        back = (c.eye - c.target) / np.linalg.norm(c.eye - c.target)
        eye = centre + back * distance_for(size_px, radius, c.fov_deg, c.height)
        cams.append(Camera(eye, centre, c.up, c.fov_deg, c.width, c.height, *clip_planes(eye, centre, centre, radius)))
    return cams


def write(folder: Path, report: dict) -> None:
    """sweep.csv (one row per object, size and variant), error_vs_size.png and cost_vs_size.png."""
    rows = report["sweep"]["rows"]
    with open(folder / "sweep.csv", "w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS, extrasaction="ignore")
        w.writeheader()
        w.writerows(report_flat(r) for r in rows)   # per-pixel work spelled as report.csv spells it
    for name, field, label, log in (
            ("error_vs_size.png", "mean_dluv", ERROR_LABEL, False),
            ("cost_vs_size.png", "median_ms", "median GPU time per frame, timer queries [ms] (log)", True)):
        plot(folder / name, report, field, label, log)


def seen(report: dict) -> str:
    """What the error plot's solid lines compare: the reference's filter and the frames' anti-aliasing."""
    f = report.get("filtering") or POINT
    solid = f"reference {f['reference_spp']} spp, frames AA {f['antialias']}"
    return solid + ("; dashed: 1 spp both" if f["reference_spp"] > 1 or f["antialias"] != "none" else "")


def plot(path: Path, report: dict, field: str, ylabel: str, log_y: bool) -> None:
    import matplotlib.pyplot as plt

    fig = figure(report, field, ylabel, log_y)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure(report: dict, field: str, ylabel: str, log_y: bool):
    """`field` against the object's size on screen, one panel per object, one line per variant; the error
    against what a viewer sees (filtered: report.json's `filtering`) solid, its point-sampled `aliased_` twin
    dashed in the same colour where the two differ."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = report["sweep"]["rows"]
    objects = list(dict.fromkeys(r["object"] for r in rows))
    fig, axes = plt.subplots(1, len(objects), figsize=(5.6 * len(objects), 4.4), squeeze=False)
    for ax, obj in zip(axes[0], objects):
        mine = [r for r in rows if r["object"] == obj]
        for label in dict.fromkeys(r["label"] for r in mine):
            pts = sorted((r["size_px"], r[field]) for r in mine if r["label"] == label and r[field] is not None)
            line, = ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=label, markersize=3)
            twin = sorted((r["size_px"], r.get(f"aliased_{field}")) for r in mine
                          if r["label"] == label and r.get(f"aliased_{field}") is not None)
            if twin and [p[1] for p in twin] != [p[1] for p in pts]:
                ax.plot([p[0] for p in twin], [p[1] for p in twin], "--", color=line.get_color(), linewidth=0.8,
                        alpha=0.7)
        ax.set_xscale("log", base=2)
        sizes = sorted({r["size_px"] for r in mine})
        ax.set_xticks(sizes, [str(s) for s in sizes])
        ax.minorticks_off()
        if log_y:
            ax.set_yscale("log")
            log_ticks(ax, "y")
        ax.set_xlabel("bounding sphere on screen [px] (log)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{obj}  frame {report['resolution'][0]}x{report['resolution'][1]}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    title = textwrap.fill(f"{'error' if field == 'mean_dluv' else 'cost'} against screen size on "
                          f"{report['device']}", 60 * len(objects))
    title += f"\n{seen(report)}" if field == "mean_dluv" else ""   # what the solid and dashed lines compare
    fig.suptitle(title, fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.14 * title.count("\n") / fig.get_figheight()))   # room for its lines
    return fig
