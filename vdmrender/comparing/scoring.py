"""Scoring a variant's frames against the reference (vdmrender.comparing.metrics: ΔLuv, FLIP, coverage), writing the
frames and heat maps, and the one line per measured row that vdmrender logs."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..common import images
from ..common import progress
from ..common.markdown import number
from .metrics import compare, flip_values, pooled


@dataclass
class References:
    """An object's or a composite's reference frames as scoring reads them (uint8 sRGB over the background,
    coverage alpha): `filtered`, at the run's samples per pixel (what a viewer sees; the error that decides),
    and `point`, the pixel-centre reference the `aliased_*` error is against (the same list at 1 spp);
    `noise_dluv`, the filtered frames' own sampling noise (noise; None at 1 spp)."""
    filtered: list
    classes: list
    point: list
    cached: bool
    noise_dluv: float | None = None

    @classmethod
    def traced(cls, load, folder: str, spp: int, background) -> "References":
        """load(spp, folder) -> (frames, classes, info), refcache.load_or_trace's: the filtered reference in
        `folder`, and at more than 1 spp the pixel-centre one in FOLDER/point."""
        (frames, classes, info), *point = [load(s, f) for f, s in folders(folder, spp)]
        filtered = [images.encode(f, background) for f in frames]
        if not point:
            return cls(filtered, classes, filtered, info["cached"])
        (point, _, point_info), = point
        return cls(filtered, classes, [images.encode(f, background) for f in point],
                   info["cached"] and point_info["cached"], noise(frames, info["halves"], background))

    def aliased(self, frames, shipped, background, scores) -> dict:
        """The `aliased_*` fields of a row: its point-sampled frames (measure.Harness) against the pixel-centre
        reference, mean and p95 ΔLuv and IoU as the row's own (`scores`: score_frames' of the frames as `shipped`,
        which are these when neither side is filtered)."""
        if self.point is self.filtered and frames is shipped:
            cs = scores
        else:
            cs = [compare(images.encode(f, background), r8, cls) for f, r8, cls in zip(frames, self.point, self.classes)]
        return {f"aliased_{k}": v for k, v in pooled(cs).items()}


def folders(folder: str, spp: int) -> list[tuple[str, int]]:
    """The references a set of views is scored against, (folder, samples per pixel): the filtered one in `folder`,
    and at more than 1 spp the pixel-centre one in FOLDER/point."""
    return [(folder, spp)] + ([(f"{folder}/point", 1)] if spp > 1 else [])


def noise(frames: list, halves: list, background) -> float | None:
    """The filtered reference's own sampling noise as a mean ΔLuv, estimated per pixel from its two halves of
    samples (reference.filtered's Halves): each an independent estimate of the pixel, A over the a samples of the
    first half, B over the other b of the n the pixel got (adaptive sampling gives pixels different n), and the
    pixel F = (a A + b B) / n, so F's deviation from its true value is sd(A - B) sqrt(a b) / n (half the halves'
    difference for a = b): each pixel's ΔLuv between A and B, times its own sqrt(a b) / n, pooled over every pixel
    either half covers, as a row's mean ΔLuv is pooled; 0 where every sample of every pixel agrees, None where
    neither half covers a pixel."""
    values = []
    for f, h in zip(frames, halves):
        n, a = h.traced.astype(np.float64), h.in_first.astype(np.float64)
        b = n - a
        other = np.maximum((n[..., None] * f - a[..., None] * h.first) / b[..., None], 0.0)
        c = compare(images.encode(h.first, background), images.encode(other.astype(np.float32), background))
        values.append(c["values"] * (np.sqrt(a * b) / n)[c["scored"]])
    d = np.concatenate(values)
    return round(float(d.mean()), 4) if d.size else None


def score_frames(frames, ref8, classes, out, frame_dir: str, heat_dir: str, heat_max, background, flip, desc: str):
    """Each frame against its reference: its scores (metrics.compare, with FLIP, coverage and non-finite
    pixels), and its sRGB frame and heat map, also written as FRAME_DIR/NNN.png and HEAT_DIR/NNN.png."""
    scores, heats, enc = [], [], []
    for k, (f, r8, cls) in enumerate(progress.bar(list(zip(frames, ref8, classes)), desc)):
        f8 = images.encode(f, background)
        c = compare(f8, r8, cls)
        c.update(flip=flip_values(f8, r8, c["scored"]) if flip else np.zeros(0),
                 coverage=float((r8[..., 3] > 0).mean()), nonfinite=int((~np.isfinite(f)).any(-1).sum()))
        heat = images.heatmap(c["dist"], heat_max)
        images.save_rgb(out.file(f"{frame_dir}/{k:03d}.png"), f8)
        images.save_rgb(out.file(f"{heat_dir}/{k:03d}.png"), heat)
        scores.append(c)
        heats.append(heat)
        enc.append(f8)
    return scores, heats, enc


def show(x, width: int, digits: int) -> str:
    """A figure of a log line, right-aligned in `width` (markdown.number: "-" where there is none)."""
    return f"{number(x, digits):>{width}}"


def time_line(row: dict) -> str:
    """A row's time as the log shows it: GPU median, spread, wall time, and a flag when not steady or noisy."""
    flags = [f for f, bad in (("not steady", row["steady"] is False), ("noisy", row["spread_warning"]),
                              ("wall time: query saturated", row["saturated"])) if bad]
    px = row.get("per_pixel")
    return (f"{row['median_ms']:9.3f} ms/frame GPU (±{row['spread_ms']:.3f}, wall {row['wall_ms']:.3f})"
            + (f" [{', '.join(flags)}]" if flags else "")
            + (f"  per px: {px['fragments']:.2f} frag {px['fetches']:.1f} fetch {px['steps']:.1f} step"
               if px and px["fragments"] is not None else ""))


def row_line(row: dict) -> str:
    """A row's time, work and error as the log shows them."""
    return (f"{time_line(row)}  mean dLuv {show(row['mean_dluv'], 7, 3)}  p95 {show(row['p95_dluv'], 7, 3)}"
            f"  IoU {show(row['iou'], 6, 4)}  FLIP {show(row['flip_mean'], 6, 4)}")


def pops(frames: dict):
    """pop(size, a, b) over a sweep's frames ({size: {label: sRGB frames}}): the mean ΔLuv between variant a's and
    variant b's frames of the same views at that size, over both coverage masks, pooled over the views (what a
    viewer sees change when an LOD chain switches from a to b there); 0 where neither covers a pixel."""
    cache = {}

    def pop(size, a: str, b: str) -> float:
        key = (size, *sorted((a, b)))
        if key not in cache:
            cs = [compare(fa, fb) for fa, fb in zip(frames[size][a], frames[size][b])]
            cache[key] = pooled(cs)["mean_dluv"] or 0.0
        return cache[key]

    return pop
