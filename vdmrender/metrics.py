"""Colour and error metrics: CIE 1976 L*u*v* and the thesis's average intensity difference (eq. 2.2).

Colours are 8-bit sRGB (IEC 61966-2-1: sRGB primaries, D65 white), decoded to linear RGB,
taken to CIE XYZ with the sRGB matrix, then to L*u*v* relative to the D65 white (Y_n = 1).
"""
from __future__ import annotations

import numpy as np

from vdmbake.colour import srgb8_to_linear

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
    """Per-pixel Euclidean distance in L*u*v* (the summand of eq. 2.2)."""
    return np.linalg.norm(srgb8_to_luv(a_rgb8) - srgb8_to_luv(b_rgb8), axis=-1)


def compare(frame: np.ndarray, reference: np.ndarray, classes: np.ndarray | None = None) -> dict:
    """Error of one frame against the reference; both (H, W, 4) uint8 sRGB + coverage alpha.

    Eq. 2.2 averages over object pixels; here those are the union of both coverage masks,
    so a missing or an extra silhouette pixel counts. `classes` (vdmrender.borders, (H, W)): pixels
    that see an open border or the surface from inside are scored apart ("apart": their count and
    values), the mean and IoU are over the surface pixels; "mean_all" and "iou_all" keep every pixel.
    """
    a, b = frame[..., 3] > 0, reference[..., 3] > 0
    union = a | b
    dist = delta_luv(frame[..., :3], reference[..., :3])
    apart = np.zeros_like(union) if classes is None else (classes != 0)
    scored = union & ~apart
    d = dist[scored]
    iou = lambda m: float((a & b & m).sum() / (union & m).sum()) if (union & m).any() else 1.0  # noqa: E731
    return {"dist": np.where(union, dist, 0.0), "union": union, "values": d,
            "mean": float(d.mean()) if d.size else 0.0, "iou": iou(~apart),
            "mean_all": float(dist[union].mean()) if union.any() else 0.0, "iou_all": iou(np.ones_like(union)),
            "apart": {int(c): int((union & (classes == c)).sum()) for c in (1, 2)} if classes is not None else {},
            "apart_values": dist[union & apart]}
