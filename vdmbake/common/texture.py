"""Albedo maps: an asset's base-colour texture (or a mesostructure tile's colour) and the albedo of a
surface point (the shading model takes its albedo from a colour texture or a constant).

A map is (H, W, 3) uint8 sRGB, row 0 at texture v = 0 (the picture's bottom, as OBJ, glTF after its
flip, and GL's t = 0). Texels are decoded to linear before they are blended (the GL spec's order for
sRGB textures); `sample` is the numpy twin of the renderer's read (bilinear, wrapping, texel centres at
(i + 1/2) / W). The renderer uploads the decoded texels (`linear`, as half floats) rather than an sRGB8
texture: llvmpipe's sRGB8 decode is off by up to 2.5% on dark codes (docs/tuning.md has the error it
made). No mipmaps on either side, so the reference
and every technique see the same texture and the error measures the technique alone.
"""
from __future__ import annotations

import numpy as np

from .colour import srgb8_to_linear

MAX_PIXELS = 8192 * 8192   # the largest albedo picture, an asset's or a tile's (384 MiB of half-float texels)

_LINEAR = srgb8_to_linear(np.arange(256))   # the decode as a table: 256 values, exact per texel


def from_image(image) -> np.ndarray:
    """A PIL image (any mode) as an albedo map: RGB, row 0 at v = 0 (alpha is not albedo: dropped)."""
    return np.ascontiguousarray(np.asarray(image.convert("RGB"), np.uint8)[::-1])


def linear(albedo_map: np.ndarray) -> np.ndarray:
    """(H, W, 3) float64 linear albedo of every texel."""
    return _LINEAR[albedo_map]


def sample(albedo_map: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(N, 3) linear RGB at texture coordinates uv (N, 2), bilinear with wrap-around."""
    h, w = albedo_map.shape[:2]
    x = np.asarray(uv[:, 0], np.float64) * w - 0.5
    y = np.asarray(uv[:, 1], np.float64) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    i0, j0 = x0.astype(np.int64) % w, y0.astype(np.int64) % h
    i1, j1 = (i0 + 1) % w, (j0 + 1) % h
    # only the four texels each point reads are decoded
    t00, t01, t10, t11 = _LINEAR[albedo_map[np.stack([j0, j0, j1, j1]), np.stack([i0, i1, i0, i1])]]
    return (1 - fy) * ((1 - fx) * t00 + fx * t01) + fy * ((1 - fx) * t10 + fx * t11)


def has_albedo(mesh) -> bool:
    """True if the asset has its own albedo (per-vertex colours or an albedo map): what the techniques that
    bake their own maps (billboards, octahedral impostors) then store a colour map for."""
    return mesh.colors is not None or mesh.texture is not None


def surface_albedo(mesh, prim: np.ndarray, bary: np.ndarray, default) -> np.ndarray:
    """(N, 3) linear albedo at points of `mesh` given as triangle indices and barycentric weights (N, 3):
    the asset's per-vertex colours interpolated as the rasteriser interpolates them, times its albedo
    map at the interpolated UV; `default` (the material's albedo) where the asset has neither."""
    tri = mesh.faces[prim]
    w = np.asarray(bary, np.float64)[:, :, None]
    if not has_albedo(mesh):
        return np.broadcast_to(np.asarray(default, np.float64), (len(prim), 3))
    albedo = (w * mesh.colors[tri]).sum(1) if mesh.colors is not None else np.ones((len(prim), 3))
    if mesh.texture is not None:
        albedo = albedo * sample(mesh.texture, (w * mesh.uvs[tri]).sum(1))
    return albedo
