"""Octahedral impostors: the bake (Brucks 2018, "Octahedral Impostors", shaderbits.com; the
technique of Unreal Engine's impostor baker used in Fortnite, and of Amplify Impostors), pure
numpy + Embree.

The object is photographed from N x N directions that lie on the lattice points of an octahedral
map of the sphere of directions (or of the upper hemisphere: "hemi-octahedral"), each photograph
an orthographic R x R view of the object's bounding sphere, all in ONE atlas of N R x N R texels.
A texel holds the surface's normal (in the view's own frame, octahedrally encoded), its depth along
the view (0 at the front of the bounding sphere's box, 1 at its back), coverage (0 or 1) and, for an
asset with its own colours (per-vertex colours or an albedo map), the surface's linear albedo there (as
Brucks' and Amplify's impostors store base colour beside the normal and depth); without them the
colour is the material's constant albedo and none is stored.

At render time (vdmrender/techniques/octahedral.py, shaders/include/octahedral.glsl) a pixel's
direction picks the lattice triangle it falls in: its three views and barycentric weights
(`nearest_views`, the numpy twin of the shader's). Every view is then intersected with the pixel's
ray in that view's frame (a ray / depth-map search) and the three hits are blended.

Conventions:
* The octahedral map (Meyer et al. 2010, "On floating-point normal vectors"; Cigolle et al. 2014):
  a unit direction d = (x, y, z) goes to p = (x, y) / (|x| + |y| + |z|), the lower half (z < 0)
  folded over the diagonals: p <- (1 - |p.yx|) sign(p). It covers the square [-1, 1]^2; the four
  corners are -z, the centre +z. The hemi-octahedral map of z >= 0 rotates the upper half's diamond
  by 45 degrees to fill the square: (u, v) = (p.x + p.y, p.x - p.y); its border is the horizon.
* Views sit on the lattice points g_ij = -1 + 2 (i, j) / (N - 1) (Brucks: the subdivided octahedron's
  vertices), i along u (atlas column tile), j along v (row tile). On the full map the border views
  repeat directions (a point (1, v) is the same direction as (1, -v)); every direction then falls in
  a lattice cell whose four corners are real views, and no wrapping is needed.
* Each cell is cut into two triangles along the diagonal parallel to the map's creases (the full
  map's equator |u| + |v| = 1, the hemi map's meridians u = +-v). For odd N the creases are lattice
  lines, so every triangle lies on one face of the octahedron and the blend is linear on it.
* A map frame `basis` (rows x, y, z; z up) turns world directions into the map's: the hemisphere is
  the one above the scene's up axis, and the full map's centre is the top-down view.
* View k looks along -e_k (e_k: from the object towards the viewer), axes u_k, v_k with
  u_k x v_k = e_k (a camera's right, up, back: Duff et al. 2017's branchless frame around e_k,
  see view_frames).
  Its square spans [-capture, capture]^2 in (u_k, v_k) around the bounding sphere's centre;
  capture = radius R / (R - 2 EMPTY), so that EMPTY rings of texels around every tile are always
  empty (the object lies inside the inscribed disk), and neither filtering nor the renderer's
  padding crosses from one tile into another.

Geometry is handled relative to the bounding-sphere centre (float64) and Embree anchors its float32
copy there too, so a model far from the origin bakes like the same model at it. Outputs are
deterministic (independent of thread scheduling).
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from . import billboard_maps
from ..bundle import budget, parts
from ..common import texture
from ..common.embree import RayScene
from ..errors import InputError
from ..common.mesh import validate
from ..common.mesh import TriMesh

EMPTY = 3            # rings of texels around every tile that the object never covers (see capture)
MIN_RESOLUTION = 16  # below this the empty rings take over the tile
MAX_ATLAS = 16384    # the atlas side N R, at most GL_MAX_TEXTURE_SIZE of common drivers (llvmpipe: 16384)
BAND_RAYS = 1 << 20  # rays one task of the bake casts at most: its arrays stay near 200 MB whatever N and R
# Peak bytes per atlas texel, without and with colour, while the part is padded, packed and read back, and while
# it is cast; and per ray in flight (bake_bytes; measured on 16 M texels: 62 to 69 and 94 bytes, 208 a ray).
PART_BYTES, CAST_BYTES, RAY_BYTES = (72, 96), (16, 28), 210


@dataclass(frozen=True)
class Settings:
    views: int = 13           # N: views per side of the octahedral map (N^2 views; odd N puts creases on the lattice)
    resolution: int = 64      # R: texels per side of every view
    hemi: bool = False        # the upper hemisphere only (hemi-octahedral), else the full sphere


@dataclass
class Atlas:
    settings: Settings
    centre: np.ndarray        # (3,) world centre of the bounding sphere: every view's centre
    radius: float             # the bounding sphere's radius (the renderer clips rays to it)
    capture: float            # half side of every view's square, world units
    basis: np.ndarray         # (3, 3) rows x, y, z of the octahedral map's frame (z: up)
    normal: np.ndarray        # (N R, N R, 2) float32 in [-1, 1]: the normal in its view's frame (u, v, e), octahedral code
    depth: np.ndarray         # (N R, N R) float32 in [0, 1] along -e_k, 1 where not covered
    coverage: np.ndarray      # (N R, N R) float32, 1 where a surface was hit
    rays: int
    albedo: np.ndarray | None = None   # (N R, N R, 3) float32 linear RGB albedo, 0 where not covered; None: no colours


def _sign(x):
    """+1 for x >= 0 (also -0.0), -1 otherwise: the shader's (x >= 0.0 ? 1.0 : -1.0)."""
    return np.where(x >= 0, 1.0, -1.0)


def encode(d: np.ndarray, hemi: bool = False) -> np.ndarray:
    """(..., 3) directions (need not be unit) -> (..., 2) map points in [-1, 1]^2.
    hemi: directions below the horizon are first moved onto it (z -> 0)."""
    d = np.asarray(d, np.float64)
    if hemi:
        d = np.concatenate([d[..., :2], np.maximum(d[..., 2:], 0.0)], -1)
    l1 = np.abs(d).sum(-1, keepdims=True)
    p = d[..., :2] / np.maximum(l1, 1e-300)
    if hemi:
        return np.stack([p[..., 0] + p[..., 1], p[..., 0] - p[..., 1]], -1)
    folded = (1.0 - np.abs(p[..., ::-1])) * _sign(p)
    return np.where(d[..., 2:] < 0, folded, p)


def decode(g: np.ndarray, hemi: bool = False) -> np.ndarray:
    """(..., 2) map points in [-1, 1]^2 -> (..., 3) unit directions (inverse of encode)."""
    g = np.asarray(g, np.float64)
    if hemi:
        g = np.stack([g[..., 0] + g[..., 1], g[..., 0] - g[..., 1]], -1) * 0.5
    z = 1.0 - np.abs(g).sum(-1, keepdims=True)
    xy = np.where(z < 0, (1.0 - np.abs(g[..., ::-1])) * _sign(g), g)
    d = np.concatenate([xy, z], -1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def map_basis(up) -> np.ndarray:
    """Rows x, y, z of the octahedral map's frame, z along `up`; identity for up = +z."""
    z = np.asarray(up, np.float64)
    z = z / np.linalg.norm(z)
    a = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = a - z * (z @ a)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def lattice(views: int) -> np.ndarray:
    """(N,) map coordinates of the lattice lines: -1 + 2 i / (N - 1)."""
    return -1.0 + 2.0 * np.arange(views) / (views - 1)


def view_frames(views: int, hemi: bool = False, basis=np.eye(3)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, N, 3) world unit vectors e, u, v of view (i, j) at [j, i] (row j, column i): e towards the
    viewer, u x v = e. The frame is built in the map's frame (Duff et al. 2017's branchless frame around
    e) and turned to world by `basis`; the sign of e.z that chooses its branch is decided on the lattice
    integers (|2i - N + 1| + |2j - N + 1| <= N - 1: the upper half of the full map), not on a rounded
    z, so that the shader's twin picks the same branch for the views on the equator."""
    g = lattice(views)
    gu, gv = np.meshgrid(g, g)         # [j, i]
    e = decode(np.stack([gu, gv], -1), hemi)
    k = np.abs(2 * np.arange(views) - (views - 1))
    upper = (k[None, :] + k[:, None] <= views - 1) | hemi
    s = np.where(upper, 1.0, -1.0)
    x, y, z = e[..., 0], e[..., 1], e[..., 2]
    a = -1.0 / (s + z)
    b = x * y * a
    u = np.stack([1.0 + s * x * x * a, s * b, -s * x], -1)
    v = np.stack([b, s + y * y * a, -y], -1)
    basis = np.asarray(basis, np.float64)
    return e @ basis, u @ basis, v @ basis


# The two triangles of a lattice cell (corner offsets from its lower-left view) when it is cut along its
# main diagonal (lower: fx >= fy, upper) or its other diagonal (lower: fx + fy <= 1, upper); the weights
# in nearest_views follow the same order.
_TRIANGLES = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [0, 1], [1, 1]],
                       [[0, 0], [1, 0], [0, 1]], [[1, 0], [0, 1], [1, 1]]])


def nearest_views(e: np.ndarray, views: int, hemi: bool = False, basis=np.eye(3)):
    """The lattice triangle each direction falls in: (..., 3, 2) integer view indices (i, j) and
    (..., 3) barycentric weights (>= 0, summing to 1; the point of the map is their weighted mean).
    e: (..., 3) world directions towards the viewer (need not be unit)."""
    if views < 2:
        raise InputError(f"octahedral: views = {views}; it must be at least 2.")
    g = encode(np.asarray(e, np.float64) @ np.asarray(basis, np.float64).T, hemi)
    x = (g + 1.0) * 0.5 * (views - 1)
    c = np.clip(np.floor(x), 0, views - 2)
    f = np.clip(x - c, 0.0, 1.0)
    fx, fy = f[..., 0], f[..., 1]
    mid = (c + 0.5) / (views - 1) * 2.0 - 1.0
    # The cut of the cell: along its main diagonal (0,0)-(1,1), or its other one (1,0)-(0,1),
    # whichever is parallel to the map's creases in this quadrant.
    main = (mid[..., 0] * mid[..., 1] < 0) != hemi
    lower = np.where(main, fx >= fy, fx + fy <= 1.0)
    case = 2 * (~main) + (~lower)                    # indexes _TRIANGLES
    tri = _TRIANGLES[case]
    w = np.stack([np.stack([1 - fx, fx - fy, fy], -1), np.stack([1 - fy, fy - fx, fx], -1),
                  np.stack([1 - fx - fy, fx, fy], -1), np.stack([1 - fy, 1 - fx, fx + fy - 1], -1)])
    w = np.take_along_axis(w, case[None, ..., None], 0)[0]
    return (c[..., None, :] + tri).astype(np.int64), w


def _check(s: Settings):
    if not (isinstance(s.views, int) and s.views >= 2):
        raise InputError(f"octahedral: views = {s.views}; it must be an integer of at least 2.")
    if not (isinstance(s.resolution, int) and s.resolution >= MIN_RESOLUTION):
        raise InputError(f"octahedral: resolution = {s.resolution}; it must be an integer of at least "
                         f"{MIN_RESOLUTION} (texels per view side).")
    if s.views * s.resolution > MAX_ATLAS:
        raise InputError(f"octahedral: views x resolution = {s.views} x {s.resolution} = "
                         f"{s.views * s.resolution} texels per atlas side; at most {MAX_ATLAS}.")


def bake_bytes(settings: Settings, coloured: bool = False) -> int:
    """The peak memory of bake, to_part and the bundle's read-back of the part, estimated (vdmbake.bundle.budget):
    the larger of the part's phase and the casting's, whose tasks in flight are one per CPU."""
    texels = (settings.views * settings.resolution) ** 2
    return max(texels * PART_BYTES[coloured],
               texels * CAST_BYTES[coloured] + (os.cpu_count() or 1) * BAND_RAYS * RAY_BYTES)


def capture_half(radius: float, resolution: int) -> float:
    """Half side of every view's square: the bounding sphere plus EMPTY rings of texels."""
    return radius * resolution / (resolution - 2 * EMPTY)


def bake(mesh: TriMesh, settings: Settings = Settings(), up=(0.0, 0.0, 1.0), log=lambda msg: None) -> Atlas:
    """Orthographic captures of the mesh from every lattice view into one atlas: one Embree ray per
    texel centre, from the front of the view's box along -e_k, against the full mesh (and, for an asset
    with colours, its albedo at the hit: texture.surface_albedo)."""
    _check(settings)
    validate(mesh, "octahedral")
    n, res = settings.views, settings.resolution
    coloured = texture.has_albedo(mesh)
    colour = " with colour" if coloured else ""
    budget.check(bake_bytes(settings, coloured), f"octahedral {'hemi' if settings.hemi else 'full'}-{n}x{res} (an "
                 f"atlas of {n * res}^2 texels{colour})", f"use fewer views or texels per view (an atlas{colour} of "
                 f"N R up to {math.isqrt(budget.BUDGET // PART_BYTES[coloured])} fits)")
    centre, radius = mesh.bounding_sphere()
    radius = radius if radius > 0 else 1.0
    cap = capture_half(radius, res)
    basis = map_basis(up)
    v = mesh.vertices - centre
    scene = RayScene(v, mesh.faces)
    scene.occluded(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]))  # Embree commits on the first query
    frames = view_frames(n, settings.hemi, basis)                   # e, u, v at [j, i]
    g = (np.arange(res) + 0.5) / res * 2.0 - 1.0
    gx, gy = np.meshgrid(g * cap, g * cap)                           # [b, a]: texel row b, column a

    side = n * res
    atlas = Atlas(settings, centre, float(radius), float(cap), basis, np.zeros((side, side, 2), np.float32),
                  np.ones((side, side), np.float32), np.zeros((side, side), np.float32), 1 + side * side,
                  np.zeros((side, side, 3), np.float32) if coloured else None)
    band = max(1, min(res, BAND_RAYS // side))                      # texel rows per task

    def cast(task):
        """Texel rows b0 .. b0 + band of the N tiles of view row j, into the atlas."""
        j, b0 = task
        rows = min(band, res - b0)
        e, u, vv = (f[j] for f in frames)                           # (N, 3) each
        origin = (cap * e[:, None, None] + gx[None, b0:b0 + rows, :, None] * u[:, None, None]
                  + gy[None, b0:b0 + rows, :, None] * vv[:, None, None]).reshape(-1, 3)
        w = np.broadcast_to(-e[:, None, None], (n, rows, res, 3)).reshape(-1, 3)
        hits = scene.intersect(origin, w, 2.0 * cap)
        hit = hits.prim >= 0
        tri = mesh.faces[hits.prim[hit]]
        bary = np.stack([1 - hits.u[hit] - hits.v[hit], hits.u[hit], hits.v[hit]], -1)
        nrm = np.einsum("hk,hkc->hc", bary, mesh.normals[tri])
        length = np.linalg.norm(nrm, axis=1, keepdims=True)
        nrm = np.where(length > 1e-12, nrm / np.maximum(length, 1e-12), hits.ng[hit])
        # Faces seen from behind show their other side, as in the reference (geometric normal . ray > 0).
        back = np.einsum("hc,hc->h", hits.ng[hit], w[hit]) > 0
        nrm[back] = -nrm[back]
        view = np.repeat(np.arange(n), rows * res)[hit]
        local = np.stack([np.einsum("hc,hc->h", nrm, u[view]), np.einsum("hc,hc->h", nrm, vv[view]),
                          np.einsum("hc,hc->h", nrm, e[view])], -1)
        code = np.zeros((len(w), 2))
        code[hit] = encode(local)
        depth = np.ones(len(w))
        depth[hit] = np.clip(hits.t[hit] / (2.0 * cap), 0.0, 1.0)
        at = slice(j * res + b0, j * res + b0 + rows)
        tiles = lambda a: a.reshape(n, rows, res, -1).transpose(1, 0, 2, 3).reshape(rows, side, -1)
        atlas.normal[at] = tiles(code)
        atlas.depth[at] = tiles(depth[:, None])[..., 0]
        atlas.coverage[at] = tiles(hit[:, None])[..., 0]
        if coloured:
            albedo = np.zeros((len(w), 3))
            albedo[hit] = texture.surface_albedo(mesh, hits.prim[hit], bary, None)
            atlas.albedo[at] = tiles(albedo)

    with ThreadPoolExecutor(os.cpu_count() or 1) as pool:
        list(pool.map(cast, [(j, b0) for j in range(n) for b0 in range(0, res, band)]))
    log(f"{n}x{n} views ({'upper hemisphere' if settings.hemi else 'full sphere'}) of {res}^2 texels, "
        f"atlas {side}^2, {atlas.rays:,} rays")
    return atlas


def to_part(a: Atlas) -> parts.OctahedralAtlas:
    """The atlas as the bundle stores it and the renderer samples it (linear filtering): the empty
    texels within billboard_maps.PAD rings of covered ones hold normal code and depth linearly
    extrapolated from them (billboard_maps.pad), clamped to their ranges, so that filtering at a
    silhouette follows the surface instead of bending it to depth 1; the albedo there is the covered
    neighbours' mean (pad, linear=False: a colour does not continue a slope). The EMPTY rings around every
    tile keep the extrapolation inside its view, so each tile is padded on its own (one tile's temporaries at
    a time)."""
    covered, res = a.coverage > 0.5, a.settings.resolution
    values = np.concatenate([a.normal, a.depth[..., None]], -1)
    albedo = None if a.albedo is None else a.albedo.copy()
    lo, hi = np.array([-1, -1, 0], np.float32), np.array([1, 1, 1], np.float32)   # code and depth ranges
    for r in range(0, len(covered), res):                   # tile by tile: a tile's padding stays in it
        for c in range(0, len(covered), res):
            t = np.s_[r:r + res, c:c + res]
            values[t] = np.clip(billboard_maps.pad(values[t], covered[t]), lo, hi)
            if albedo is not None:
                albedo[t] = billboard_maps.pad(albedo[t], covered[t], linear=False)
    return parts.OctahedralAtlas(a.settings.views, a.settings.hemi, a.basis, a.centre, a.radius, a.capture,
                                 values[..., :2], values[..., 2], a.coverage, a.rays, albedo)
