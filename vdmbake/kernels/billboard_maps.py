"""Enhanced billboards: what the renderer needs from each billboard's maps, computed once in the bake
(pure numpy; the maps themselves come from vdmbake.kernels.billboards).

The surface a billboard stands for is the bilinear interpolation of its depth map (Vichitvejpaisal2005
§3.1: the depth map is a height field over the billboard plane, ray-marched in Vichitvejpaisal2005 §3.3). Its samples
sit at texel centres, so the bilinear surface of the R x R map runs between them; with a one-texel border
it covers the whole box, [0, 1]^2 in map coordinates, as (R + 1)^2 bilinear cells ("texels" of the surface:
the square between four neighbouring samples).

* map_texels: normal and depth with that border; the border and the empty texels within PAD rings of
  covered ones are extrapolated from the covered ones (pad), so the surface continues with its slope past
  a silhouette or the map's edge instead of bending towards the empty texels' depth.
* empty_cells: the cells a ray passes through. A cell is covered if any of its four corner texels is
  (the improved march's coverage test, a textureGather of the alpha map at the hit): neighbouring
  billboards then overlap by up to a texel instead of leaving cracks between them.
* depth_pyramid: the min/max pyramid (vdmbake.common.pyramid, CLAMP mode) of the padded depth over those cells,
  the empty ones marked so that the hierarchical march skips them at every level.
* albedo_texels: the colour map (assets with colours only) with the same border, extended from the covered
  texels without extrapolation (a colour does not continue a slope).
* bordered: all of it as the bundle's `bordered-billboards` part holds it (vdmbake.bundle.parts.BorderedMaps).
"""
from __future__ import annotations

import numpy as np

from ..bundle import parts
from ..common import pyramid

PAD = 2   # rings of empty texels extrapolated around the covered ones (the bilinear surface reaches 1)
STEEP = 6.0   # map texels of depth per texel: steeper than any captured face (75.5 deg, 3.9 along a texel's
              # side, 5.5 along its diagonal), so only a depth discontinuity or a runaway extrapolation is


def pad(values: np.ndarray, valid: np.ndarray, rings: int = PAD, linear: bool = True) -> np.ndarray:
    """Empty texels within `rings` of covered ones, filled by linear extrapolation from them: each
    covered 8-neighbour n1 with a covered n2 beyond it (same direction) proposes 2 n1 - n2 (n1 alone
    otherwise); the proposals are averaged. Bilinear filtering between a covered texel and an empty one
    then continues the surface's slope (a steep rim stays steep), instead of bending it to depth 1.
    linear=False: each proposes n1 (the covered neighbours' mean), for colours: no overshoot, no texture
    detail amplified, and filtering at a silhouette keeps the edge texels' colour instead of fading to 0."""
    h, w = valid.shape
    v = values.astype(np.float32).copy()
    ok = valid.copy()
    around = [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj]
    for _ in range(rings):
        # this ring: the empty texels with a covered 8-neighbour (only they are computed: a thin band)
        op = np.pad(ok, 2)
        near = np.zeros_like(ok)
        for di, dj in around:
            near |= op[2 + di:2 + di + h, 2 + dj:2 + dj + w]
        i, j = np.nonzero(near & ~ok)
        if not len(i):
            break
        vp = np.pad(v, ((2, 2), (2, 2), (0, 0)))
        i, j = i + 2, j + 2
        acc, cnt = np.zeros((len(i), v.shape[-1]), np.float32), np.zeros(len(i), np.float32)
        for di, dj in around:
            n1, n2 = vp[i + di, j + dj], vp[i + 2 * di, j + 2 * dj]
            ok1, ok2 = op[i + di, j + dj], op[i + 2 * di, j + 2 * dj]
            acc += np.where(ok1[:, None], np.where(ok2[:, None] & linear, 2 * n1 - n2, n1), 0.0)
            cnt += ok1
        v[i - 2, j - 2] = acc / cnt[:, None]
        ok[i - 2, j - 2] = True
    return v


def map_texels(b) -> tuple[np.ndarray, np.ndarray]:
    """(R+2, R+2, 4) normal + depth with a one-texel border, and (R, R) coverage. The border and the
    empty texels near covered ones are extrapolated (pad): bilinear filtering in the outer half texel
    of the map then follows the surface's slope rather than the clamped edge texel."""
    covered = np.asarray(b.alpha) > 0.5
    res = covered.shape[0]
    values = np.zeros((res + 2, res + 2, 4), np.float32)
    values[..., 3] = 1.0
    values[1:-1, 1:-1, :3] = np.asarray(b.normal, np.float32)
    values[1:-1, 1:-1, 3] = np.asarray(b.depth, np.float32)
    valid = np.zeros((res + 2, res + 2), bool)
    valid[1:-1, 1:-1] = covered
    return pad(values, valid), covered


def empty_cells(covered: np.ndarray) -> np.ndarray:
    """(R+1, R+1) True for the bilinear cells of the bordered map with no covered corner. Corners in the
    border count as the map's edge texel next to them (the clamped textureGather of the improved march)."""
    c = np.pad(np.asarray(covered, bool), 1, mode="edge")
    return ~(c[:-1, :-1] | c[:-1, 1:] | c[1:, :-1] | c[1:, 1:])


def depth_pyramid(b, values: np.ndarray, covered: np.ndarray, steep: float | None = STEEP) -> pyramid.Pyramid:
    """The min/max pyramid of the bordered depth (map_texels' values and coverage of billboard b), empty
    cells marked. With `steep` (map texels of depth per texel), the surface does not bridge depth
    discontinuities: an extrapolated sample stays within that of the covered samples next to it, so a
    surface continues past its silhouette by a bounded skirt, not by a streak; and a cell whose corners
    still differ by more than that holds two surfaces (a thin tip in front of what lies behind it), not the
    wall the bilinear patch between them would make, so it is empty. The pyramid's samples are that
    clamped depth; the maps keep theirs (the improved march samples them)."""
    depth = values[..., 3].copy()
    empty = empty_cells(covered)
    if steep is not None:
        res = covered.shape[0]
        limit = steep * max(b.size[0], b.size[1]) / res / b.size[2]          # in box depths
        cov = np.zeros(depth.shape, bool)
        cov[1:-1, 1:-1] = covered
        # extrapolated samples: within `limit` of the covered ones among their 8 neighbours
        lo, hi = np.where(cov, depth, np.inf), np.where(cov, depth, -np.inf)
        pad_lo, pad_hi = np.pad(lo, 1, constant_values=np.inf), np.pad(hi, 1, constant_values=-np.inf)
        h, w = depth.shape
        n_lo = np.minimum.reduce([pad_lo[1 + i:1 + i + h, 1 + j:1 + j + w] for i in (-1, 0, 1) for j in (-1, 0, 1)])
        n_hi = np.maximum.reduce([pad_hi[1 + i:1 + i + h, 1 + j:1 + j + w] for i in (-1, 0, 1) for j in (-1, 0, 1)])
        near = ~cov & np.isfinite(n_lo)
        depth[near] = np.clip(depth[near], n_lo[near] - limit, n_hi[near] + limit)
        # a cell still steeper than that bridges a discontinuity (also through an extrapolated sample between
        # a thin feature and what lies behind it): no surface there
        c = pyramid.corners(depth, pyramid.CLAMP)
        empty |= c.max(-1) - c.min(-1) > limit
    return pyramid.build(depth, pyramid.CLAMP, empty)


def albedo_texels(b) -> np.ndarray | None:
    """(R+2, R+2, 3) billboard b's colour map with the one-texel border of map_texels, the border and the
    empty texels near covered ones holding the mean of their covered neighbours (pad, linear=False):
    the renderers read it bilinearly at the hit, which may lie up to a texel past the covered ones
    (the improved march's footprint test); None for a billboard without a colour map."""
    if b.albedo is None:
        return None
    covered = np.asarray(b.alpha) > 0.5
    values = np.zeros((covered.shape[0] + 2, covered.shape[1] + 2, 3), np.float32)
    values[1:-1, 1:-1] = np.asarray(b.albedo, np.float32)
    valid = np.pad(covered, 1)
    return pad(values, valid, linear=False)


def bordered(b, traced: bool, steep: float | None = STEEP) -> parts.BorderedMaps:
    """Billboard b's bordered maps, its colour map if it has one and, if `traced` (the hierarchical march
    renders it), its pyramid."""
    values, covered = map_texels(b)
    return parts.BorderedMaps(values, depth_pyramid(b, values, covered, steep) if traced else None, albedo_texels(b))
