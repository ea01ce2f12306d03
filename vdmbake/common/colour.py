"""The sRGB transfer function (IEC 61966-2-1), both ways, shared by the bake (Jmol's sRGB atom colours,
albedo maps, viewer meshes' colours) and the renderer (frames encoded for output, 8-bit colours decoded
for the error metric)."""
from __future__ import annotations

import numpy as np


def srgb8_to_linear(rgb8) -> np.ndarray:
    """sRGB 8-bit values (0..255) to linear RGB in [0, 1]."""
    c = np.asarray(rgb8, np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def srgb_encode(c: np.ndarray) -> np.ndarray:
    """Linear values to sRGB-encoded values, clamped to [0, 1]."""
    c = np.clip(c, 0.0, 1.0)
    return np.where(c < 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


def to_srgb8(c) -> np.ndarray:
    """Linear values to 8-bit sRGB, clamped, rounded to nearest as the GL framebuffer conversion does."""
    return np.round(srgb_encode(c) * 255.0).astype(np.uint8)
