"""Quadrics as one plain triangle mesh for viewers (MeshLab, trimesh, Blender): the exact quadric list
(`quadrics` part) uses custom PLY elements that no viewer draws, so a quadrics object can also store
its spheres and capped cylinders tessellated, as the `tessellated` technique draws them
(shaders/instanced.vert places the same unit icosphere and prism per quadric on the GPU), in a
standard PLY: vertex x y z, nx ny nz (float) and red green blue (uchar sRGB), triangle faces.
"""
from __future__ import annotations

import numpy as np

from ..common import geometry
from ..common.colour import to_srgb8
from ..common.mesh import TriMesh
from ..formats.ply import elements_from_bytes, elements_to_bytes
from .quadrics import QuadricSet


def tessellate(q: QuadricSet, level: int) -> tuple[TriMesh, np.ndarray]:
    """One mesh of every quadric: icospheres subdivided `level` times (20 * 4^level faces), prisms with
    4 * 2^level sides and flat caps; and its (V, 3) linear RGB vertex colours (each quadric's own)."""
    sphere = geometry.icosphere(level)
    prism = geometry.cylinder(1.0, 2.0, 4 * 2 ** level, 1, 1)   # radius 1, z in [-1, 1]
    s, c = q.spheres, q.cylinders
    # Spheres: centre + radius * unit vertex; the unit normals stay.
    sv = s[:, None, :3] + s[:, None, 3:4] * sphere.vertices[None]
    sn = np.broadcast_to(sphere.normals, sv.shape)
    # Cylinders: the prism's z runs from p0 (z = -1) to p1 (z = 1), x and y along a frame around the axis.
    p0, p1, r = c[:, :3], c[:, 3:6], c[:, 6:7]
    axis = p1 - p0
    w = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    u, v = geometry.onb(w)
    x, y, z = (prism.vertices[None, :, k:k + 1] for k in range(3))
    cv = (0.5 * (p0 + p1))[:, None] + x * (r * u)[:, None] + y * (r * v)[:, None] + z * (0.5 * axis)[:, None]
    nx, ny, nz = (prism.normals[None, :, k:k + 1] for k in range(3))
    cn = nx * u[:, None] + ny * v[:, None] + nz * w[:, None]
    vertices = np.concatenate([sv.reshape(-1, 3), cv.reshape(-1, 3)])
    normals = np.concatenate([sn.reshape(-1, 3), cn.reshape(-1, 3)])
    faces = np.concatenate([(sphere.faces[None] + len(sphere.vertices) * np.arange(len(s))[:, None, None]).reshape(-1, 3),
                            (prism.faces[None] + len(prism.vertices) * np.arange(len(c))[:, None, None]).reshape(-1, 3)
                            + len(s) * len(sphere.vertices)])
    rgb = np.concatenate([np.repeat(q.sphere_rgb, len(sphere.vertices), 0), np.repeat(q.cylinder_rgb, len(prism.vertices), 0)])
    return TriMesh(vertices, faces.astype(np.int64), normals), rgb


def to_bytes(mesh: TriMesh, rgb: np.ndarray) -> bytes:
    """The standard PLY viewers read (float positions: a viewer's precision)."""
    v = np.zeros(len(mesh.vertices), [(n, "<f4") for n in ("x", "y", "z", "nx", "ny", "nz")]
                 + [(n, "|u1") for n in ("red", "green", "blue")])
    srgb = to_srgb8(rgb)
    for k, axis in enumerate("xyz"):
        v[axis], v["n" + axis] = mesh.vertices[:, k], mesh.normals[:, k]
        v[("red", "green", "blue")[k]] = srgb[:, k]
    f = np.zeros(len(mesh.faces), [("n", "u1"), ("vertex_indices", "<i4", (3,))])
    f["n"], f["vertex_indices"] = 3, mesh.faces
    return elements_to_bytes({"vertex": v, "face": f}, "vdmbake quadrics tessellated for viewers")


def from_bytes(data: bytes, origin: str) -> tuple[TriMesh, np.ndarray]:
    """The mesh and its sRGB8 vertex colours, as written by to_bytes."""
    e = elements_from_bytes(data, origin)
    v = e["vertex"]
    col = lambda *names: np.stack([v[n] for n in names], 1)  # noqa: E731
    return (TriMesh(col("x", "y", "z").astype(np.float64), e["face"]["vertex_indices"].astype(np.int64),
                    col("nx", "ny", "nz").astype(np.float64)), col("red", "green", "blue"))
