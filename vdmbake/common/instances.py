"""Instances (issue 23): the matrices that place an object's copies, pure numpy, shared by the renderer's
instanced draws and the reference.

Every instance is a similarity about the object's bounding-sphere centre c: M = T(c + t) R S(s) T(-c), a uniform
scale s (so normals only turn: R n), a rotation R and a translation t. A list gives t, R (about X, then Y, then Z)
and s per instance; a scatter draws t uniformly over a rectangle of the plane normal to the scene's up, R a turn
about up, s uniformly in its range, from numpy's PCG64 generator seeded by the scene (the same seed, the same
places)."""
from __future__ import annotations

import numpy as np

from ..assets.meshes import rotation_xyz


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


def relative(m: np.ndarray, anchor) -> np.ndarray:
    """The matrices between anchor-relative coordinates (the renderers' GPU space): T(-a) M T(a)."""
    a = np.asarray(anchor, np.float64)
    r = m.copy()
    r[:, :3, 3] += np.einsum("nij,j->ni", m[:, :3, :3], a) - a
    return r


def model_columns(m: np.ndarray, anchor) -> bytes:
    """The matrices about `anchor` (relative) as float32 column-major mat4s, as GLSL reads a per-instance mat4."""
    return np.ascontiguousarray(relative(m, anchor).transpose(0, 2, 1), dtype="f4").tobytes()


def scales(m: np.ndarray) -> np.ndarray:
    """(N,) each similarity's uniform scale."""
    return np.linalg.norm(m[:, :3, 0], axis=1)


def reach(m: np.ndarray, anchor, radius: float) -> float:
    """The radius about `anchor` (an object's bounding-sphere centre) that holds every copy's bounding sphere."""
    rel = relative(m, anchor)
    return float((np.linalg.norm(rel[:, :3, 3], axis=1) + radius * scales(rel)).max())


def spheres(m: np.ndarray, centre, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Every copy's bounding sphere: (N, 3) centres, (N,) radii, from the object's (centre, radius)."""
    return np.einsum("nij,j->ni", m[:, :3, :3], np.asarray(centre, np.float64)) + m[:, :3, 3], radius * scales(m)


def enclosing(m: np.ndarray, centre, radius: float) -> tuple[np.ndarray, float]:
    """A sphere holding every instance's bounding sphere: centred on the box of their centres, as large as the
    farthest instance's surface from there."""
    c, r = spheres(m, centre, radius)
    mid = 0.5 * ((c - r[:, None]).min(0) + (c + r[:, None]).max(0))
    return mid, float((np.linalg.norm(c - mid, axis=1) + r).max())


def count(instances) -> int:
    """How many copies a scene.Instances makes."""
    return instances.scatter.count if instances.scatter is not None else len(instances.placements)


def placed(mesh, m: np.ndarray):
    """Every copy of `mesh` (vdmbake.assets.meshes.TriMesh) placed by the world matrices m, merged into one mesh
    (what the reference traces): positions by each similarity, normals turned by its rotation; texture
    coordinates, colours and the albedo map kept."""
    from ..assets.meshes import TriMesh

    parts = []
    for a in m:
        rot = a[:3, :3] / np.linalg.norm(a[:3, 0])
        parts.append(TriMesh(mesh.vertices @ a[:3, :3].T + a[:3, 3], mesh.faces, mesh.normals @ rot.T, mesh.uvs,
                             colors=mesh.colors, texture=mesh.texture))
    return TriMesh.concatenate(parts)
