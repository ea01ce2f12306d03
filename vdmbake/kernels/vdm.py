"""View-dependent displacement mapping: the bake (Wang2003 §3.1, §3.3 and Appendix).

Units are texture units: one tile of the height field spans [0, 1) x [0, 1); the mesostructure
lies inward of the reference surface z = 0, at z = -depth * (1 - h(x, y)), h in [0, 1] (1 = top).
Curvatures are in 1 / texture unit. The viewing vector V = (sin t cos p, sin t sin p, cos t)
points from the surface to the eye; the ray enters the surface at the texel along -V, and
d_VDM is the distance along it to the first mesostructure hit, -1 where there is none.
For curved surfaces d_VDM is the extended definition of Wang2003 Appendix, l / sin(theta), l the arc
length in texture space between the entry point and the hit, so that the real texture
coordinate is always T' = T - d_VDM * V_xy.

Table axes are sampled at bin centres (theta over [0, pi/2], phi over [0, 2 pi)), so the tables
are textures whose hardware interpolation and clamp / wrap addressing are the lookups;
curvatures are sampled endpoint-inclusive over the range the base mesh actually has.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..common.embree import RayScene


@dataclass(frozen=True)
class Sampling:
    size: int                   # texels per side of the height field (the paper: 128)
    n_phi: int = 32             # azimuths (the paper: 32)
    n_theta: int = 8            # polar angles (the paper: 8)
    curvatures: tuple = (0.0,)  # c samples (the paper: 16 in [-2, 3]); a plane needs only 0

    @property
    def thetas(self) -> np.ndarray:
        return (np.arange(self.n_theta) + 0.5) / self.n_theta * (np.pi / 2)

    @property
    def phis(self) -> np.ndarray:
        return (np.arange(self.n_phi) + 0.5) / self.n_phi * (2 * np.pi)


def curvature_samples(lo: float, hi: float, count: int) -> tuple:
    """Endpoint-inclusive samples of [lo, hi]; one sample (lo) when the range is a point."""
    return (float(lo),) if hi <= lo or count < 2 else tuple(np.linspace(lo, hi, count).tolist())


def view_vectors(thetas, phis) -> np.ndarray:
    """(n_phi, n_theta, 3) unit viewing vectors in the local frame (z = surface normal)."""
    t, p = np.meshgrid(thetas, phis)
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)


def padding_texels(depth: float, sampling: Sampling) -> int:
    """Texels to add around the tile so every sampled ray meets the mesostructure's floor before
    leaving the patch: its horizontal reach is depth * tan(theta_max)."""
    return int(np.ceil(depth * np.tan(sampling.thetas[-1]) * sampling.size)) + 1


def mesostructure_mesh(heights: np.ndarray, depth: float, pad: int) -> tuple[np.ndarray, np.ndarray]:
    """The zero-curvature mesostructure: vertices at texel centres, z = -depth (1 - h), over the
    tile [0, 1)^2 plus `pad` texels of its periodic continuation on every side."""
    n = heights.shape[0]
    idx = np.arange(-pad, n + pad)
    m = len(idx)
    coord = (idx + 0.5) / n
    h = heights[np.ix_(idx % n, idx % n)]
    Y, X = np.meshgrid(coord, coord, indexing="ij")
    v = np.stack([X, Y, -depth * (1.0 - h)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(m - 1), np.arange(m - 1), indexing="ij")
    a = (i * m + j).ravel()
    f = np.concatenate([np.stack([a, a + 1, a + m + 1], 1), np.stack([a, a + m + 1, a + m], 1)])
    return v, f


def height_normals(heights: np.ndarray, depth: float) -> np.ndarray:
    """(N, N, 3) texture-space unit normals of the mesostructure mesh at its vertices (the texel
    centres), area-weighted over the six incident triangles: the shading normals of every
    mesostructure technique, and what the displaced reference's vertex normals converge to."""
    from ..common.mesh import vertex_normals

    n = heights.shape[0]
    v, f = mesostructure_mesh(heights, depth, 1)
    return vertex_normals(v, f).reshape(n + 2, n + 2, 3)[1:-1, 1:-1]


def flat_rays(sampling: Sampling, eps: float, rows: slice = slice(None)) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions of the zero-curvature bake: for every texel centre (rows y, columns x)
    and view (phi, theta), a ray along -V. Rays start eps above the reference surface (a ray
    starting on a top texel could slip under the one-sided sheet); vdm_flat takes eps / cos(theta) off.
    `rows`: only these texel rows (y), in the same order (vdm_flat casts them block by block)."""
    n = sampling.size
    c = (np.arange(n) + 0.5) / n
    Y, X = np.meshgrid(c[rows], c, indexing="ij")
    origins = np.stack([X, Y, np.full_like(X, eps)], -1).reshape(-1, 1, 3)
    dirs = -view_vectors(sampling.thetas, sampling.phis).reshape(1, -1, 3)
    return (np.broadcast_to(origins, (len(origins), dirs.shape[1], 3)).reshape(-1, 3),
            np.broadcast_to(dirs, (len(origins), dirs.shape[1], 3)).reshape(-1, 3))


FLAT_BLOCK_RAYS = 1 << 19   # rays generated and cast per block: their arrays stay small, nothing waits on a copy


def vdm_flat(heights: np.ndarray, depth: float, sampling: Sampling, scene: RayScene | None = None,
             on_block=None):
    """Zero-curvature VDM by ray casting (Wang2003 §3.1): (N, N, n_phi, n_theta) float32 distances,
    the ray count, and the Embree scene (reusable). Rows are y, columns x (image order).
    on_block(out, rows): called with the table and each block of texel rows (a slice) once it is cast."""
    n = sampling.size
    if depth <= 0:
        out = np.zeros((n, n, sampling.n_phi, sampling.n_theta), np.float32)
        if on_block:
            on_block(out, slice(0, n))
        return out, 0, scene
    if scene is None:
        scene = RayScene(*mesostructure_mesh(heights, depth, padding_texels(depth, sampling)))
    eps = 1e-4 * depth
    extra = (eps / np.cos(sampling.thetas)).astype(np.float32)
    before = scene.rays_cast
    out = np.empty((n, n, sampling.n_phi, sampling.n_theta), np.float32)
    step = max(1, FLAT_BLOCK_RAYS // (n * sampling.n_phi * sampling.n_theta))   # texel rows per block
    for y in range(0, n, step):
        t = scene.distances(*flat_rays(sampling, eps, slice(y, y + step)))
        t = t.reshape(-1, n, sampling.n_phi, sampling.n_theta)
        out[y:y + step] = np.where(t >= 0, np.maximum(t - extra, 0.0), -1.0)
        if on_block:
            on_block(out, slice(y, min(y + step, n)))
    return out, scene.rays_cast - before, scene


def bend(s: np.ndarray, h: np.ndarray, c) -> tuple[np.ndarray, np.ndarray]:
    """A point at arc length s along the view's azimuth and depth h below the reference surface,
    after bending the surface to curvature c about the entry point (origin, normal +z'):
    returns its 2-D position (x along the azimuth, y up): x = (1 - h c) sin(s c) / c,
    y = (cos(s c) - 1) / c - h cos(s c), written with the half-angle sine so that small s c loses no
    digits ((cos a - 1) = -2 sin^2(a / 2)) and c = 0 is the flat case exactly. c may be an array too."""
    if np.ndim(c) == 0 and c == 0:
        return np.asarray(s, np.float64) + 0.0, -np.asarray(h, np.float64)
    flat = np.asarray(c) == 0
    c = np.where(flat, 1.0, c) if np.ndim(c) else c
    sc = s * c
    half = np.sin(0.5 * sc)
    sin2 = 2.0 * half * half                      # 1 - cos(s c)
    x = (1.0 - h * c) * np.sin(sc) / c
    y = -sin2 / c - h * (1.0 - sin2)
    if np.ndim(flat) and flat.any():
        x, y = np.where(flat, s, x), np.where(flat, -np.asarray(h, np.float64), y)
    return x, y


CHUNK_ROWS = 8192  # rows (x, y, phi) per block: the (rows, theta, sample) temporaries stay in cache


def hit_geometry(d_flat: np.ndarray, sampling: Sampling) -> tuple:
    """The curvature-independent part of Wang2003 Appendix's resampling, computed once per table: which
    zero-curvature samples hit (valid), their extended d (0 where none), and the arc length s and depth
    h of each hit below its entry point. Theta-major: (n_theta, rows) for d_flat (..., n_theta), so the
    per-row scans over theta (running maximum, ranks, counts) run across whole rows at once."""
    th = sampling.thetas[:, None]
    d = d_flat.reshape(-1, d_flat.shape[-1]).T
    valid = d >= 0
    dd = np.where(valid, d, 0.0).astype(np.float64)
    return valid, dd, dd * np.sin(th), dd * np.cos(th)


def vdm_curved(d_flat: np.ndarray, sampling: Sampling, c: float, geometry: tuple | None = None,
               out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Wang2003 Appendix's resampling (resample_columns) over cache-sized blocks of rows: (table, horizon) of
    d_flat's shape and its shape less theta. `geometry`: hit_geometry(d_flat) when several curvatures share
    it; `out`: where to write the table (any view of d_flat's shape whose leading axes are contiguous)."""
    rows = d_flat.reshape(-1, d_flat.shape[-1])
    geometry = geometry or hit_geometry(rows, sampling)
    res = np.empty(d_flat.shape, np.float32) if out is None else out
    res_rows = res.reshape(rows.shape, copy=False)       # a view, never a copy
    horizon = np.empty(len(rows), np.float32)
    for s in range(0, len(rows), CHUNK_ROWS):
        b = slice(s, s + CHUNK_ROWS)
        r, horizon[b] = resample_columns(tuple(g[:, b] for g in geometry), sampling, c)
        res_rows[b] = r.T
    return res, horizon.reshape(d_flat.shape[:-1])


def vdm_curved_rows(d_flat: np.ndarray, sampling: Sampling, c: float) -> tuple[np.ndarray, np.ndarray]:
    """resample_columns for rows (rows, n_theta) of zero-curvature distances: (rows, n_theta), (rows,)."""
    r, horizon = resample_columns(hit_geometry(d_flat, sampling), sampling, c)
    return r.T.copy(), horizon


def _scan(op, a: np.ndarray) -> np.ndarray:
    """op.accumulate over axis 0 as one vector op per row (numpy's accumulate along the first axis of a
    C-ordered array runs column by column)."""
    out = np.empty_like(a)
    out[0] = a[0]
    for k in range(1, len(a)):
        op(out[k - 1], a[k], out=out[k])
    return out


def resample_columns(geometry: tuple, sampling: Sampling, c: float) -> tuple[np.ndarray, np.ndarray]:
    """Wang2003 Appendix's curvature resampling: bend the zero-curvature hit points to curvature c,
    take their new viewing angles theta', drop those that became occluded (theta' not above
    every earlier one), resample linearly at the uniform thetas; -1 past the last hit on a
    convex surface (the ray leaves it). Values are the extended d = l / sin(theta).
    geometry: hit_geometry's (n_theta, m) columns; returns the table (n_theta, m) float32 and each
    column's horizon (m,): the largest theta' of a kept hit (pi / 2 for a hit at the entry point;
    0 if none), the exact edge of the valid range that the uniform samples only bracket."""
    th = sampling.thetas[:, None]
    valid, dd, s, h = geometry                          # arc length s and depth h of each hit
    with np.errstate(divide="ignore", invalid="ignore"):
        # The bent hit (bend) seen from the entry point: theta' = atan2(x, -y) = pi / 2 + atan(y / x) while
        # x > 0 (the hit lies ahead of its entry point), and the extended displacement l / sin(theta') with
        # 1 / sin(theta') = sqrt(1 + (y / x)^2). With tau = tan(s c / 2), y / x = -(2 tau^2 + h c (1 - tau^2)) /
        # (2 (1 - h c) tau): one tangent instead of bend's two sines. c = 0 is the flat case, y / x = -h / s.
        hc = h * c
        if c == 0:
            t = -h / s
        else:
            tau = np.tan(0.5 * c * s)
            tau2 = tau * tau
            t = -(2.0 * tau2 + hc * (1.0 - tau2)) / (2.0 * (1.0 - hc) * tau)
        hit = s > 0                                     # a hit at the entry point keeps its angle
        th_new = np.where(hit, np.pi / 2 + np.arctan(t), th)
        ext = np.where(hit, s * np.sqrt(1.0 + t * t), dd)
        # bent past a half turn or below the centre of curvature: x <= 0 (rare; checked on the block first)
        if c != 0 and (float(h.max()) * c >= 1.0 or float(s.max()) * abs(c) >= np.pi) and \
                (wrapped := hit & ((hc >= 1.0) | (np.abs(c * s) >= np.pi))).any():
            x, y = bend(s[wrapped], h[wrapped], c)
            th_new[wrapped] = np.arctan2(x, -y)
            ext[wrapped] = s[wrapped] / np.sin(th_new[wrapped])
    # Occlusion after bending: keep a sample only if its angle exceeds every earlier one; the
    # kept samples are then increasing in theta' in index order, so no sort is needed.
    run = _scan(np.maximum, np.where(valid, th_new, -np.inf))
    keep = valid.copy()
    keep[1:] &= th_new[1:] > run[:-1]
    # Kept samples, compacted by rank (they increase in theta' with their index), and for every
    # target theta_j the number of kept samples at or below it: O(samples) work per column.
    n, m = th_new.shape
    th32 = sampling.thetas.astype(np.float32)
    th_new, ext = th_new.astype(np.float32), ext.astype(np.float32)
    col = np.arange(m)
    rank = _scan(np.add, keep.astype(np.int64)) - 1
    kept = rank[-1] + 1
    slot = (rank * m + col)[keep]
    comp_ang = np.full(n * m, np.inf, np.float32)
    comp_val = np.zeros(n * m, np.float32)
    comp_ang[slot], comp_val[slot] = th_new[keep], ext[keep]
    first_target = np.zeros((n, m), np.int64)                # targets below theta'_k: theta'_k <= theta_j iff j >= it
    for t in th32:
        first_target += th_new > t
    counts = np.bincount((first_target * m + col)[keep], minlength=(n + 1) * m).reshape(n + 1, m)
    below = _scan(np.add, counts[:n])                                    # kept samples at or below theta_j
    has_lo, has_hi = below >= 1, below < kept
    i0 = np.clip(below - 1, 0, n - 1) * m + col           # flat indices of the bracketing kept samples
    i1 = np.clip(below, 0, n - 1) * m + col
    a0, a1, v0, v1 = comp_ang.take(i0), comp_ang.take(i1), comp_val.take(i0), comp_val.take(i1)
    th32 = th32[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(has_lo & has_hi, (th32 - a0) / (a1 - a0), np.float32(0))
    r = np.where(has_lo & has_hi, v0 + w * (v1 - v0), np.where(has_hi, v1, v0))  # clamp outside the samples
    if c > 0:                                    # convex: past the last hit the ray leaves the surface
        r = np.where(has_hi | (a0 >= th32), r, -1.0)
    # A hit at the entry point (d = 0: the mesostructure touches the reference surface) is hit from every
    # angle up to the horizon.
    top = np.float32(np.pi / 2)
    horizon = np.where((keep & ~hit).any(0), top, np.minimum(np.where(keep, th_new, np.float32(0)).max(0), top))
    return np.where(has_lo | has_hi, r, -1.0).astype(np.float32), horizon


def mvm(vdm: np.ndarray, sampling: Sampling, horizons: dict | None = None) -> np.ndarray:
    """Maximal View polar angle Map (Wang2003 §3.3): theta_MVM(x, y, phi, c), the largest theta with
    d != -1. The uniform samples only bracket it: the upper edge of the last valid sample's bin
    is taken (pi / 2 where every sample is valid, so a flat or concave patch never clips grazing
    views; 0 where none is), or, for the convex curvatures in `horizons` (c index -> (N, N, n_phi)
    from vdm_curved), the exact angle of the last visible hit. (N, N, n_phi, n_theta, n_c) -> (N, N, n_phi, n_c)."""
    out = np.empty(vdm.shape[:3] + vdm.shape[4:], np.float32)
    for i in range(vdm.shape[-1]):
        out[..., i] = mvm_slice(vdm[..., i], sampling, (horizons or {}).get(i))
    return out


def mvm_slice(vdm_c: np.ndarray, sampling: Sampling, horizon: np.ndarray | None = None) -> np.ndarray:
    """mvm for one curvature: (N, N, n_phi, n_theta) -> (N, N, n_phi); `horizon` for a convex one."""
    ok = vdm_c >= 0
    if horizon is not None:
        return np.where(ok.any(-1), horizon, np.float32(0))
    edge = sampling.thetas + 0.25 * np.pi / sampling.n_theta
    return np.where(ok, edge, 0.0).max(axis=-1).astype(np.float32)


ERROR_BLOCK_ROWS = 16384   # rows of A per block of the reconstruction-error pass


def bake_bytes(size: int, n_phi: int, n_theta: int, n_c: int, k: int | str) -> int:
    """The peak memory of bake_tables, compress and the storage choice for k eigenfunctions ("all": every
    column), estimated (vdmbake.bundle.budget): 3 bytes per byte of the float32 table plus 3 more for the
    weights of every column kept, and 128 MiB besides (measured: 2.75 bytes per table byte at k = 4 of 144
    columns, 5.8 with all of them, on a 268 MB table; 128 MiB for the rest of the process)."""
    table = size * size * n_phi * n_theta * n_c * 4
    columns = n_theta * n_c + n_c
    kept = 1.0 if k == "all" else min(k, columns) / columns
    return int(table * (3 + 3 * kept)) + (128 << 20)


@dataclass
class Compressed:
    W: np.ndarray        # (N, N, n_phi, k) weights of the eigenfunctions
    E_vdm: np.ndarray    # (k, n_theta, n_c)
    E_mvm: np.ndarray    # (k, n_c)
    rank: int            # numerical rank of A (k is capped at it)
    errors: dict         # k -> Truncation, for k itself and every k asked for in `report`


@dataclass
class Truncation:
    energy: float        # fraction of sum(sigma^2) kept
    rms_vdm: float       # reconstruction RMS of d over the valid entries (texture units)
    rms_mvm: float       # reconstruction RMS of theta_MVM (radians)
    max_abs_vdm: float   # largest |error| of d over the valid entries


def compress(vdm: np.ndarray, theta_mvm: np.ndarray, k: int, report=()) -> Compressed:
    """SVD of A = [A_VDM, A_MVM] (Wang2003 §3.3): rows (x, y, phi), columns (theta, c) then (c); the -1
    entries of A_VDM are replaced by the MVM angle first. Computed from the Gram matrix A^T A
    (columns are few), float64; W = A E. k is capped at the matrix rank; the reconstruction
    error is measured for k and for every smaller k in `report` (the first k columns of E are
    the best rank-k approximation, so one decomposition serves them all)."""
    n, _, n_phi, n_theta, n_c = vdm.shape
    rows, cols = n * n * n_phi, n_theta * n_c
    A = np.empty((rows, cols + n_c), np.float32)          # built in place: the tables are large
    a_vdm = A[:, :cols].reshape(rows, n_theta, n_c)
    invalid = (vdm < 0).reshape(rows, n_theta, n_c)
    np.copyto(a_vdm, vdm.reshape(rows, n_theta, n_c))
    np.copyto(a_vdm, np.broadcast_to(theta_mvm.reshape(rows, 1, n_c), a_vdm.shape), where=invalid)
    A[:, cols:] = theta_mvm.reshape(rows, n_c)
    gram = (A.T @ A).astype(np.float64)   # float32 sgemm over the long axis; the small eigenproblem in float64
    sigma2, E = np.linalg.eigh(gram)
    sigma2, E = sigma2[::-1].clip(min=0.0), E[:, ::-1]
    rank = int((sigma2 > sigma2[0] * 1e-12).sum()) if sigma2[0] > 0 else 0
    k = max(1, min(k, rank if rank else 1))
    E = E[:, :k].astype(np.float32)
    W = A @ E
    invalid = invalid.reshape(rows, cols)
    valid = invalid.size - np.count_nonzero(invalid)
    total = sigma2.sum()
    errors = {}
    for kk in sorted({min(max(1, int(r)), k) for r in report} | {k}):
        sq_vdm = sq_mvm = max_vdm = 0.0
        for s in range(0, rows, ERROR_BLOCK_ROWS):        # the residual block by block, in cache
            b = slice(s, s + ERROR_BLOCK_ROWS)
            err = W[b, :kk] @ E[:, :kk].T
            err -= A[b]
            err_vdm = err[:, :cols]
            err_vdm[invalid[b]] = 0.0                     # the -1 entries are the MVM's business
            sq_vdm += float(np.einsum("ij,ij->", err_vdm, err_vdm, dtype=np.float64))
            sq_mvm += float(np.einsum("ij,ij->", err[:, cols:], err[:, cols:], dtype=np.float64))
            max_vdm = max(max_vdm, float(np.abs(err_vdm).max()))
        errors[kk] = Truncation(
            energy=float(sigma2[:kk].sum() / total) if total > 0 else 1.0,
            rms_vdm=float(np.sqrt(sq_vdm / valid)) if valid else 0.0,
            rms_mvm=float(np.sqrt(sq_mvm / (rows * n_c))),
            max_abs_vdm=max_vdm if valid else 0.0)
    return Compressed(W=W.reshape(n, n, n_phi, k), E_vdm=E[:cols].T.reshape(k, n_theta, n_c).copy(),
                      E_mvm=E[cols:].T.copy(), rank=rank, errors=errors)


def bake_tables(heights: np.ndarray, depth: float, sampling: Sampling) -> tuple[np.ndarray, np.ndarray, int]:
    """The full 5-D VDM (N, N, n_phi, n_theta, n_c) and the MVM (N, N, n_phi, n_c), and rays cast.
    Every row (x, y, phi) is resampled on its own, so the work is pipelined: while Embree casts the next
    block of texel rows (it releases the GIL), worker threads resample the blocks already cast, one task per
    block and curvature (numpy releases the GIL in its kernels), each writing its slice of both tables in
    place; the curvature-independent part of the resampling is computed once per block."""
    from concurrent.futures import ThreadPoolExecutor

    cs = sampling.curvatures
    n = sampling.size
    table = np.empty((n, n, sampling.n_phi, sampling.n_theta, len(cs)), np.float32)
    theta_mvm = np.empty((n, n, sampling.n_phi, len(cs)), np.float32)

    def one(flat_rows: np.ndarray, rows: slice, i: int, geometry) -> None:
        part = table[rows, ..., i]
        if cs[i] == 0:
            part[...], horizon = flat_rows, None
        else:
            _, horizon = vdm_curved(flat_rows, sampling, cs[i], geometry, out=part)
        theta_mvm[rows, ..., i] = mvm_slice(part, sampling, horizon if cs[i] > 0 else None)

    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        tasks = []

        def on_block(flat: np.ndarray, rows: slice) -> None:
            flat_rows = flat[rows]
            geometry = hit_geometry(flat_rows, sampling) if any(c != 0 for c in cs) else None
            tasks.extend(pool.submit(one, flat_rows, rows, i, geometry) for i in range(len(cs)))

        _, rays, _ = vdm_flat(heights, depth, sampling, on_block=on_block)
        for t in tasks:
            t.result()                            # re-raises a worker's exception
    return table, theta_mvm, rays
