"""The references, independent of the GL path: a primary ray through every pixel centre (or through N x N
stratified points of every pixel, box-filtered: `filtered`) plus one shadow ray per hit, shaded in float64
with the numpy twin of the shared model. Meshes are traced by Embree; spheres and cylinders analytically in
float64."""
from __future__ import annotations

import functools
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from vdmbake.common.colour import srgb_encode
from vdmbake.common.embree import RayScene
from vdmbake.common.texture import surface_albedo

from . import quadric_groups, quadric_math
from .shading import safe_normalize, shade

SHADOW_EPSILON = 1e-5  # shadow-ray origin offset along the geometric normal, in bounding radii
CELL_PER_BOX = 1.0     # QuadricTracer: grid cell edge, in median quadric box edges
COLOUR_SPREAD = 1 / 255  # filtered: samples (or neighbouring pixels) more than an sRGB8 level apart disagree


def _shape(camera, pixels) -> tuple[int, ...]:
    """What a render returns per ray: (H, W), row 0 at the top, or (P,) for the rays of chosen pixels."""
    return (camera.height, camera.width) if pixels is None else (len(pixels),)


def _frame(shape, hit: np.ndarray, radiance: np.ndarray) -> np.ndarray:
    """shape + (4,) float32 (_shape): linear RGB of the hit rays, and coverage."""
    out = np.zeros((hit.size, 4))
    out[hit, :3] = radiance
    out[hit, 3] = 1.0
    return out.reshape(*shape, 4).astype(np.float32)


def _depth(shape, hit: np.ndarray, view_depth: np.ndarray) -> np.ndarray:
    """shape (_shape) float64 view depth of the hit rays (inf elsewhere): what composite frames compare to find
    each pixel's nearest object (every reference casts the camera's same pixel rays)."""
    out = np.full(hit.size, np.inf)
    out[hit] = view_depth
    return out.reshape(shape)


def facing_the_light(normals: np.ndarray, light) -> np.ndarray:
    """(N,) where the shading normals face the light: only there may a shadow ray change the pixel (shade lights
    none other), so only there is one cast."""
    return np.einsum("ij,j->i", normals, np.asarray(light.direction, float)) > 0


def _towards(light, rays: np.ndarray) -> np.ndarray:
    """The light's direction for each of the rays where `rays` is True: (count, 3)."""
    return np.broadcast_to(np.asarray(light.direction, float), (int(rays.sum()), 3))


class Confined:
    """A reference's render traced only where its rays may meet the object: the pixels within the screen box of its
    bounding sphere and one pixel around it (a sweep's small sizes cover a few hundred of a frame's pixels); every
    other pixel is empty, as its ray would have found it, so the frame is the same to the bit. `sphere` is the
    (centre, radius) of everything the reference traces; `_render` traces the rays it is given."""

    def render(self, camera, others=(), depth: bool = False, offset=None, pixels=None):
        """As MeshReference._render."""
        rays = np.arange(camera.width * camera.height) if pixels is None else np.asarray(pixels)
        keep = may_meet(camera, *self.sphere, rays)
        if keep is None or keep.all():
            return self._render(camera, others, depth, offset, pixels)
        some = None if offset is None else np.asarray(offset).reshape(-1, 2)[keep]
        got = self._render(camera, others, depth, some, rays[keep])
        shape = _shape(camera, pixels)
        frame = np.zeros((rays.size, 4), np.float32)
        frame[keep] = got[0] if depth else got
        if not depth:
            return frame.reshape(*shape, 4)
        view_depth = np.full(rays.size, np.inf)
        view_depth[keep] = got[1]
        return frame.reshape(*shape, 4), view_depth.reshape(shape)


def may_meet(camera, centre, radius: float, rays: np.ndarray) -> np.ndarray | None:
    """(P,) True for the row-major pixels `rays` within the screen box of the sphere and a pixel around it; None
    where the sphere reaches the eye's plane (or cannot be measured) and any pixel may see it. The box is that of
    the projected corners of the camera-aligned cube around the sphere, which encloses the sphere's projection."""
    x, y, z = camera.basis() @ (np.asarray(centre, float) - camera.eye)
    depth = -z
    if not (np.isfinite(radius) and depth - radius > 0):
        return None
    t = np.tan(np.radians(camera.fov_deg) / 2)
    a = camera.width / camera.height
    depths = np.array([depth - radius, depth + radius])
    across = np.concatenate([(x + s * radius) / depths for s in (-1, 1)]) / (t * a)   # NDC x of the corners
    up = np.concatenate([(y + s * radius) / depths for s in (-1, 1)]) / t
    col = (across + 1) / 2 * camera.width
    row = (1 - up) / 2 * camera.height
    r, c = np.divmod(rays, camera.width)
    return ((c >= np.floor(col.min()) - 1) & (c <= np.ceil(col.max()) + 1)
            & (r >= np.floor(row.min()) - 1) & (r <= np.ceil(row.max()) + 1))


class MeshReference(Confined):
    """Traces one triangle mesh; the Embree scene is built once and reused for every camera."""

    def __init__(self, mesh, light, material):
        self.mesh, self.light, self.material = mesh, light, material
        self.scene = RayScene(mesh.vertices, mesh.faces)
        self.local = mesh.vertices - self.scene.anchor   # about the anchor: keeps the shadow offset's digits
        self.sphere = mesh.bounding_sphere()
        self.eps = SHADOW_EPSILON * self.sphere[1]

    def occluded(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Shadow rays from other objects (composite frames): (N,) True where this mesh blocks them."""
        return self.scene.occluded(origins, dirs)

    def _render(self, camera, others=(), depth: bool = False, offset=None, pixels=None):
        """(H, W, 4) float32: linear RGB and coverage, row 0 at the top. others: references whose
        objects also block this one's shadow rays (composite frames); depth: also return each pixel's view
        depth (_depth); offset: each pixel's ray through this point of it (Camera.pixel_rays), not its centre;
        pixels: only these pixels' rays (Camera.pixel_rays), (P, 4)."""
        eye, d = camera.pixel_rays(offset, pixels)
        # Start on the near plane and stop at the far plane, as the rasteriser clips (d has view depth 1).
        hits = self.scene.intersect(eye + d * camera.near, d, camera.far - camera.near)
        hit = hits.prim >= 0
        tri = self.mesh.faces[hits.prim[hit]]
        w = np.stack([1 - hits.u[hit] - hits.v[hit], hits.u[hit], hits.v[hit]], 1)
        # einsum: the corners' weighted sum without the (N, 3, 3) product (3x faster, the same sums)
        local = np.einsum("ij,ijk->ik", w, self.local[tri])
        p = local + self.scene.anchor
        n = safe_normalize(np.einsum("ij,ijk->ik", w, self.mesh.normals[tri]))
        dh = d[hit]
        ng = hits.ng[hit]
        back = np.einsum("ij,ij->i", ng, dh) > 0          # seen from behind: flip to face the viewer
        n[back], ng[back] = -n[back], -ng[back]
        to_eye = safe_normalize(camera.eye - p)
        lit = facing_the_light(n, self.light)
        lit[lit] = ~self.scene.occluded((local + ng * self.eps)[lit], _towards(self.light, lit), relative=True)
        for o in others:
            lit[lit] = ~o.occluded((p + ng * self.eps)[lit], _towards(self.light, lit))
        albedo = surface_albedo(self.mesh, hits.prim[hit], w, self.material.albedo)
        shape = _shape(camera, pixels)
        frame = _frame(shape, hit, shade(albedo, n, to_eye, lit, self.light, self.material))
        return (frame, _depth(shape, hit, camera.near + hits.t[hit])) if depth else frame


_BOX = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
_BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


class QuadricTracer:
    """Exact first hits of rays with spheres and capped cylinders, in float64.

    Embree finds the candidates: the quadrics are grouped by grid cell, each group enclosed in a box
    (12 triangles) of its own orientation (quadric_groups). Boxes are visited front to back along
    each ray; every box face met makes its group's quadrics tested analytically (quadric_math); a
    ray is done when the next box face lies beyond its best hit. A box is left by stepping a hair
    past the face; a face of another box within that hair (Embree rounds to float32) is found in
    float64 instead: every box near the face point (quadric_groups.Cover) that holds the point a
    hair before the face but not the point two hairs after it, or the reverse, is tested too (two
    crossings in between only clip a corner, nearer the box than its padding, where no quadric lies).
    A box that contains a ray's start shows no face before its exit, which may lie beyond a hit
    found meanwhile (the camera inside an atom, a water box around the eye): so the walk starts
    `reach` (the longest box diagonal) before the start, where every such box is entered, and
    each box it meets is tested whatever its exit distance (hits still count from tmin on).
    Shadow rays (stop_at_any) need no head start: they never stop before a hit, so they meet such
    a box at its exit, at most `reach` on (they look that far whatever their tmax)."""

    def __init__(self, q):
        self.q = q
        self.n_s = len(q.spheres)
        n = self.n_s + len(q.cylinders)
        lo, hi = quadric_groups.quadric_boxes(q.spheres, q.cylinders, np.broadcast_to(np.eye(3), (n, 3, 3)))
        edge = CELL_PER_BOX * float(np.median((hi - lo).max(1)))
        self.members, group = quadric_groups.grid_groups(0.5 * (lo + hi), edge)
        rot = quadric_groups.random_rotations(len(self.members))
        lo, hi = quadric_groups.quadric_boxes(q.spheres, q.cylinders, rot[group])
        order = np.argsort(group, kind="stable")
        start = np.searchsorted(group[order], np.arange(len(self.members)))
        lo, hi = np.minimum.reduceat(lo[order], start), np.maximum.reduceat(hi[order], start)
        self.step = 1e-6 * q.bounding_sphere()[1]
        pad = 1e-5 * (hi - lo) + 4 * self.step   # boxes enclose their quadrics despite float32, by over 2 hairs
        lo, hi = lo - pad, hi + pad
        self.frames = np.concatenate([rot.reshape(-1, 9), lo, hi], 1)
        corners = np.einsum("cji,ckj->cki", rot, np.where(_BOX[None] > 0, hi[:, None], lo[:, None]))
        faces = (np.arange(len(corners))[:, None, None] * 8 + _BOX_FACES[None]).reshape(-1, 3)
        self.scene = RayScene(corners.reshape(-1, 3), faces)
        self.reach = float(np.linalg.norm(hi - lo, axis=1).max())
        self.bounds = np.concatenate([corners.min(1) - 3 * self.step, corners.max(1) + 3 * self.step], 1)
        self.cover = quadric_groups.Cover(self.bounds[:, :3], self.bounds[:, 3:], edge)

    def _test(self, o, d, idx, tmin):
        """Analytic first hit of rays (o, d unit) with quadric idx: (t, normal)."""
        t, n = np.full(len(o), np.inf), np.zeros((len(o), 3))
        sph = idx < self.n_s
        if sph.any():
            s = self.q.spheres[idx[sph]]
            ts = quadric_math.ray_spheres(o[sph], d[sph], s[:, :3], s[:, 3], tmin[sph])
            hit = o[sph] + np.where(np.isfinite(ts), ts, 0.0)[:, None] * d[sph]
            t[sph], n[sph] = ts, (hit - s[:, :3]) / s[:, 3:4]
        cyl = ~sph
        if cyl.any():
            c = self.q.cylinders[idx[cyl] - self.n_s]
            t[cyl], n[cyl] = quadric_math.ray_capped_cylinders(o[cyl], d[cyl], c[:, :3], c[:, 3:6], c[:, 6], tmin[cyl])
        return t, n

    def _met(self, o, d, face_t, group):
        """The groups to test where rays meet a face of `group` at face_t: that group, and every other
        group with a face between a hair before and two hairs after (the step over, float32 error
        included; rare). Pairs (ray, group), the met groups first."""
        p = o + face_t[:, None] * d
        ray, near = self.cover.near(p)
        bounds = self.bounds[near]                       # first the box's world bounds, grown by 3 hairs
        keep = ((p[ray] >= bounds[:, :3]) & (p[ray] <= bounds[:, 3:])).all(1) & (near != group[ray])
        ray, near = ray[keep], near[keep]
        frame = self.frames[near]                        # then its rotation rows, lo and hi
        rot = frame[:, :9].reshape(-1, 3, 3)
        local = np.einsum("nij,nj->ni", rot, p[ray])
        along = self.step * np.einsum("nij,nj->ni", rot, d[ray])
        lo, hi = frame[:, 9:12], frame[:, 12:]
        before, after = local - along, local + 2 * along
        crossed = ((before >= lo) & (before <= hi)).all(1) != ((after >= lo) & (after <= hi)).all(1)
        return np.r_[np.arange(len(o)), ray[crossed]], np.r_[group, near[crossed]]

    def _nearest(self, o, d, ray, group, tmin):
        """Each ray's first hit with the quadrics of its groups, pairs (ray, group) whose first len(o)
        are rays 0, 1, ...: (t, normal, quadric index); ties go to the lower index."""
        m = self.members[group]
        pair, col = np.nonzero(m >= 0)
        quad = m[pair, col]
        t, nrm = self._test(o[ray[pair]], d[ray[pair]], quad, tmin[ray[pair]])
        grid, at = np.full(m.shape, np.inf), np.zeros(m.shape, np.int64)
        grid[pair, col], at[pair, col] = t, np.arange(len(pair))
        win = at[np.arange(len(m)), grid.argmin(1)]           # each pair's best; members ascend in a row
        more = np.unique(ray[len(o):])                         # the rare rays with further groups
        r, w = np.r_[more, ray[len(o):]], np.r_[win[more], win[len(o):]]
        order = np.lexsort((quad[w], t[w], r))
        first = order[np.diff(r[order], prepend=-1) != 0]
        win = win[:len(o)]
        win[r[first]] = w[first]
        return t[win], nrm[win], quad[win]

    def first_hit(self, o, d, tmin, tmax, stop_at_any=False):
        """Unit rays o + t d: (t, normal, quadric index), t inf and index -1 where nothing is hit in
        [tmin, tmax]. stop_at_any: shadow rays; any hit will do."""
        n = len(o)
        best_t, best_n, best_i = np.full(n, np.inf), np.zeros((n, 3)), np.full(n, -1)
        tmax = np.broadcast_to(np.asarray(tmax, float), (n,))
        tmin = np.broadcast_to(np.asarray(tmin, float), (n,))
        cur = tmin.copy() if stop_at_any else tmin - self.reach
        limit = np.maximum(tmax, tmin + self.reach) if stop_at_any else tmax
        active = np.arange(n)
        for _ in range(100000):
            if not len(active):
                break
            h = self.scene.intersect(o[active] + d[active] * cur[active, None], d[active], limit[active] - cur[active])
            face_t = cur[active] + h.t
            go = (h.prim >= 0) & (face_t < best_t[active])
            active, face_t = active[go], face_t[go]
            ray, group = self._met(o[active], d[active], face_t, h.prim[go] // 12)
            t, nrm, idx = self._nearest(o[active], d[active], ray, group, tmin[active])
            better = (t < best_t[active]) & (t <= tmax[active])
            a = active[better]
            best_t[a], best_n[a], best_i[a] = t[better], nrm[better], idx[better]
            cur[active] = face_t + self.step
            if stop_at_any:
                active = active[~better]
        else:
            raise RuntimeError("quadric reference: box traversal did not finish")
        return best_t, best_n, best_i


class QuadricReference(Confined):
    """Traces spheres and capped cylinders exactly (float64), with one shadow ray per hit."""

    def __init__(self, q, light, material):
        self.q, self.light, self.material = q, light, material
        self.tracer = QuadricTracer(q)
        self.scene = self.tracer.scene  # its rays_cast counts every traversal step
        self.rgb = np.concatenate([q.sphere_rgb, q.cylinder_rgb]).astype(np.float64)
        self.sphere = q.bounding_sphere()
        self.eps = SHADOW_EPSILON * self.sphere[1]

    def occluded(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Shadow rays from other objects (composite frames): (N,) True where a quadric blocks them."""
        t, _, _ = self.tracer.first_hit(np.ascontiguousarray(origins, float), np.ascontiguousarray(dirs, float),
                                        np.zeros(len(origins)), np.full(len(origins), np.inf), stop_at_any=True)
        return np.isfinite(t)

    def _render(self, camera, others=(), depth: bool = False, offset=None, pixels=None):
        """As MeshReference._render."""
        eye, d = camera.pixel_rays(offset, pixels)
        scale = np.linalg.norm(d, axis=1)         # d has view depth 1: near/far become distances
        du = d / scale[:, None]
        t, n, idx = self.tracer.first_hit(np.ascontiguousarray(eye), du, camera.near * scale, camera.far * scale)
        hit = idx >= 0
        p = camera.eye + du[hit] * t[hit, None]
        n = n[hit]
        n = np.where((np.einsum("ij,ij->i", n, du[hit]) > 0)[:, None], -n, n)  # face the viewer
        lit = facing_the_light(n, self.light)
        lit[lit] = ~self.occluded((p + n * self.eps)[lit], _towards(self.light, lit))
        for o in others:
            lit[lit] = ~o.occluded((p + n * self.eps)[lit], _towards(self.light, lit))
        shape = _shape(camera, pixels)
        frame = _frame(shape, hit, shade(self.rgb[idx[hit]], n, safe_normalize(camera.eye - p), lit,
                                         self.light, self.material))
        return (frame, _depth(shape, hit, t[hit] / scale[hit])) if depth else frame


class CompositeReference:
    """Several objects traced together (composite frames): per pixel the nearest of the objects' hits,
    each shaded with its own material and colours, and every object's shadow rays blocked by every
    object (as the composite's one shadow map of the whole scene does in GL)."""

    def __init__(self, refs):
        self.refs = list(refs)

    @property
    def rays_cast(self) -> int:
        return sum(r.scene.rays_cast for r in self.refs)

    def render(self, camera, offset=None, pixels=None) -> np.ndarray:
        out = [r.render(camera, [o for o in self.refs if o is not r], depth=True, offset=offset, pixels=pixels)
               for r in self.refs]
        depth = np.stack([d for _, d in out])
        nearest = depth.argmin(0)[None, ..., None]            # ties go to the first object of the scene
        return np.take_along_axis(np.stack([f for f, _ in out]), nearest, 0)[0]


def _permute(i: np.ndarray, count: int, p: np.ndarray) -> np.ndarray:
    """Element i of a pseudo-random permutation of range(count) chosen by p (uint32 arrays, one permutation per
    element of p): Kensler 2013, "Correlated Multi-Jittered Sampling", listing 3: a hash bijective on the smallest
    power of two at least count, walked until it lands below count."""
    w = count - 1
    for shift in (1, 2, 4, 8, 16):
        w |= w >> shift
    i, todo = i.astype(np.uint32), np.ones(i.shape, bool)
    while todo.any():
        j, q = i[todo], p[todo]
        j ^= q; j *= 0xe170893d; j ^= q >> 16; j ^= (j & w) >> 4; j ^= q >> 8; j *= 0x0929eb3f   # noqa: E702
        j ^= q >> 23; j ^= (j & w) >> 1; j *= 1 | q >> 27; j *= 0x6935fa69; j ^= (j & w) >> 11    # noqa: E702
        j *= 0x74dcb303; j ^= (j & w) >> 2; j *= 0x9e501cc3; j ^= (j & w) >> 2; j *= 0xc860a3df    # noqa: E702
        j &= w; j ^= j >> 5                                                                           # noqa: E702
        i[todo] = j
        todo = i >= count
    return (i + p) % np.uint32(count)


def _unit(i: int, p: np.ndarray) -> np.ndarray:
    """A pseudo-random number in [0, 1) for sample i of each pattern p (Kensler 2013, listing 4, in float64)."""
    i = np.uint32(i) ^ p
    i ^= i >> 17; i ^= i >> 10; i *= 0xb36534e5; i ^= i >> 12; i ^= i >> 21; i *= 0x93fc4795     # noqa: E702
    i ^= 0xdf6e307f; i ^= i >> 17; i *= 1 | p >> 18                                                # noqa: E702
    return i / 4294967808.0


class Pattern:
    """The N x N sample points of every pixel (spp = N^2), sample k in stratum (k mod N, k div N) of an N x N grid
    of the pixel: correlated multi-jittered (Kensler 2013, listing 5), so that the N samples of each row and of each
    column of strata also fall in N different sub-columns (sub-rows), a Latin hypercube besides the strata: edges
    along the axes converge as 1/N^2, not 1/N. Each pixel has its own pattern (p, its index from 1: 0 would give x
    and y one permutation), so a run's reference is deterministic and neighbouring pixels share no pattern to alias
    with the scene's."""

    def __init__(self, camera, spp: int):
        self.n = math.isqrt(spp)
        self.p = np.arange(1, camera.height * camera.width + 1, dtype=np.uint32).reshape(camera.height, camera.width)
        self._sub = {}

    def _sub_cell(self, axis: int, i: int) -> np.ndarray:
        """Every pixel's sub-column (axis 0) or sub-row (1) of the samples in row (column) i of strata: a
        permutation depends on that index only, N of each per pixel, not N^2; made once."""
        if (axis, i) not in self._sub:
            salt = np.uint32((0xa511e9b3, 0x63d83595)[axis])
            self._sub[axis, i] = _permute(np.full(self.p.shape, i, np.uint32), self.n, self.p * salt)
        return self._sub[axis, i]

    def at(self, k: int, pixels: np.ndarray | None = None) -> np.ndarray | None:
        """Sample k's offsets within the pixels (Camera.pixel_rays): (H, W, 2), or (P, 2) for row-major pixel
        indices; None at 1 spp: the pixel centre, the point-sampled reference, as every GL frame without AA."""
        n = self.n
        if n == 1:
            return None
        p, sx, sy = self.p, self._sub_cell(0, k % n), self._sub_cell(1, k // n)
        if pixels is not None:
            p, sx, sy = p.ravel()[pixels], sx.ravel()[pixels], sy.ravel()[pixels]
        jx, jy = _unit(k, p * np.uint32(0xa399d265)), _unit(k, p * np.uint32(0x711ad6a5))
        return np.stack([(k % n + (sy + jx) / n) / n, (k // n + (sx + jy) / n) / n], -1)


def in_first_half(k: int, n: int) -> bool:
    """Whether sample k of N x N belongs to the first half of the strata: the checkerboard's cells (i + j even).
    The two halves are two estimates of the pixel, from which its noise is estimated (vdmrender.comparing.scoring.noise)."""
    return (k % n + k // n) % 2 == 0


@functools.lru_cache
def first_pass(n: int) -> tuple[int, ...]:
    """The N samples of N x N that every pixel gets before the rest are decided (filtered): one in each column and
    each row of strata (so N sub-columns and sub-rows apart, the pattern's Latin hypercube), placed greedily each as
    far (on the torus) from those before it as it can be, half of them in each checkerboard half (in_first_half)
    so that a pixel that stops here still has two estimates; at N = 4, one in each quadrant of the pixel."""
    rows, free = [], list(range(n))
    for i in range(n):
        firsts = sum(in_first_half(c + r * n, n) for c, r in enumerate(rows))

        def spread(j):
            d = [min(abs(i - c), n - abs(i - c)) ** 2 + min(abs(j - r), n - abs(j - r)) ** 2 for c, r in enumerate(rows)]
            return min(d, default=0)

        want = 2 * firsts <= len(rows)   # the first half has no more than the second: the next goes there
        j = min(free, key=lambda j: (in_first_half(i + j * n, n) != want, -spread(j), j))
        rows.append(j)
        free.remove(j)
    return tuple(i + j * n for i, j in enumerate(rows))


def workers() -> int:
    """The threads a filtered reference traces on: every core this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:   # not on Linux
        return os.cpu_count() or 1


def _in_order(pool, fn, items, ahead: int):
    """fn(item) for every item on the pool's threads, yielded in the items' order, with at most `ahead` running or
    waiting to be taken: a bounded number of frames in memory, and sums that do not depend on which thread ends first."""
    pending = []
    for item in items:
        pending.append(pool.submit(fn, item))
        if len(pending) >= ahead:
            yield pending.pop(0).result()
    for p in pending:
        yield p.result()


@dataclass
class Halves:
    """What a filtered reference keeps of each pixel for its noise (vdmrender.comparing.scoring.noise): `first`, the mean
    (premultiplied RGB, coverage) of its samples in the first half of the strata (in_first_half), and how many
    samples it got, `traced`, of which `in_first` in that half: (H, W) each."""
    first: np.ndarray
    traced: np.ndarray
    in_first: np.ndarray


class Agreement:
    """Whether a pixel's samples so far agree (filtered's first pass), kept per pixel as they come: the coverage
    seen, and the least, greatest and summed sRGB colour of the samples that cover it."""

    def __init__(self, shape):
        self.some, self.every = np.zeros(shape, bool), np.ones(shape, bool)
        self.lo, self.hi, self.sum = np.full((*shape, 3), np.inf), np.full((*shape, 3), -np.inf), np.zeros((*shape, 3))

    def add(self, rgba: np.ndarray) -> None:
        """One sample of every pixel: linear RGB, coverage 0 or 1."""
        cover = rgba[..., 3] > 0
        self.some |= cover
        self.every &= cover
        c = srgb_encode(np.clip(rgba[..., :3], 0.0, 1.0))
        self.lo = np.where(cover[..., None], np.minimum(self.lo, c), self.lo)
        self.hi = np.where(cover[..., None], np.maximum(self.hi, c), self.hi)
        self.sum += np.where(cover[..., None], c, 0.0)

    def disagree(self, count: int) -> np.ndarray:
        """Where the `count` samples disagree, so that more of them may change the pixel: some cover it and some do
        not, or the colours of those that cover it are more than COLOUR_SPREAD apart in some sRGB channel (a
        shadow's edge is such a colour); and the pixels beside those (4-neighbours), and both pixels of a pair that
        agree within but not with each other (wholly covered beside empty, or COLOUR_SPREAD apart): an edge that
        crosses a pixel between its few samples mostly shows in a neighbour (on the torus of
        tests/test_reference_sampling at 32 px and 16 spp, without them 14 of 109 silhouette pixels, some a
        quarter covered, kept their first pass, and the silhouette's error grew 28%)."""
        out = (self.some != self.every) | (self.every & ((self.hi - self.lo).max(-1) > COLOUR_SPREAD))
        mean = np.where(self.every[..., None], self.sum / count, -1.0)   # -1: not wholly covered
        near = out.copy()
        for a, b in ((np.s_[1:], np.s_[:-1]), (np.s_[:, 1:], np.s_[:, :-1])):   # each pixel and the one below, right
            edge = out[a] | out[b] | (np.abs(mean[a] - mean[b]).max(-1) > COLOUR_SPREAD)
            near[a] |= edge
            near[b] |= edge
        return near


def first_samples(spp: int, adaptive: bool = True) -> tuple[int, ...]:
    """The samples every pixel of a filtered reference gets: first_pass's N when adaptive, at N > 2 (two samples on
    a diagonal of 2 x 2 strata leave no second half), else all N^2."""
    n = math.isqrt(spp)
    return first_pass(n) if adaptive and n > 2 else tuple(range(spp))


def filtered(render, camera, spp: int, threads: int | None = None,
             adaptive: bool = True) -> tuple[np.ndarray, Halves | None]:
    """The box-filtered frame of `render(camera, offset=..., pixels=...)` (a reference's render): the mean over each
    pixel's samples (Pattern) of linear RGB times coverage, and of coverage, i.e. premultiplied colour and the
    fraction of the pixel the object covers; what a viewer sees of the pixel over the background is then
    rgb + (1 - coverage) background (images.encode). With it, the Halves the frame's own sampling noise is estimated
    from (vdmrender.comparing.scoring.noise); None at one sample per pixel.

    Adaptive (PBRT-v4's adaptive sampling, on the samples' agreement rather than their variance): every pixel first
    gets the N samples of first_pass, and only pixels whose samples disagree (Agreement: coverage, colour, an edge
    beside them) get the other N^2 - N, so `spp` is the budget of the hardest pixels; a pixel that gets them all has
    the same samples as without `adaptive` (first_samples: at N <= 2 every pixel gets them all).

    The samples are traced on `threads` threads (workers(): every core; Embree and numpy's large loops release the
    GIL), a whole frame or about a frame's rays at a time, and summed in the samples' own order: the same bytes
    whatever the thread count."""
    n, size = math.isqrt(spp), camera.height * camera.width
    if n == 1:
        f = render(camera).astype(np.float64)
        f[..., :3] *= f[..., 3:]
        return f.astype(np.float32), None
    pattern, threads = Pattern(camera, spp), threads or workers()
    first = first_samples(spp, adaptive)
    total, half = np.zeros((size, 4)), np.zeros((size, 4))
    traced, in_first = np.zeros(size, np.int32), np.zeros(size, np.int32)

    def add(k: int, f: np.ndarray, at) -> None:
        f = f.reshape(-1, 4).astype(np.float64)
        f[:, :3] *= f[:, 3:]
        total[at] += f
        traced[at] += 1
        if in_first_half(k, n):
            half[at] += f
            in_first[at] += 1

    rest = [k for k in range(spp) if k not in first]
    seen = Agreement((camera.height, camera.width))
    with ThreadPoolExecutor(threads) as pool:
        for k, f in zip(first, _in_order(pool, lambda offset: render(camera, offset=offset),
                                         (pattern.at(k) for k in first), threads)):
            add(k, f, slice(None))
            if rest:
                seen.add(f)
        pixels = np.flatnonzero(seen.disagree(len(first))) if rest else np.zeros(0, np.int64)
        per = max(1, size // max(len(pixels), 1))   # samples per batch: about a frame's rays
        batches = [rest[i:i + per] for i in range(0, len(rest), per)] if len(pixels) else []

        def trace(ks):
            return render(camera, offset=np.concatenate([pattern.at(k, pixels) for k in ks]),
                          pixels=np.tile(pixels, len(ks)))

        for ks, f in zip(batches, _in_order(pool, trace, batches, threads)):
            for k, fk in zip(ks, f.reshape(len(ks), len(pixels), 4)):
                add(k, fk, pixels)
    shape = (camera.height, camera.width)
    return ((total / traced[:, None]).reshape(*shape, 4).astype(np.float32),
            Halves((half / in_first[:, None]).reshape(*shape, 4).astype(np.float32),
                   traced.reshape(shape), in_first.reshape(shape)))
