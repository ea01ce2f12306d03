"""Conventional displacement mapping: the base mesh subdivided and displaced inward by the
mesostructure (Cook 1984). It is both the `displaced` technique (at a few subdivision levels)
and, subdivided until no edge spans more than half a height-field texel, the truly displaced
geometry the VDM reference traces (DESIGN.md, "The reference").

The base mesh is the reference surface every mesostructure technique starts from, so the
subdivision is linear (midpoint) over its facets, carrying the interpolated normal, UV and
texture tangents; a vertex moves by depth * s_n * (1 - h(uv * tiling)) against its normal.

Seams live in the texture coordinates only: vertices split for their UVs (a UV seam) are welded by
position first (meshes.weld), take one position and one normal, and move by the mean of their
copies' displacements (equal where the height field is continuous across the seam, e.g. a periodic
tile at integer tiling), so the displaced surface has no cracks; each copy keeps its own UV and
shading normal.
"""
from __future__ import annotations

import numpy as np

from . import texspace
from .errors import InputError
from .heightfields import sample
from .meshes import TriMesh, subdivide, weld
from .vdm import height_normals

MAX_FACES = 16_000_000   # a reference finer than this would not fit a 24 GiB machine's Embree build


def edge_texels(mesh: TriMesh, size: int, tiling) -> float:
    """The longest base-mesh edge, measured in height-field texels of the tiled UVs."""
    d = mesh.uvs[mesh.faces] - mesh.uvs[np.roll(mesh.faces, 1, axis=1)]
    return float(np.abs(d * np.asarray(tiling) * size).max())


def reference_levels(mesh: TriMesh, size: int, tiling) -> int:
    """Subdivision levels that bring every edge under half a texel."""
    return max(0, int(np.ceil(np.log2(max(edge_texels(mesh, size, tiling), 1e-9) / 0.5))))


def displaced(mesh: TriMesh, heights: np.ndarray, depth: float, tiling, levels: int) -> TriMesh:
    """The base mesh (with UVs and frame) subdivided `levels` times and displaced inward. The
    shading normals are those every per-pixel technique uses: the mesostructure's texture-space
    normal (vdm.height_normals) mapped through the interpolated frame, so the comparison measures
    geometry (parallax, occlusion, silhouettes, shadows), not a different normal."""
    faces_out = len(mesh.faces) * 4 ** levels
    if faces_out > MAX_FACES:
        raise InputError(f"displacement at {levels} subdivision levels would make {faces_out:,} faces "
                         f"(limit {MAX_FACES:,}); use fewer levels, a smaller mesostructure size, "
                         "less tiling or a finer base mesh.")
    w = weld(mesh.vertices)
    first = np.unique(w, return_index=True)[1]
    normal = np.zeros((len(first), 3))
    np.add.at(normal, w, mesh.normals)                     # one normal per point of the surface
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    f, a = mesh.faces, {"pos": mesh.vertices[first][w], "normal": normal[w], "uv": mesh.uvs,
                        "dpdu": mesh.frame.dpdu, "dpdv": mesh.frame.dpdv, "weld": w}
    for _ in range(levels):
        f, a = subdivide(f, a)
    T = a["uv"] * np.asarray(tiling)
    J = np.stack([a["dpdu"] / tiling[0], a["dpdv"] / tiling[1]], -1)
    J -= a["normal"][:, :, None] * np.einsum("vi,vij->vj", a["normal"], J)[:, None, :]   # into the tangent plane
    amount = depth * texspace.normal_scale(J) * (1.0 - sample(heights, T))
    w = a["weld"]
    amount = (np.bincount(w, amount) / np.bincount(w))[w]   # the copies of a seam vertex move together
    moved = a["pos"] - a["normal"] * amount[:, None]
    n_tex = np.stack([sample(c, T) for c in np.moveaxis(height_normals(heights, depth), -1, 0)], -1)
    return TriMesh(moved, f, texspace.world_normals(J, a["normal"], n_tex), a["uv"])
