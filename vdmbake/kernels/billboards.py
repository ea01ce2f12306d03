"""Enhanced billboards: the bake (Vichitvejpaisal2005 chapter 3), pure numpy + Embree.

An enhanced billboard (Vichitvejpaisal2005 §3.1) is a box looking at part of the model along one view
direction w: an orthographic R x R projection of the polygons it captured, as a transparency
map (alpha), a depth map (distance from the box front along w, 0..1 of the box depth), a
normal map and, for an asset with its own colours (per-vertex colours or an albedo map), the
colour map (Vichitvejpaisal2005 §3.1: "color and normal of projected polygon poly is stored in color map and normal
map"; here the linear albedo at the texel's surface point, which the renderer shades,
Vichitvejpaisal2005 §3.3 step 2.3).
An asset without colours has no colour map: the material's albedo is the colour everywhere. The
renderer (Vichitvejpaisal2005 §3.3) ray-marches the depth map as a height field inside the box.

Building (Vichitvejpaisal2005 §3.2) is greedy set cover over a 36 x 18 array of candidate view directions
(Vichitvejpaisal2005 §4.1): take the direction that projects the most remaining polygons, keep those within
the depth limit e_depth of the billboard plane, make them one billboard, remove them, repeat.
A polygon is projectable from w (Vichitvejpaisal2005 §3.1, conditions 1 and 2) when it faces the viewer,
n . (-w) > min_cos (Vichitvejpaisal2005 §4.3: nearly perpendicular polygons are not projected), and it is
not occluded: an Embree ray from its centroid toward the viewer meets nothing of the full
mesh. Occlusion by the full mesh does not change as polygons are removed, so it is computed
once, as a (directions x faces) matrix, and the loop is then cheap bookkeeping.

Approximations: a polygon's visibility is that of its centroid (a partly covered polygon
whose centroid is seen is captured; its covered part is what the map's front-most surface
shows); intersecting polygons (Vichitvejpaisal2005 §4.3) therefore need no special case. Maps are square
(R x R) whatever the box's aspect: texels are stretched to the box's u and v extents.

Geometry is handled relative to the bounding-box centre (float64) and Embree anchors its
float32 copy there too, so a model far from the origin bakes like the same model at it.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..common import geometry, texture
from ..common.embree import RayScene
from ..errors import InputError
from ..common.mesh import validate
from ..common.mesh import TriMesh
from ..bundle.parts import Billboard

# The axis baseline of Vichitvejpaisal2005 §4.2 (Fig. 4-5), as view directions: +X, -X, +Y, -Y, +Z, -Z.
AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
HAIR = 1e-5         # visibility rays start this far (x model diameter) off the face, along its normal
MARGIN = 1e-4       # boxes grow by this (x model diameter) on every side: a flat set keeps a depth,
                    # and texel rays start strictly in front of the nearest polygon
DEGENERATE = 1e-12  # faces with area below this x diameter^2 have no normal


@dataclass(frozen=True)
class Settings:
    mode: str = "greedy"      # "greedy" (Vichitvejpaisal2005 §3.2) or "axis" (the +-X, +-Y, +-Z baseline of §4.2)
    azimuths: int = 36        # the candidate view-plane array A (Vichitvejpaisal2005 §4.1: 36 x 18)
    elevations: int = 18
    resolution: int = 512     # map side in texels (Vichitvejpaisal2005 §4.1: 512 x 512)
    # e_depth (Vichitvejpaisal2005 §3.1 condition 3, §3.2 step 7), as a fraction of the bounding-sphere diameter:
    # the billboard plane p sits at the nearest projectable polygon, and a polygon is stored only if
    # its distance to p (that of its nearest vertex) is at most e_depth. A box is thus about e_depth
    # deep (plus its deepest polygon's own extent along w), which bounds the ray-march per billboard.
    max_depth: float = 0.5
    min_cos: float = 0.25     # n . (-w) at or below this: too close to perpendicular (Vichitvejpaisal2005 §4.3), ~75.5 deg
    max_billboards: int = 64


@dataclass
class Result:
    billboards: list[Billboard]
    faces: list[np.ndarray]   # per billboard, the indices of the mesh faces it captured
    leftover: dict        # faces never captured, by reason: too_small, perpendicular, hidden, over_budget
    candidates: int       # candidate directions evaluated
    rays: int             # Embree rays cast in all


def candidate_directions(azimuths: int, elevations: int) -> np.ndarray:
    """(A*E, 3) unit view directions on a latitude-longitude grid (the view-plane array of Vichitvejpaisal2005 §3.2,
    Fig. 3-2), elevation-major from the south; elevations at bin centres, so no pole is repeated."""
    el = (np.arange(elevations) + 0.5) / elevations * np.pi - np.pi / 2
    az = np.arange(azimuths) / azimuths * 2 * np.pi
    e, a = np.meshgrid(el, az, indexing="ij")
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], -1).reshape(-1, 3)


def view_frame(w: np.ndarray) -> np.ndarray:
    """Rows u, v, w: a right-handed orthonormal basis around the unit vector w."""
    u, v = geometry.onb(w[None])
    return np.array([u[0], v[0], w])


def _check(s: Settings):
    if s.mode not in ("greedy", "axis"):
        raise InputError(f"billboards: mode '{s.mode}' is unknown; use 'greedy' or 'axis'.")
    for name in ("azimuths", "elevations", "resolution", "max_billboards"):
        if int(getattr(s, name)) < 1:
            raise InputError(f"billboards: {name} = {getattr(s, name)}; it must be at least 1.")
    if not s.max_depth > 0:
        raise InputError(f"billboards: max_depth = {s.max_depth}; it must be > 0 (a fraction of the diameter).")
    if not 0 <= s.min_cos < 1:
        raise InputError(f"billboards: min_cos = {s.min_cos}; it must be in [0, 1).")


def bake(mesh: TriMesh, settings: Settings = Settings(), log=lambda msg: None) -> Result:
    """Visibility of every face from every candidate (Vichitvejpaisal2005 §3.2 step 3), the greedy or axis choice of
    billboards (steps 1-12), their maps (steps 9-10), and the faces left out, by reason:
    too_small (degenerate, or smaller than 1/4 of the finest billboard texel even seen head-on),
    perpendicular (never facing a candidate by more than min_cos), hidden (facing some candidate
    but occluded from all that it faces), over_budget (still projectable when max_billboards
    billboards were made: the thesis's "billboards containing little polygons are ignored", 4.3)."""
    _check(settings)
    validate(mesh, "billboards")
    centre, radius = mesh.bounding_sphere()
    scale = 2 * radius if radius > 0 else 1.0          # the model's diameter: every tolerance's unit
    v = mesh.vertices - centre
    tri = v[mesh.faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    degenerate = area <= DEGENERATE * scale ** 2
    fn = np.where(degenerate[:, None], 0.0, cross / np.where(degenerate, 1.0, 2 * area)[:, None])
    dirs = candidate_directions(settings.azimuths, settings.elevations) if settings.mode == "greedy" else AXES

    with ThreadPoolExecutor(os.cpu_count() or 1) as pool:
        vis, facing_any, rays = _visibility(v, mesh.faces, tri.mean(1) + HAIR * scale * fn, fn, dirs,
                                            settings.min_cos, pool)
        log(f"visibility: {len(dirs)} directions x {len(tri)} faces, {rays} rays")
        chosen = _build(vis, tri, fn, area, dirs, settings, scale)
        billboards = list(pool.map(lambda c: _maps(v, mesh, fn, c[1], dirs[c[0]], settings.resolution, scale),
                                   chosen))
    faces = [take for _, take in chosen]
    rays += len(billboards) * settings.resolution ** 2
    for k, (b, f) in enumerate(zip(billboards, faces)):
        b.origin += centre
        log(f"billboard {k + 1}: w = {np.round(b.axes[2], 3).tolist()}, {len(f)} faces, "
            f"{int(b.alpha.sum())} texels, box {np.round(b.size, 4).tolist()}")

    # Faces never captured, by reason (Vichitvejpaisal2005 §3.4, §4.3).
    captured = np.zeros(len(tri), bool)
    for f in faces:
        captured[f] = True
    texel = min((b.size[0] * b.size[1] for b in billboards), default=scale * scale) / settings.resolution ** 2
    small = ~captured & (degenerate | (area < 0.25 * texel))  # even seen head-on: under 1/4 of the finest texel
    perpendicular = ~captured & ~small & ~facing_any
    hidden = ~captured & ~small & facing_any & ~vis.any(0)
    leftover = {"too_small": int(small.sum()), "perpendicular": int(perpendicular.sum()),
                "hidden": int(hidden.sum()),
                "over_budget": int((~captured).sum() - small.sum() - perpendicular.sum() - hidden.sum())}
    return Result(billboards, faces, leftover, len(dirs), rays)


def _visibility(v, faces, starts, fn, dirs, min_cos, pool):
    """Vichitvejpaisal2005 §3.2 step 3 for all candidates at once: vis[d, f] is True where face f is projectable
    from dirs[d] (Vichitvejpaisal2005 §3.1 conditions 1 and 2). Rays are cast only for the front-facing pairs."""
    scene = RayScene(v, faces)
    scene.occluded(np.zeros((1, 3)), AXES[:1])  # Embree commits on the first query: before threads share it

    def one(w):
        facing = fn @ -w > min_cos
        idx = np.flatnonzero(facing)
        seen = ~scene.occluded(starts[idx], np.broadcast_to(-w, (len(idx), 3)))
        return facing, idx[seen]

    vis = np.zeros((len(dirs), len(faces)), bool)
    facing_any = np.zeros(len(faces), bool)
    rays = 1
    for d, (facing, idx) in enumerate(pool.map(one, dirs)):
        vis[d, idx] = True
        facing_any |= facing
        rays += int(facing.sum())
    return vis, facing_any, rays


def _build(vis, tri, fn, area, dirs, settings: Settings, scale: float) -> list[tuple[int, np.ndarray]]:
    """Vichitvejpaisal2005 §3.2 steps 1-12: (direction, captured faces) per billboard, in order."""
    remaining = np.ones(tri.shape[0], bool)
    counts = vis.sum(1)  # |S| per candidate over the remaining faces
    chosen, d = [], -1
    while counts.max() > 0 and len(chosen) < settings.max_billboards:
        d = _pick(counts, d, vis, remaining, fn, area, dirs, settings.mode == "greedy")
        take = np.flatnonzero(vis[d] & remaining)           # steps 4-6 and 8: S, projectable
        near = (tri[take] @ dirs[d]).min(1)                 # each polygon's distance along w ...
        take = take[near - near.min() <= settings.max_depth * scale]  # step 7: ... to p within e_depth
        remaining[take] = False                             # step 11
        counts -= vis[:, take].sum(1)
        chosen.append((d, take))
    return chosen


def _pick(counts, last, vis, remaining, fn, area, dirs, greedy: bool) -> int:
    """Greedy (Vichitvejpaisal2005 §3.2 step 4): the candidate projecting the most remaining polygons; ties go to the
    largest projected area (the most head-on view), then the first index. Axis mode: the next axis
    direction in order that still projects something."""
    if not greedy:
        order = (last + 1 + np.arange(len(counts))) % len(counts)
        return int(order[np.argmax(counts[order] > 0)])
    best = np.flatnonzero(counts == counts.max())
    if len(best) == 1:
        return int(best[0])
    # Rounded so that views equal up to float rounding (symmetric models) tie exactly: deterministic.
    projected = [np.round((area * (fn @ -dirs[d]))[vis[d] & remaining].sum() / area.sum(), 9) for d in best]
    return int(best[np.argmax(projected)])


def _maps(v, mesh: TriMesh, fn, take, w, resolution: int, scale: float) -> Billboard:
    """Vichitvejpaisal2005 §3.2 steps 9-10: project the captured faces orthographically along w into an R x R box.
    One Embree ray per texel centre from the box front along +w against these faces only."""
    axes = view_frame(w)
    faces = mesh.faces[take]
    p = v[np.unique(faces)] @ axes.T
    lo = p.min(0) - MARGIN * scale
    size = p.max(0) + MARGIN * scale - lo
    g = (np.arange(resolution) + 0.5) / resolution
    row, col = np.meshgrid(g, g, indexing="ij")
    uvw = np.stack([lo[0] + col * size[0], lo[1] + row * size[1], np.full_like(col, lo[2])], -1).reshape(-1, 3)
    hits = RayScene(v, faces).intersect(uvw @ axes, np.broadcast_to(w, uvw.shape))
    hit = hits.prim >= 0
    prim = hits.prim[hit]
    # Shading normal: barycentric interpolation of the vertex normals, P = (1-u-v) v0 + u v1 + v v2;
    # the face's own normal where they cancel out; turned to face the viewer (-w).
    b = np.stack([1 - hits.u[hit] - hits.v[hit], hits.u[hit], hits.v[hit]], -1)
    n = np.einsum("hk,hkc->hc", b, mesh.normals[faces[prim]])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 1e-12, n / np.maximum(length, 1e-12), fn[take][prim])
    n = np.where((n @ w)[:, None] > 0, -n, n)
    depth = np.ones(resolution * resolution)
    depth[hit] = np.clip(hits.t[hit] / size[2], 0.0, 1.0)
    normal = np.zeros((resolution * resolution, 3))
    normal[hit] = n
    shape = (resolution, resolution)
    albedo = None
    if texture.has_albedo(mesh):   # the colour map (Vichitvejpaisal2005 §3.1): the asset's albedo at the texel's surface point
        albedo = np.zeros((resolution * resolution, 3))
        albedo[hit] = texture.surface_albedo(mesh, take[prim], b, None)
        albedo = albedo.reshape(shape + (3,)).astype(np.float32)
    return Billboard(origin=lo @ axes, axes=axes, size=size,
                     alpha=hit.reshape(shape).astype(np.float32), depth=depth.reshape(shape).astype(np.float32),
                     normal=normal.reshape(shape + (3,)).astype(np.float32), albedo=albedo)
