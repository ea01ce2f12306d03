"""Coarse meshes: the full mesh simplified by quadric error collapses (fast-simplification)."""
from __future__ import annotations

import numpy as np

from .meshes import TriMesh, vertex_normals


def simplify(mesh: TriMesh, ratio: float) -> TriMesh:
    """Keep about `ratio` of the faces (at least one); vertex normals are recomputed, UVs dropped."""
    import fast_simplification

    if ratio >= 1.0:
        return TriMesh(mesh.vertices, mesh.faces, mesh.normals)
    # Simplify about the centre: quadric errors of a far-off mesh lose digits otherwise.
    centre = 0.5 * (mesh.vertices.min(0) + mesh.vertices.max(0))
    target = max(1, int(round(ratio * len(mesh.faces))))
    v, f = fast_simplification.simplify(mesh.vertices - centre, mesh.faces, target_count=target)
    v = np.asarray(v, np.float64) + centre
    f = np.asarray(f, np.int64).reshape(-1, 3)
    return TriMesh(v, f, vertex_normals(v, f))
