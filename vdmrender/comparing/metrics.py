"""Colour and error metrics: CIE 1976 L*u*v* and the average intensity difference of
Vichitvejpaisal2005 eq. 2.2.

Colours are 8-bit sRGB (IEC 61966-2-1: sRGB primaries, D65 white), decoded to linear RGB,
taken to CIE XYZ with the sRGB matrix, then to L*u*v* relative to the D65 white (Y_n = 1).
"""
from __future__ import annotations

import os

import numpy as np

from vdmbake.common.colour import srgb8_to_linear

# Linear sRGB -> XYZ (IEC 61966-2-1, D65).
SRGB_TO_XYZ = np.array([[0.4124564, 0.3575761, 0.1804375],
                        [0.2126729, 0.7151522, 0.0721750],
                        [0.0193339, 0.1191920, 0.9503041]])
WHITE_D65 = SRGB_TO_XYZ.sum(1)  # XYZ of RGB (1, 1, 1): (0.95047, 1.0, 1.08883)
_EPS = (6 / 29) ** 3            # CIE: below this Y/Yn, L* is linear
_KAPPA = (29 / 3) ** 3


def _uv_prime(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    den = xyz[..., 0] + 15 * xyz[..., 1] + 3 * xyz[..., 2]
    safe = np.where(den > 0, den, 1.0)
    return np.where(den > 0, 4 * xyz[..., 0] / safe, 0.0), np.where(den > 0, 9 * xyz[..., 1] / safe, 0.0)


def xyz_to_luv(xyz: np.ndarray, white: np.ndarray = WHITE_D65) -> np.ndarray:
    y = xyz[..., 1] / white[1]
    L = np.where(y > _EPS, 116 * np.cbrt(y) - 16, _KAPPA * y)
    up, vp = _uv_prime(xyz)
    un, vn = _uv_prime(white)
    return np.stack([L, 13 * L * (up - un), 13 * L * (vp - vn)], -1)


def srgb8_to_luv(rgb8: np.ndarray) -> np.ndarray:
    return xyz_to_luv(srgb8_to_linear(rgb8) @ SRGB_TO_XYZ.T)


def delta_luv(a_rgb8: np.ndarray, b_rgb8: np.ndarray) -> np.ndarray:
    """Per-pixel Euclidean distance in L*u*v* (the summand of Vichitvejpaisal2005 eq. 2.2)."""
    return np.linalg.norm(srgb8_to_luv(a_rgb8) - srgb8_to_luv(b_rgb8), axis=-1)


def compare(frame: np.ndarray, reference: np.ndarray, classes: np.ndarray | None = None) -> dict:
    """Error of one frame against the reference; both (H, W, 4) uint8 sRGB + coverage alpha.

    Vichitvejpaisal2005 eq. 2.2 averages over object pixels; here those are the union of both coverage masks,
    so a missing or an extra silhouette pixel counts. The IoU weighs each pixel by its coverage (box-filtered
    frames cover edge pixels in part; for frames covering pixels wholly or not at all it is the masks' IoU). `classes` (vdmrender.tracing.borders, (H, W)): pixels
    that see an open border or the surface from inside are scored apart ("apart": their count and
    values); "mean" and "iou" are over the other, surface pixels, "mean_all" and "iou_all" over every
    pixel. A frame with no pixel to score has no data: it is `empty`, its mean and IoU are None, never
    a perfect score.
    """
    a, b = frame[..., 3] > 0, reference[..., 3] > 0
    union = a | b
    both, either = np.minimum(frame[..., 3], reference[..., 3]), np.maximum(frame[..., 3], reference[..., 3])
    dist = delta_luv(frame[..., :3], reference[..., :3])
    apart = np.zeros_like(union) if classes is None else (classes != 0)
    scored = union & ~apart
    d = dist[scored]
    # coverage overlap: intersection over union of the coverage fractions (of the masks where both are 0 or 1)
    iou = lambda m: float(both[m].sum(dtype=np.int64) / either[m].sum(dtype=np.int64)) if (union & m).any() else None  # noqa: E731
    return {"dist": np.where(union, dist, 0.0), "union": union, "scored": scored, "values": d, "empty": not scored.any(),
            "mean": float(d.mean()) if d.size else None, "iou": iou(~apart),
            "mean_all": float(dist[union].mean()) if union.any() else None, "iou_all": iou(np.ones_like(union)),
            "apart": {int(c): int((union & (classes == c)).sum()) for c in (1, 2)} if classes is not None else {},
            "apart_values": dist[union & apart]}


# FLIP's widest filter at 67 pixels per degree (Andersson et al. 2020, sec. 4): the colour pipeline's
# ceil(3 sqrt(b_max / 2 pi^2) ppd) = 10 px with b_max = 0.04, the feature detectors' 3 x 0.5 x 0.082 ppd = 8.2 px
FLIP_REACH = 16


def flip_values(frame: np.ndarray, reference: np.ndarray, scored: np.ndarray) -> np.ndarray:
    """NVIDIA FLIP (Andersson et al. 2020, LDR, default 67 pixels per degree) of the sRGB frame
    against the reference, at the `scored` pixels (those Vichitvejpaisal2005 eq. 2.2 averages over; none where there
    are none), each in [0, 1]. FLIP models what a viewer notices when flipping between the two images,
    so it sees edges and patterns: a second opinion beside ΔLuv, which weighs every pixel alone."""
    if not scored.any():
        return np.zeros(0)
    # FLIP's OpenMP threads would spin while waiting; on a shared CPU (CI, llvmpipe rendering beside
    # it) that costs 0.3 s per small frame instead of 0.01 s. Read once, when its libgomp loads.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    import flip_evaluator

    # FLIP is local: each pixel's value depends on the pixels within its filters' reach, so the scored pixels' box
    # plus that reach gives the same values as the whole frame (an object far away covers a few pixels of it)
    ys, xs = np.nonzero(scored)
    box = (slice(max(ys.min() - FLIP_REACH, 0), ys.max() + FLIP_REACH + 1),
           slice(max(xs.min() - FLIP_REACH, 0), xs.max() + FLIP_REACH + 1))
    ref, test = (np.ascontiguousarray(x[box][..., :3], np.float32) / 255 for x in (reference, frame))
    fmap, _, _ = flip_evaluator.evaluate(ref, test, "LDR", applyMagma=False, computeMeanError=False)
    return np.asarray(fmap, np.float64).reshape(ref.shape[:2])[scored[box]]


def _rounded(x, digits: int):
    return None if x is None else round(float(x), digits)


def pooled(scores: list[dict]) -> dict:
    """Frames' scores (compare's) as one: mean and p95 ΔLuv over every scored pixel of every frame, the IoU averaged
    over the frames that are not empty; None where there is nothing to pool."""
    d = np.concatenate([s["values"] for s in scores])
    full = [s["iou"] for s in scores if not s["empty"]]
    return {"mean_dluv": _rounded(d.mean(), 4) if d.size else None,
            "p95_dluv": _rounded(np.percentile(d, 95), 4) if d.size else None,
            "iou": _rounded(np.mean(full), 6) if full else None}


def summarise(scores: list[dict]) -> dict:
    """A variant's report fields from its frames' scores (compare's, each with "flip" values,
    "coverage" of the reference and a "nonfinite" pixel count): the error pooled over every scored
    pixel of every frame, the IoU averaged over frames; empty frames are counted and left out. With
    pixel classes (open borders), also the pixels scored apart and every pixel together."""
    d = np.concatenate([s["values"] for s in scores])
    fl = np.concatenate([s["flip"] for s in scores])
    full = [s for s in scores if not s["empty"]]
    per_frame = [{"frame": k, "empty": s["empty"], "mean_dluv": _rounded(s["mean"], 4), "iou": _rounded(s["iou"], 6),
                  "flip": _rounded(s["flip"].mean(), 5) if s["flip"].size else None,
                  "coverage": round(s["coverage"], 6), "nonfinite": s["nonfinite"]} for k, s in enumerate(scores)]
    row = {"empty_frames": len(scores) - len(full), **pooled(scores),
           "max_dluv": _rounded(d.max(), 4) if d.size else None,
           "flip_mean": _rounded(fl.mean(), 5) if fl.size else None,
           "coverage": round(float(np.mean([s["coverage"] for s in scores])), 6),
           "nonfinite": sum(s["nonfinite"] for s in scores), "per_frame": per_frame}
    if scores[0]["apart"]:   # scored apart (vdmrender.tracing.borders): the border and inside pixels, and every pixel
        border, inside = (sum(s["apart"][c] for s in scores) for c in (1, 2))
        apart = np.concatenate([s["apart_values"] for s in scores])
        union = d.size + apart.size
        whole = [s for s in scores if s["mean_all"] is not None]
        for p, s in zip(per_frame, scores):
            p.update(iou_all=_rounded(s["iou_all"], 6), border_px=s["apart"][1], inside_px=s["apart"][2])
        row.update(surface_px=int(d.size), border_px=border, inside_px=inside,
                   border_fraction=round(border / max(union, 1), 6), inside_fraction=round(inside / max(union, 1), 6),
                   mean_dluv_apart=_rounded(apart.mean(), 4) if apart.size else None,
                   mean_dluv_all=_rounded(np.concatenate([d, apart]).mean(), 4) if union else None,
                   iou_all=_rounded(np.mean([s["iou_all"] for s in whole]), 6) if whole else None)
    return row
