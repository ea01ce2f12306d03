"""Instances (issue 23): the matrices that place an object's copies, pure numpy, shared by the renderer's
instanced draws and the reference.

Every instance is a similarity about the object's bounding-sphere centre c: M = T(c + t) R S(s) T(-c), a uniform
scale s (so normals only turn: R n), a rotation R and a translation t. A list gives t, R (about X, then Y, then Z)
and s per instance; a scatter draws t uniformly over a rectangle of the plane normal to the scene's up, R a turn
about up, s uniformly in its range, from numpy's PCG64 generator seeded by the scene (the same seed, the same
places)."""
from __future__ import annotations

import dataclasses

import numpy as np

from .mesh import rotation_xyz
from ..bundle.parts.kind import EXTENT, check_extent
from ..errors import InputError

# A copy's radius over the radius of the sphere holding every copy, at least. The reference traces the copies
# merged into one float32 scene about that sphere's centre and scaled to it (vdmbake.common.embree): float32's
# 2^-24 then keeps a copy's shape to 1/256 of its radius; smaller, the copy flattens to a point and is missing
# from the reference while GL draws it (a copy 1e20 from the object: 23 ΔLuv, IoU 0).
MIN_SHARE = 2.0 ** -16
# A copy's radius over its centre's distance from the origin, at least. The copies are placed in float64 world
# coordinates (placed) before the reference centres them, so float64's 2^-52 of that distance keeps a copy's shape to
# 1/256 of its radius here; one copy alone 1e20 from the origin came out as a point: an empty reference, IoU 0, exit 0.
MIN_FAR = 2.0 ** -44


def about_axis(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations by `angles` (radians) about the unit `axis` (Rodrigues' formula)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def matrices(instances, up, centre) -> np.ndarray:
    """(N, 4, 4) world matrices of the object's instances (scene.Instances) about its centre."""
    centre = np.asarray(centre, np.float64)
    if instances.scatter is not None:
        sc = instances.scatter
        rng = np.random.default_rng(sc.seed)
        u = np.asarray(up, np.float64) / np.linalg.norm(up)
        a = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = a - u * (a @ u)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        xy = (rng.random((sc.count, 2)) - 0.5) * np.asarray(sc.area)
        turn = rng.random(sc.count) * 2 * np.pi if sc.rotate else np.zeros(sc.count)
        scale = sc.scale[0] + rng.random(sc.count) * (sc.scale[1] - sc.scale[0])
        t, R = xy[:, :1] * e1 + xy[:, 1:] * e2, about_axis(u, turn)
    else:
        p = instances.placements
        t = np.array([q.translate for q in p], np.float64)
        R = np.stack([rotation_xyz(q.rotate_deg) for q in p])
        scale = np.array([q.scale for q in p], np.float64)
    m = np.zeros((len(t), 4, 4))
    m[:, :3, :3] = R * scale[:, None, None]
    m[:, :3, 3] = centre + t - np.einsum("nij,j->ni", m[:, :3, :3], centre)
    m[:, 3, 3] = 1.0
    return m


def relative(m: np.ndarray, centre, anchor) -> np.ndarray:
    """The matrices from coordinates relative to the object's centre (where its data is uploaded) to coordinates
    relative to `anchor` (the renderers' GPU space, enclosing): T(-anchor) M T(centre)."""
    r = m.copy()
    r[:, :3, 3] += np.einsum("nij,j->ni", m[:, :3, :3], np.asarray(centre, np.float64)) - np.asarray(anchor, np.float64)
    return r


def model_columns(m: np.ndarray, centre, anchor) -> bytes:
    """relative(m, centre, anchor) as float32 column-major mat4s, as GLSL reads a per-instance mat4."""
    return np.ascontiguousarray(relative(m, centre, anchor).transpose(0, 2, 1), dtype="f4").tobytes()


def scales(m: np.ndarray) -> np.ndarray:
    """(N,) each similarity's uniform scale."""
    return np.linalg.norm(m[:, :3, 0], axis=1)


def spheres(m: np.ndarray, centre, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Every copy's bounding sphere: (N, 3) centres, (N,) radii, from the object's (centre, radius)."""
    return np.einsum("nij,j->ni", m[:, :3, :3], np.asarray(centre, np.float64)) + m[:, :3, 3], radius * scales(m)


def enclosing(m: np.ndarray, centre, radius: float) -> tuple[np.ndarray, float]:
    """A sphere holding every copy's bounding sphere, centred on the box of their centres: what the cameras frame,
    and the renderers' GPU space (its centre the anchor, its radius what the shadow map spans), so copies placed
    far from the object itself keep small float32 coordinates and a shadow map of their own extent (about the
    object's centre, copies 1.7e4 units away lost their shadows: mean ΔLuv 8.1). One copy in place: the object's
    own centre and radius, exactly."""
    c, r = spheres(m, centre, radius)
    mid = 0.5 * (c.min(0) + c.max(0))
    return mid, float((np.linalg.norm(c - mid, axis=1) + r).max())


def check(m: np.ndarray, centre, radius: float, origin: str) -> None:
    """Refuse copies the reference cannot hold: each copy's bounding sphere by the range check of a single
    object's (check_extent), the sphere holding them all too, each copy at least MIN_SHARE of that sphere's radius,
    and each at least MIN_FAR of its distance from the origin. InputError names the first copy out of range, its
    place and size."""
    c, r = spheres(m, centre, radius)
    with np.errstate(over="ignore", invalid="ignore"):
        bad = ~(np.isfinite(c).all(1) & (np.abs(c).max(1) <= EXTENT) & (1 / EXTENT <= r) & (r <= EXTENT))
    if bad.any():
        k = int(np.argmax(bad))
        check_extent(f"{origin}: copy {k}", c[k], float(r[k]))
    mid, around = enclosing(m, centre, radius)
    check_extent(f"{origin}: the sphere holding every copy", mid, around)
    small = r < MIN_SHARE * around
    if small.any():
        k, far = int(np.argmax(small)), int(np.argmax(np.linalg.norm(c - np.asarray(centre, np.float64), axis=1)))
        raise InputError(f"{origin}: the copies spread over a sphere of radius {around:.6g} (copy {far} at "
                         f"{np.round(c[far], 6).tolist()} the farthest from the object's own place), so copy {k} "
                         f"(radius {r[k]:.6g}) is {r[k] / around:.3g} of it, less than {MIN_SHARE:.3g}: the reference "
                         "traces the copies together in float32 and would lose it; place the copies closer "
                         "together, or make them separate objects.")
    far = np.linalg.norm(c, axis=1)
    lost = r < MIN_FAR * far
    if lost.any():
        k = int(np.argmax(lost))
        raise InputError(f"{origin}: copy {k} lies {far[k]:.6g} from the origin (at {np.round(c[k], 6).tolist()}) "
                         f"with a radius of {r[k]:.6g}, {r[k] / far[k]:.3g} of that distance, less than {MIN_FAR:.3g}: "
                         "the reference places copies in float64 and would lose its shape; place it nearer the "
                         "origin, or make it larger.")


def count(instances) -> int:
    """How many copies a scene.Instances makes."""
    return instances.scatter.count if instances.scatter is not None else len(instances.placements)


def placed(mesh, m: np.ndarray):
    """Every copy of `mesh` (vdmbake.common.mesh.TriMesh) placed by the world matrices m, merged into one mesh
    (what the reference traces): positions by each similarity, normals turned by its rotation; texture
    coordinates, colours and the albedo map kept."""
    from .mesh import TriMesh

    parts = []
    for a in m:
        rot = a[:3, :3] / np.linalg.norm(a[:3, 0])
        parts.append(TriMesh(mesh.vertices @ a[:3, :3].T + a[:3, 3], mesh.faces, mesh.normals @ rot.T, mesh.uvs,
                             colors=mesh.colors, texture=mesh.texture))
    return TriMesh.concatenate(parts)


def placed_quadrics(q, m: np.ndarray):
    """Every copy of the quadrics q (vdmbake.kernels.quadrics.QuadricSet) placed by the world matrices m, merged
    into one set (what the reference traces): centres and end points by each similarity, radii by its scale,
    colours kept."""
    scale = scales(m)[:, None]

    def moved(p):   # (N, 3) points -> (copies * N, 3)
        return (np.einsum("cij,nj->cni", m[:, :3, :3], p) + m[:, None, :3, 3]).reshape(-1, 3)

    s, c = q.spheres, q.cylinders
    spheres = np.concatenate([moved(s[:, :3]), (scale * s[:, 3]).reshape(-1, 1)], 1)
    cylinders = np.concatenate([moved(c[:, :3]), moved(c[:, 3:6]), (scale * c[:, 6]).reshape(-1, 1)], 1)
    return dataclasses.replace(q, spheres=spheres, sphere_rgb=np.tile(q.sphere_rgb, (len(m), 1)),
                               cylinders=cylinders, cylinder_rgb=np.tile(q.cylinder_rgb, (len(m), 1)))
