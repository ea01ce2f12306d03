"""Colour and error metrics: CIE 1976 L*u*v* and the thesis's average intensity difference (eq. 2.2).

Colours are 8-bit sRGB (IEC 61966-2-1: sRGB primaries, D65 white), decoded to linear RGB,
taken to CIE XYZ with the sRGB matrix, then to L*u*v* relative to the D65 white (Y_n = 1).
"""
from __future__ import annotations

import os

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


def compare(frame: np.ndarray, reference: np.ndarray) -> dict:
    """Error of one frame against the reference; both (H, W, 4) uint8 sRGB + coverage alpha.

    Eq. 2.2 averages over object pixels; here those are the union of both coverage masks,
    so a missing or an extra silhouette pixel counts. A frame where neither image covers a
    pixel has no data: it is `empty`, with no mean and no IoU (None), never a perfect score.
    """
    a, b = frame[..., 3] > 0, reference[..., 3] > 0
    union = a | b
    dist = delta_luv(frame[..., :3], reference[..., :3])
    d = dist[union]
    empty = not union.any()
    return {"dist": np.where(union, dist, 0.0), "union": union, "values": d, "empty": empty,
            "mean": None if empty else float(d.mean()),
            "iou": None if empty else float((a & b).sum() / union.sum())}


def flip_values(frame: np.ndarray, reference: np.ndarray, union: np.ndarray) -> np.ndarray:
    """NVIDIA FLIP (Andersson et al. 2020, LDR, default 67 pixels per degree) of the sRGB frame
    against the reference, at the pixels of `union` (those eq. 2.2 averages over; none where it is
    empty), each in [0, 1]. FLIP models what a viewer notices when flipping between the two images,
    so it sees edges and patterns: a second opinion beside ΔLuv, which weighs every pixel alone."""
    if not union.any():
        return np.zeros(0)
    # FLIP's OpenMP threads would spin while waiting; on a shared CPU (CI, llvmpipe rendering beside
    # it) that costs 0.3 s per small frame instead of 0.01 s. Read once, when its libgomp loads.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    import flip_evaluator

    ref, test = (np.ascontiguousarray(x[..., :3], np.float32) / 255 for x in (reference, frame))
    fmap, _, _ = flip_evaluator.evaluate(ref, test, "LDR", applyMagma=False, computeMeanError=False)
    return np.asarray(fmap, np.float64).reshape(union.shape)[union]
