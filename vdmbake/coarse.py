"""Coarse meshes: the full mesh simplified by quadric error collapses (fast-simplification), safe at UV
seams.

A mesh file splits a vertex wherever its texture coordinates jump (a UV seam), so the seam is an open
border to a simplifier, which then collapses each side on its own and opens cracks (the textured 10k
bunny: 109 border edges in, 1013 out at half the faces). The simplifier is therefore given the surface
welded by position (`meshes.weld`), and its two kinds of topological damage are repaired afterwards:
fins (two faces on the same three vertices, the remains of a collapsed pocket) are removed, and an
edge that ends up shared by more than two faces (two sheets pinched together) is split into one edge
per sheet (`split_pinches`), so the output's faces meet only along manifold edges.
"""
from __future__ import annotations

import numpy as np

from .meshes import TriMesh, vertex_normals, weld


def simplify(mesh: TriMesh, ratio: float) -> TriMesh:
    """Keep about `ratio` of the faces (at least one) of the surface welded by position; vertex normals are
    recomputed over the simplified surface, UVs dropped (no technique textures a coarse mesh), per-vertex
    colours carried (`collapsed_colors`)."""
    import fast_simplification

    if ratio >= 1.0:
        return TriMesh(mesh.vertices, mesh.faces, mesh.normals, colors=mesh.colors)
    ids = weld(mesh.vertices)
    points = mesh.vertices[np.unique(ids, return_index=True)[1]]
    faces = ids[mesh.faces]
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])]
    # Simplify about the centre: quadric errors of a far-off mesh lose digits otherwise.
    centre = 0.5 * (points.min(0) + points.max(0))
    target = max(1, int(round(ratio * len(mesh.faces))))
    v, f, collapses = fast_simplification.simplify(points - centre, faces, target_count=target, return_collapses=True)
    v = np.asarray(v, np.float64) + centre
    f = np.asarray(f, np.int64).reshape(-1, 3)
    colors = None if mesh.colors is None else collapsed_colors(points, faces, ids, mesh.colors, collapses, len(v))
    f = remove_fins(f) if len(remove_fins(f)) else f   # all fins (a handful of faces): keep them, not nothing
    v, f, used = compact(v, f)
    v, f, source = split_pinches(v, f)
    colors = None if colors is None else colors[used][source]
    # A collapse's optimal point may lie beyond the full mesh's bounding sphere (0.9% of the radius on a
    # coarse torus), where the cameras' clip planes, which hug that sphere, would cut it: pulled back onto it.
    sphere_centre, radius = mesh.bounding_sphere()
    reach = np.linalg.norm(v - sphere_centre, axis=1, keepdims=True)
    v = sphere_centre + (v - sphere_centre) * np.minimum(1.0, radius / np.maximum(reach, 1e-300))
    return TriMesh(v, f, vertex_normals(v, f), colors=colors)


def collapsed_colors(points, faces, ids, colors, collapses, count: int) -> np.ndarray:
    """(count, 3) colours of the simplified vertices: each the area-weighted mean of the welded vertices
    collapsed into it (fast-simplification's replay of the collapses maps every input vertex to its output
    vertex); a welded vertex's colour is the mean of the vertices it welds."""
    import fast_simplification

    mapping = np.asarray(fast_simplification.replay_simplification(points, faces, collapses)[2])
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


def remove_fins(faces: np.ndarray) -> np.ndarray:
    """Faces without their repeats: every face whose three vertices another face also has goes, both of a
    pair facing opposite ways (a zero-volume fin that a collapse left behind) and repeats facing the same
    way (one copy kept)."""
    key = np.sort(faces, 1)
    _, first, inverse, count = np.unique(key, axis=0, return_index=True, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    # A group is a fin when its faces do not all wind the same way as its first face.
    same = np.all(np.roll(faces, 0, 1) == faces[first[inverse]], 1) | \
        np.all(np.roll(faces, 1, 1) == faces[first[inverse]], 1) | np.all(np.roll(faces, 2, 1) == faces[first[inverse]], 1)
    fin = np.zeros(len(first), bool)
    np.logical_or.at(fin, inverse, ~same)
    keep = (count[inverse] == 1) | (~fin[inverse] & (np.arange(len(faces)) == first[inverse]))
    return faces[keep]


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
