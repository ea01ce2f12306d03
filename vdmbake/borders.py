"""Open boundaries of a surface with mesostructure (VDM, Wang et al. 2003, sec. 5: "VDMs will be
extended to model open surface boundaries, which are not handled in our current implementation").

The mesostructure fills a shell under the base surface: from the reference surface down to
depth * s_n along the normal (texspace.py). On a closed surface the shell has no sides. Where the
base surface has a border (a plane, an open mesh), the shell is open there, and what a view sees
through that open side is defined by no per-pixel method: the VDM, parallax occlusion mapping and
bump mapping all start their rays at the base surface, while the truly displaced reference sheet
shows its cut edge and, from behind, its underside. The shell's side wall is the `skirt`: every
border edge swept from the base surface to the shell's floor. A view ray that crosses the skirt
before its reference hit (or crosses it and hits nothing) sees the border; vdmrender scores those
pixels apart from the surface (vdmrender/borders.py).

Pure numpy; borders are found on the surface, not on its UV charts: vertices split at a UV seam
are welded first (meshes.weld), so a seam is never a border.
"""
from __future__ import annotations

import numpy as np

from . import texspace
from .meshes import TriMesh, weld


def boundary_edges(faces: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """(E, 2) vertex index pairs of the edges used by exactly one face, keyed by the position ids
    `ids` (meshes.weld), in their face's winding order (so the surface lies to the left)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = np.sort(ids[e], axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[counts[inv.ravel()] == 1]


def skirt(mesh: TriMesh, depth: float, tiling) -> tuple[np.ndarray, np.ndarray]:
    """The shell's side wall along the base mesh's borders: (vertices (2B, 3), faces (2E, 3)), each
    border edge a quad from the base surface down to depth * s_n along each end's normal (the deepest
    the mesostructure reaches there). Empty arrays on a closed surface."""
    ids = weld(mesh.vertices)
    edges = boundary_edges(mesh.faces, ids)
    if not len(edges):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    used, local = np.unique(edges, return_inverse=True)
    local = local.reshape(-1, 2)
    n = mesh.normals[used]
    J = texspace.jacobian(mesh.frame, tiling)[used]
    J = J - n[:, :, None] * np.einsum("vi,vij->vj", n, J)[:, None, :]     # into the tangent plane
    top = mesh.vertices[used]
    bottom = top - n * (depth * texspace.normal_scale(J))[:, None]
    a, b = local[:, 0], local[:, 1]
    m = len(used)
    faces = np.concatenate([np.stack([a, b, b + m], 1), np.stack([a, b + m, a + m], 1)])
    return np.concatenate([top, bottom]), faces.astype(np.int64)
