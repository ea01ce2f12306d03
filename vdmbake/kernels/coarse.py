"""Coarse meshes: the full mesh simplified by quadric error collapses (fast-simplification), safe at UV
seams.

A mesh file splits a vertex wherever its texture coordinates jump (a UV seam), so the seam is an open
border to a simplifier, which then collapses each side on its own and opens cracks (the textured 10k
bunny: 109 border edges in, 1013 out at half the faces). The simplifier is therefore given the surface
welded by position (`common.mesh.weld`), and its two kinds of topological damage are repaired afterwards:
fins (two faces on the same three vertices, the remains of a collapsed pocket) are removed, and an
edge that ends up shared by more than two faces (two sheets pinched together) is split into one edge
per sheet (`split_pinches`), so the output's faces meet only along manifold edges.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..common.mesh import TriMesh, crease_normals, weld

CREASE_DEG = 60.0   # faces meeting at a larger angle do not share a vertex normal


def simplify(mesh: TriMesh, ratio: float) -> TriMesh:
    """Keep about `ratio` of the faces (at least one, none if the weld leaves none) of the surface welded by
    position (`surface`); vertex normals are recomputed over the simplified surface with sharp edges kept
    sharp, per-vertex colours carried (`collapsed_colors`), and for an asset with an albedo map its UVs
    (`transferred_uvs`) and the map; other UVs are dropped (no other technique reads a coarse mesh's)."""
    textured = mesh.texture is not None
    if ratio >= 1.0:
        return TriMesh(mesh.vertices, mesh.faces, mesh.normals, mesh.uvs if textured else None,
                       colors=mesh.colors, texture=mesh.texture, file_normals=mesh.file_normals)
    v, f, colors, lineage = surface(mesh, ratio)
    if not len(f):                                     # nothing left: the caller names the setting
        return TriMesh(v[:0], f, v[:0])
    if mesh.file_normals:
        return _with_file_normals(mesh, v, f, colors, lineage)
    # Welding joined the faces across sharp edges too (a cone's rim): normals are smoothed only within
    # CREASE_DEG, so an edge sharp in the input stays sharp in the shading.
    v, f, n, source = crease_normals(v, f, CREASE_DEG)
    colors = None if colors is None else colors[source]
    if not textured:
        return TriMesh(v, f, n, colors=colors)
    # A vertex whose faces lie in different UV charts (a seam) is split into one copy per chart, at the same
    # position: the surface stays closed where the charts meet.
    corner_uv = transferred_uvs(mesh, lineage, v[f])
    key = np.column_stack([f.ravel(), corner_uv.reshape(-1, 2)])
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    keep = f.ravel()[first]
    return TriMesh(v[keep], inv.reshape(-1, 3), n[keep], corner_uv.reshape(-1, 2)[first],
                   colors=None if colors is None else colors[keep], texture=mesh.texture)


def _with_file_normals(mesh: TriMesh, v, f, colors, lineage) -> TriMesh:
    """The simplified surface shaded as the file's normals shade the full mesh (not by the crease rule, which
    would round a hard edge of less than CREASE_DEG or crease a smooth one): each corner takes the normal (and,
    textured, the UV) of the nearest point of the full mesh's piece its face descends from (`transferred_uvs`), and
    a vertex whose corners disagree is split, so the coarse level shades like the full mesh."""
    carried = mesh.normals if mesh.texture is None else np.column_stack([mesh.normals, mesh.uvs])
    both = transferred_uvs(mesh, lineage, v[f], carried).reshape(-1, carried.shape[1])   # one nearest-point search
    n, uv = both[:, :3], both[:, 3:]
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    _, first, inv = np.unique(np.column_stack([f.ravel(), np.round(n * 1e6), uv]), axis=0, return_index=True,
                              return_inverse=True)
    keep = f.ravel()[first]
    return TriMesh(v[keep], inv.reshape(-1, 3), n[first], uv[first] if mesh.texture is not None else None,
                   colors=None if colors is None else colors[keep], texture=mesh.texture, file_normals=True)


class Lineage(NamedTuple):
    """Where the simplified surface came from (the faces keep their order through every later step)."""
    origin: np.ndarray     # (F,) the full mesh's face each face descends from
    raw: np.ndarray        # (F, 3) each corner's vertex as the simplifier numbered it
    mapping: np.ndarray    # welded input vertex -> that numbering (-1: unused)
    ids: np.ndarray        # full mesh vertex -> welded vertex (common.mesh.weld)


def transferred_uvs(mesh: TriMesh, lineage: Lineage, corners: np.ndarray,
                    values: np.ndarray | None = None) -> np.ndarray:
    """(F, 3, 2) texture coordinates of the coarse faces' corners (positions `corners`, (F, 3, 3)); or of the
    full mesh's per-vertex `values` (V, C) instead of its UVs, (F, 3, C).

    Each coarse face descends from one face of the full mesh (`lineage.origin`: an edge collapse moves a
    face's corners but keeps the face), and a corner from the vertices that collapsed into it. The faces
    around those vertices form the corner's region; the part of it joined to the origin face through shared
    vertices (a mesh file splits vertices at UV seams, so a seam separates the parts) is one piece of one UV
    chart, continuous, however the chart wraps around elsewhere. The corner takes the UV of the nearest point
    of that piece: the nearest face's affine UV map at the corner projected onto its plane (beyond the face
    where the corner lies beyond the chart's border, continuing the chart linearly). So the texture follows
    the moved corners rather than sliding with them, and the faces on either side of a seam read their own
    chart."""
    origin, mapping = lineage.origin, lineage.mapping
    n_faces = np.int64(len(mesh.faces))
    # (coarse vertex, full face) pairs, sorted: the faces around the vertices collapsed into each coarse vertex
    pairs = np.unique(np.column_stack([mapping[lineage.ids[mesh.faces]].ravel(),
                                       np.repeat(np.arange(n_faces), 3)]), axis=0)
    pairs = pairs[pairs[:, 0] >= 0]
    piece = _pieces(pairs, mesh.faces)
    start = np.searchsorted(pairs[:, 0], np.arange(mapping.max() + 2))
    p = corners.reshape(-1, 3)
    vertex, own = lineage.raw.reshape(-1), np.repeat(origin, 3)
    key = pairs[:, 0] * n_faces + pairs[:, 1]
    mine = piece[np.searchsorted(key, vertex * n_faces + own)]   # the piece holding the corner's origin face
    lo, count = start[vertex], start[vertex + 1] - start[vertex]
    cand_corner = np.repeat(np.arange(len(p)), count)
    cand = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + np.repeat(lo, count)
    same = piece[cand] == mine[cand_corner]
    cand_corner, cand_face = cand_corner[same], pairs[cand[same], 1]
    b, dist = _project(mesh.vertices[mesh.faces[cand_face]], p[cand_corner])
    order = np.lexsort((dist, cand_corner))
    best = order[np.searchsorted(cand_corner[order], np.arange(len(p)))]
    values = mesh.uvs if values is None else values
    return np.einsum("nk,nkc->nc", b[best], values[mesh.faces[cand_face[best]]]).reshape(-1, 3, values.shape[1])


def _pieces(pairs: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(P,) label of each (coarse vertex, face) pair: pairs of one coarse vertex whose faces are joined
    through shared vertices (within that vertex's faces) share a label."""
    rows = np.repeat(np.arange(len(pairs)), 3)
    _, group = np.unique(np.column_stack([pairs[rows, 0], faces[pairs[:, 1]].ravel()]), axis=0, return_inverse=True)
    group = group.ravel()
    label = np.arange(len(pairs))
    while True:
        low = np.full(group.max() + 1, len(pairs))
        np.minimum.at(low, group, label[rows])
        new = label.copy()
        np.minimum.at(new, rows, low[group])
        new = new[new]                                          # pointer jumping: halves the chains
        if np.array_equal(new, label):
            return label
        label = new


def _project(tri: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric coordinates (N, 3) of points p projected onto their triangles' planes (unclamped: outside
    the triangle they extend it), and the distance from p to the triangle itself (clamped), for ranking.
    A sliver (no plane) gives its nearest corner."""
    e1, e2, d = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], p - tri[:, 0]
    g11, g12, g22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    r1, r2 = (d * e1).sum(1), (d * e2).sum(1)
    det = g11 * g22 - g12 * g12
    ok = det > 1e-12 * g11 * g22
    safe = np.where(ok, det, 1.0)
    b1 = np.where(ok, (g22 * r1 - g12 * r2) / safe, 0.0)
    b2 = np.where(ok, (g11 * r2 - g12 * r1) / safe, 0.0)
    b = np.column_stack([1 - b1 - b2, b1, b2])
    corner = np.argmin(np.linalg.norm(p[:, None] - tri, axis=2), 1)
    b = np.where(ok[:, None], b, np.eye(3)[corner])
    # distance to the triangle: to the clamped-and-renormalised barycentric point (a ranking, not exact)
    c = np.clip(b, 0.0, None)
    c /= np.maximum(c.sum(1, keepdims=True), 1e-300)
    return b, np.linalg.norm(np.einsum("nk,nkc->nc", c, tri) - p, axis=1)


def surface(mesh: TriMesh, ratio: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, Lineage | None]:
    """The simplified surface: vertices, faces (manifold edges only, no fins), per-vertex colours (or
    None) and, for an asset with an albedo map or file normals, its Lineage (None otherwise: the replay of the collapses
    and the face matching are about a third of the time): one vertex per point, but where a pinched edge
    was split."""
    import fast_simplification

    ids = weld(mesh.vertices)
    points = mesh.vertices[np.unique(ids, return_index=True)[1]]
    faces = ids[mesh.faces]
    whole = np.flatnonzero((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0]))
    faces = faces[whole]
    if not len(faces):      # every face's corners weld into one point or a line: no surface to simplify
        return points[:0], faces, None, None
    # Simplify about the centre: quadric errors of a far-off mesh lose digits otherwise.
    centre = 0.5 * (points.min(0) + points.max(0))
    target = min(len(faces), max(1, int(round(ratio * len(mesh.faces)))))   # the weld may leave fewer
    v, f, collapses = fast_simplification.simplify(points - centre, faces, target_count=target, return_collapses=True)
    v = np.asarray(v, np.float64) + centre
    f = np.asarray(f, np.int64).reshape(-1, 3)
    textured = mesh.texture is not None or mesh.file_normals    # both need the lineage (transferred_uvs)
    mapping = (np.asarray(fast_simplification.replay_simplification(points, faces, collapses)[2])
               if textured or mesh.colors is not None else None)
    colors = None if mesh.colors is None else collapsed_colors(points, faces, ids, mesh.colors, mapping, len(v))
    origin = whole[surviving_faces(faces, f, mapping)] if textured else None
    keep = fin_free(f)
    if keep.any():                                     # all fins (a handful of faces): keep them, not nothing
        f, origin = f[keep], None if origin is None else origin[keep]
    raw = f
    v, f, used = compact(v, f)
    v, f, source = split_pinches(v, f)
    colors = None if colors is None else colors[used][source]
    # A collapse's optimal point may lie beyond the full mesh's bounding sphere (0.9% of the radius on a
    # coarse torus), where the cameras' clip planes, which hug that sphere, would cut it: pulled back onto it.
    sphere_centre, radius = mesh.bounding_sphere()
    reach = np.linalg.norm(v - sphere_centre, axis=1, keepdims=True)
    v = sphere_centre + (v - sphere_centre) * np.minimum(1.0, radius / np.maximum(reach, 1e-300))
    return v, f, colors, Lineage(origin, raw, mapping, ids) if textured else None


def surviving_faces(faces: np.ndarray, out: np.ndarray, mapping: np.ndarray) -> np.ndarray:
    """For each simplified face, the input face it is: edge collapses only delete faces and renumber the
    corners of the others, so an output face is the one input face whose corners map (`mapping`: input
    vertex -> output vertex, fast-simplification's replay) onto its three vertices."""
    both = np.concatenate([np.sort(out, 1), np.sort(mapping[faces], 1)])
    _, inv = np.unique(both, axis=0, return_inverse=True)
    inv = inv.ravel()
    face_of = np.full(inv.max() + 1, -1, np.int64)
    face_of[inv[len(out):]] = np.arange(len(faces))
    origin = face_of[inv[:len(out)]]
    if (origin < 0).any():
        raise RuntimeError("coarse: a simplified face matches no input face (fast-simplification changed?)")
    return origin


def collapsed_colors(points, faces, ids, colors, mapping, count: int) -> np.ndarray:
    """(count, 3) colours of the simplified vertices: each the area-weighted mean of the welded vertices
    collapsed into it (`mapping`: fast-simplification's replay of the collapses maps every input vertex to
    its output vertex); a welded vertex's colour is the mean of the vertices it welds."""
    welded = np.zeros((len(points), 3))
    np.add.at(welded, ids, colors)
    welded /= np.bincount(ids, minlength=len(points))[:, None]
    tri = points[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    weight = np.bincount(faces.ravel(), np.repeat(area, 3), len(points)) + 1e-300
    kept = mapping >= 0                          # -1: a vertex no face uses (a file may list such)
    total = np.zeros((count, 3))
    np.add.at(total, mapping[kept], (welded * weight[:, None])[kept])
    return total / np.maximum(np.bincount(mapping[kept], weight[kept], count), 1e-300)[:, None]


def fin_free(faces: np.ndarray) -> np.ndarray:
    """Which faces to keep so that none repeats: every face whose three vertices another face also has goes,
    both of a pair facing opposite ways (a zero-volume fin that a collapse left behind) and repeats facing
    the same way (one copy kept)."""
    key = np.sort(faces, 1)
    _, first, inverse, count = np.unique(key, axis=0, return_index=True, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    # A group is a fin when its faces do not all wind the same way as its first face.
    same = np.all(np.roll(faces, 0, 1) == faces[first[inverse]], 1) | \
        np.all(np.roll(faces, 1, 1) == faces[first[inverse]], 1) | np.all(np.roll(faces, 2, 1) == faces[first[inverse]], 1)
    fin = np.zeros(len(first), bool)
    np.logical_or.at(fin, inverse, ~same)
    return (count[inverse] == 1) | (~fin[inverse] & (np.arange(len(faces)) == first[inverse]))


def compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Drop the vertices no face uses; also returns the kept vertices' old indices."""
    used, f = np.unique(faces, return_inverse=True)
    return vertices[used], f.reshape(-1, 3), used


def edge_faces(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Undirected edges: (E, 2) sorted vertex pairs, the edge of every face side (F*3, face-major: side
    3i + k runs from corner k to corner k + 1 of face i), the number of faces on each edge and how many
    of them run along it from its lower to its higher vertex."""
    sides = np.stack([faces, np.roll(faces, -1, 1)], 2).reshape(-1, 2)
    edges, inverse, count = np.unique(np.sort(sides, 1), axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    return edges, inverse, count, np.bincount(inverse, sides[:, 0] < sides[:, 1], len(edges)).astype(np.int64)


def split_pinches(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split each vertex of a pinched edge (shared by 4, 6, ... faces, half running each way: sheets that a
    collapse pressed together) into one copy per fan: the faces around the vertex that connect through
    edges of exactly two faces. The sheets then touch there (same positions, separate vertices), each
    edge-manifold. An edge of three faces (a T-junction, as a scan may have) is left as it is. Also returns
    each output vertex's source vertex (the copies' originals)."""
    edges, side_edge, count, forward = edge_faces(faces)
    bad = np.unique(edges[(count > 2) & (2 * forward == count)])
    if len(bad) == 0:
        return vertices, faces, np.arange(len(vertices))
    corners = faces.ravel()                         # corner c = 3 * face + k, at vertex corners[c]
    label = np.arange(len(corners))
    # Join the corners of two faces at a shared manifold edge, per end of that edge.
    side_face = np.repeat(np.arange(len(faces)), 3)
    side_k = np.tile(np.arange(3), len(faces))
    manifold = count[side_edge] == 2
    s = np.flatnonzero(manifold)
    s = s[np.argsort(side_edge[s], kind="stable")]  # the two sides of each manifold edge, adjacent
    a, b = s[0::2], s[1::2]
    pairs = []
    for end in (0, 1):
        ca = 3 * side_face[a] + (side_k[a] + end) % 3                 # corner at this end in face of a
        va = corners[ca]
        cb = 3 * side_face[b] + np.argmax(faces[side_face[b]] == va[:, None], 1)
        pairs.append(np.stack([ca, cb], 1))
    pairs = np.concatenate(pairs)
    pairs = pairs[np.isin(corners[pairs[:, 0]], bad)]                # only the fans of pinched vertices
    while True:                                                      # connected components by min-label
        lo = np.minimum(label[pairs[:, 0]], label[pairs[:, 1]])
        if np.array_equal(label[pairs[:, 0]], lo) and np.array_equal(label[pairs[:, 1]], lo):
            break
        np.minimum.at(label, pairs[:, 0], lo)
        np.minimum.at(label, pairs[:, 1], lo)
    # Each fan of a pinched vertex beyond its first gets a new vertex at the same position.
    pinched = np.isin(corners, bad)
    fans, fan_of = np.unique(label[pinched], return_inverse=True)
    fan_vertex = corners[fans]
    first_fan = np.unique(fan_vertex, return_index=True)[1]
    new_id = np.full(len(fans), -1, np.int64)
    new_id[first_fan] = fan_vertex[first_fan]
    extra = np.flatnonzero(new_id < 0)
    new_id[extra] = len(vertices) + np.arange(len(extra))
    out = corners.copy()
    out[pinched] = new_id[fan_of.ravel()]
    source = np.concatenate([np.arange(len(vertices)), fan_vertex[extra]])
    return vertices[source], out.reshape(-1, 3), source
