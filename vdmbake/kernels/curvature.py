"""Per-vertex texture tangents and principal curvatures estimated on a triangle mesh with UVs.

For meshes loaded from files, where no analytic SurfaceFrame exists. The curvatures follow
Rusinkiewicz, "Estimating Curvatures and Their Derivatives on Triangle Meshes" (3DPVT 2004):
per face, the second fundamental form is fitted by least squares to the differences of the
vertex normals along the three edges, in an orthonormal face frame; each corner rotates its
vertex's tangent frame into the face plane, re-expresses the face tensor there, and the vertex
averages these with mixed Voronoi-area weights (Meyer et al. 2003); the eigen-decomposition of
the averaged 2x2 tensor gives the principal curvatures and directions.

Conventions (those of SurfaceFrame and primitives.py): k > 0 where the surface bends away from
its normal (dN/ds = k t along a principal direction t, so a sphere with outward normals has
k1 = k2 = +1/R); k1 >= k2; d1 is unit, perpendicular to the normal, the direction of k1; k2 is
along d2 = normal x d1. dpdu, dpdv are the per-face gradients of position with respect to the UVs,
averaged with face-area weights and projected onto each vertex's tangent plane. Faces of zero area
(zero UV area, for the tangents) contribute nothing; a vertex with nothing to average gets zero
tangents, zero curvatures and an arbitrary d1 perpendicular to its normal. All outputs are finite.
"""
from __future__ import annotations

import numpy as np

from ..common.mesh import SurfaceFrame

_DEGENERATE = 1e-12   # a triangle whose area / (sum of squared edges) is below this has no shape


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _unit(a: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(a, axis=-1, keepdims=True)
    return np.divide(a, length, out=np.zeros_like(a), where=length > 0)


def _vertex_average(faces: np.ndarray, weight: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    """Weighted mean over each vertex's corners of per-corner values (F, 3, ...); 0 where no weight."""
    flat = values.reshape(faces.size, -1)
    acc, total = np.zeros((count, flat.shape[1])), np.zeros(count)
    np.add.at(acc, faces.ravel(), weight.reshape(-1, 1) * flat)
    np.add.at(total, faces.ravel(), weight.ravel())
    scale = np.divide(1.0, total, out=np.zeros_like(total), where=total > 0)
    return (acc * scale[:, None]).reshape(count, *values.shape[2:])


def _uv_tangents(p, faces, n, uvs):
    """dpdu, dpdv: per-face solutions of [e1 e2] = [dpdu dpdv] [duv1 duv2], area-weighted at the vertices."""
    tri, uv = p[faces], uvs[faces]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    a, b = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]
    usable = np.abs(det) > _DEGENERATE * np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=usable)[:, None]
    grads = np.stack([(e1 * b[:, 1:] - e2 * a[:, 1:]) * inv, (e2 * a[:, :1] - e1 * b[:, :1]) * inv], 1)
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1) * usable
    g = _vertex_average(faces, np.repeat(area[:, None], 3, 1), np.repeat(grads[:, None], 3, 1), len(p))
    g -= n[:, None] * _dot(g, n[:, None])[..., None]
    return g[:, 0], g[:, 1]


def _face_tensors(e, dn):
    """Per-face orthonormal frame (t, b, normal) and the least-squares second fundamental form
    (ku, kuv, kv) in it, fitted to II(e_i) = dn_i for the three edges; zero-area faces flagged."""
    l2 = _dot(e, e)
    cross = np.cross(e[:, 0], e[:, 1])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    good = area > _DEGENERATE * l2.sum(1)
    t, nf = _unit(e[:, 0]), _unit(cross)
    b = np.cross(nf, t)
    u, v = _dot(e, t[:, None]), _dot(e, b[:, None])              # (F, 3) edge coordinates
    du, dv = _dot(dn, t[:, None]), _dot(dn, b[:, None])
    uu, uv, vv = (u * u).sum(1), (u * v).sum(1), (v * v).sum(1)
    zero = np.zeros_like(uu)
    m = np.stack([np.stack([uu, uv, zero], -1), np.stack([uv, uu + vv, uv], -1),
                  np.stack([zero, uv, vv], -1)], 1)
    rhs = np.stack([(u * du).sum(1), (v * du + u * dv).sum(1), (v * dv).sum(1)], -1)
    m[~good] = np.eye(3)
    rhs[~good] = 0.0
    k = np.linalg.solve(m, rhs[..., None])[..., 0]
    return t, b, nf, k, area, good


def _mixed_areas(e, area, good):
    """Meyer et al.'s mixed Voronoi area of each corner; e[:, i] is the edge opposite corner i."""
    l2 = _dot(e, e)
    nxt, prv = np.roll(e, -1, axis=1), np.roll(e, -2, axis=1)        # edges i+1, i+2
    dots = -_dot(nxt, prv)                                            # |a||b| cos(angle at corner i)
    inv = np.divide(1.0, 16.0 * area, out=np.zeros_like(area), where=good)[:, None]
    # (1/8) sum over the two edges at corner i of |edge|^2 cot(the angle opposite it), cot = dot / 2A
    voronoi = (np.roll(l2, -2, 1) * np.roll(dots, -2, 1) + np.roll(l2, -1, 1) * np.roll(dots, -1, 1)) * inv
    obtuse = dots < 0
    mixed = np.where(obtuse, 0.5, 0.25) * area[:, None]
    return np.where(obtuse.any(1, keepdims=True), mixed, voronoi) * good[:, None]


def _vertex_basis(p, faces, n):
    """An orthonormal tangent basis (up, vp = n x up) per vertex, up along an incident edge (so it
    moves with the mesh under rigid motions), any perpendicular where no edge serves."""
    edge = np.zeros_like(p)
    edge[faces.ravel()] = (p[np.roll(faces, -1, 1)] - p[faces]).reshape(-1, 3)
    up = edge - n * _dot(edge, n)[:, None]
    axis = np.where((np.abs(n[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    ok = np.linalg.norm(up, axis=1) > 1e-6 * np.linalg.norm(edge, axis=1)
    up = _unit(np.where(ok[:, None], up, np.cross(n, axis)))
    return up, np.cross(n, up)


def _rotate_into(x, a, b):
    """Rotate vectors x perpendicular to unit a by the rotation taking a to unit b (a . b >= 0)."""
    dperp = (a + b) / (1.0 + _dot(a, b))[..., None]
    return x - dperp * _dot(x, b)[..., None]


def estimate_frame(vertices, faces, normals, uvs) -> SurfaceFrame:
    """SurfaceFrame estimated from a triangle mesh: vertices (V, 3), faces (F, 3) vertex indices,
    unit normals (V, 3) that fix the curvature sign, uvs (V, 2)."""
    p = np.asarray(vertices, np.float64)
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    n = _unit(np.asarray(normals, np.float64))
    dpdu, dpdv = _uv_tangents(p, faces, n, np.asarray(uvs, np.float64))

    tri, nrm = p[faces], n[faces]
    e = np.roll(tri, -2, axis=1) - np.roll(tri, -1, axis=1)        # e_i = p_{i+2} - p_{i+1}
    dn = np.roll(nrm, -2, axis=1) - np.roll(nrm, -1, axis=1)
    t, b, nf, k, area, good = _face_tensors(e, dn)
    weight = _mixed_areas(e, area, good)

    # Each corner: the vertex basis rotated into the face plane (towards whichever side of it the
    # vertex normal faces), then the face tensor evaluated on that basis.
    up, vp = _vertex_basis(p, faces, n)
    side = np.where(_dot(nrm, nf[:, None]) < 0, -1.0, 1.0)[..., None]
    target = side * nf[:, None]
    ru, rv = _rotate_into(up[faces], nrm, target), _rotate_into(vp[faces], nrm, target)
    u1, v1 = _dot(ru, t[:, None]), _dot(ru, b[:, None])
    u2, v2 = _dot(rv, t[:, None]), _dot(rv, b[:, None])
    ku, kuv, kv = (k[:, i:i + 1] for i in range(3))
    corner = np.stack([ku * u1 * u1 + 2 * kuv * u1 * v1 + kv * v1 * v1,
                       ku * u1 * u2 + kuv * (u1 * v2 + u2 * v1) + kv * v1 * v2,
                       ku * u2 * u2 + 2 * kuv * u2 * v2 + kv * v2 * v2], -1)
    tensor = _vertex_average(faces, weight, corner, len(p))
    mat = np.stack([tensor[:, :2], tensor[:, 1:]], 1)             # [[ku, kuv], [kuv, kv]]
    evals, evecs = np.linalg.eigh(mat)                             # ascending
    a, c = evecs[:, 0, 1], evecs[:, 1, 1]                          # eigenvector of the larger one
    sign = np.where(a < 0, -1.0, 1.0)[:, None]                     # d1 . up >= 0: follows rigid motions
    d1 = sign * (a[:, None] * up + c[:, None] * vp)
    return SurfaceFrame(dpdu, dpdv, evals[:, 1].copy(), evals[:, 0].copy(), d1)
