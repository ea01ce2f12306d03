"""The triangle mesh every room shares (vertices, faces, normals, UVs, colours, texture, Wang2003's surface frame) and
the pure numpy that measures it: its bounding box's middle, area-weighted and crease-preserving normals, and welding
by position, placing it (a scene's transform) and refusing what no technique can draw. The file readers that make
one are vdmbake.assets.meshes."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError


@dataclass
class SurfaceFrame:
    """Per-vertex differential geometry for mapping mesostructure onto a surface (Wang2003 §3.2):
    the texture tangents and the principal curvatures and directions."""
    dpdu: np.ndarray    # (V, 3) world-space derivative of position along texture u
    dpdv: np.ndarray    # (V, 3) ... along texture v
    k1: np.ndarray      # (V,) principal curvature along d1, 1 / world units, > 0 where the surface
    k2: np.ndarray      # (V,) ... along d2 = normal x d1      bends away from its normal (convex)
    d1: np.ndarray      # (V, 3) unit principal direction of k1

    @staticmethod
    def concatenate(parts: list["SurfaceFrame"]) -> "SurfaceFrame":
        return SurfaceFrame(*(np.concatenate([getattr(p, f) for p in parts])
                              for f in ("dpdu", "dpdv", "k1", "k2", "d1")))


@dataclass
class TriMesh:
    vertices: np.ndarray            # (V, 3) float64
    faces: np.ndarray               # (F, 3) int64, counter-clockwise seen from outside
    normals: np.ndarray             # (V, 3) float64, unit
    uvs: np.ndarray | None = None   # (V, 2) float64
    frame: SurfaceFrame | None = None
    colors: np.ndarray | None = None   # (V, 3) linear RGB albedo per vertex (the asset's own), or None
    texture: np.ndarray | None = None  # the asset's albedo map (vdmbake.common.texture: (H, W, 3) uint8 sRGB, row 0
                                       # at v = 0), read at `uvs`; None where it has none
    file_normals: bool = False         # normals the asset file gives (glTF NORMAL), which coarse levels follow

    @staticmethod
    def concatenate(parts: list["TriMesh"]) -> "TriMesh":
        offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
        uvs, frames, colors = [p.uvs for p in parts], [p.frame for p in parts], [p.colors for p in parts]
        return TriMesh(np.concatenate([p.vertices for p in parts]),
                       np.concatenate([p.faces + o for p, o in zip(parts, offsets)]),
                       np.concatenate([p.normals for p in parts]),
                       None if any(u is None for u in uvs) else np.concatenate(uvs),
                       None if any(f is None for f in frames) else SurfaceFrame.concatenate(frames),
                       None if any(c is None for c in colors) else np.concatenate(colors),
                       parts[0].texture if all(p.texture is parts[0].texture for p in parts) else None,
                       any(p.file_normals for p in parts))

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """Centre of the bounding box and the radius that encloses every vertex (infinite, without a warning,
        for a mesh too large to measure: parts.check_extent refuses it)."""
        centre = middle(self.vertices)
        with np.errstate(over="ignore", invalid="ignore"):
            return centre, float(np.linalg.norm(self.vertices - centre, axis=1).max())


def middle(vertices: np.ndarray) -> np.ndarray:
    """The centre of the vertices' bounding box, each bound halved before they are summed (halving is exact, so the
    same bits as halving their sum): finite for any finite vertices, where a file may place them at 1e308 (refused
    by their extent, parts.check_extent, without an overflow warning printed first)."""
    return 0.5 * vertices.min(0) + 0.5 * vertices.max(0)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (the sum of the incident faces' cross products)."""
    tri = vertices[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    # A vertex used only by degenerate faces has no normal; give it +Z rather than NaN.
    return np.where(length > 0, n / np.where(length > 0, length, 1.0), [0.0, 0.0, 1.0])


def crease_normals(vertices: np.ndarray, faces: np.ndarray, crease_deg: float = 60.0):
    """Vertex normals that keep sharp edges sharp: at each corner of a face, the area-weighted sum of the
    normals of the faces around its vertex that turn less than `crease_deg` from that face (a smoothing
    group, as DCC tools' auto-smooth); a vertex whose corners get different normals is split. Returns
    vertices, faces, normals and, per output vertex, the input vertex it copies."""
    tri = vertices[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(fn, axis=1, keepdims=True)
    unit = fn / np.maximum(area, 1e-300)
    corner_v = faces.ravel()
    corner_f = np.repeat(np.arange(len(faces)), 3)
    order = np.argsort(corner_v, kind="stable")
    sv, sf = corner_v[order], corner_f[order]
    start = np.searchsorted(sv, sv, side="left")
    count = np.searchsorted(sv, sv, side="right") - start
    # every pair (corner, corner of the same vertex): a corner's group is the faces within the crease angle
    a = np.repeat(np.arange(len(sv)), count)
    b = start[a] + (np.arange(len(a)) - np.repeat(np.cumsum(count) - count, count))
    # a face without area has no direction: it joins every group around its vertices
    flat = area[:, 0] <= 0
    near = (np.einsum("ij,ij->i", unit[sf[a]], unit[sf[b]]) >= np.cos(np.radians(crease_deg))) | flat[sf[a]] | flat[sf[b]]
    n = np.zeros((len(sv), 3))
    np.add.at(n, a[near], fn[sf[b[near]]])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 0, n / np.where(length > 0, length, 1.0), [0.0, 0.0, 1.0])
    corner_n = np.empty_like(n)
    corner_n[order] = n
    key = np.column_stack([corner_v, np.round(corner_n * 1e6)])
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return vertices[corner_v[first]], inv.reshape(-1, 3), corner_n[first], corner_v[first]


def weld(vertices: np.ndarray, rel_tol: float = 1e-9) -> np.ndarray:
    """(V,) int64 position ids: vertices within rel_tol of the bounding radius share an id (they are one
    point of the surface, split only for their texture coordinates, e.g. at a UV seam). Ids are
    numbered in order of first appearance, so the first vertex of each id can stand for it."""
    centre = middle(vertices)
    scale = max(float(np.abs(vertices - centre).max()), 1e-300) * rel_tol
    _, first, inv = np.unique(np.round((vertices - centre) / scale), axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return rank[inv.ravel()]


def rotation_xyz(degrees) -> np.ndarray:
    """Rotation about X, then Y, then Z (extrinsic), angles in degrees."""
    ax, ay, az = np.radians(degrees)
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def transformed(mesh: TriMesh, transform) -> TriMesh:
    """Scale, rotate, translate (a scene Transform); normals by the inverse transpose, re-normalised."""
    m = rotation_xyz(transform.rotate_deg) @ np.diag(transform.scale)
    n = mesh.normals @ np.linalg.inv(m)  # row vectors: n' = (M^-T n)^T = n^T M^-1
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    faces = mesh.faces if np.linalg.det(m) > 0 else mesh.faces[:, ::-1].copy()  # a mirror flips winding
    frame = None
    sx, sy, sz = transform.scale
    if mesh.frame is not None and sx == sy == sz:   # a non-uniform scale changes curvatures otherwise: dropped
        f = mesh.frame
        frame = SurfaceFrame(f.dpdu @ m.T, f.dpdv @ m.T, f.k1 / sx, f.k2 / sx, f.d1 @ rotation_xyz(transform.rotate_deg).T)
    return TriMesh(mesh.vertices @ m.T + np.asarray(transform.translate), faces, n, mesh.uvs, frame, mesh.colors,
                   mesh.texture, mesh.file_normals)


def validate(mesh: TriMesh, origin: str) -> TriMesh:
    """Reject what no technique can render: no faces, non-finite data, bad indices."""
    if len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise InputError(f"{origin}: the mesh is empty ({len(mesh.vertices)} vertices, {len(mesh.faces)} faces); "
                         "a mesh needs at least one triangle.")
    bad = ~np.isfinite(mesh.vertices).all(1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{origin}: {int(bad.sum())} vertices have NaN or Inf coordinates "
                         f"(first: vertex {i} = {mesh.vertices[i].tolist()}); every coordinate must be finite.")
    if mesh.faces.min() < 0 or mesh.faces.max() >= len(mesh.vertices):
        raise InputError(f"{origin}: face indices reach {int(mesh.faces.max())} but the mesh has "
                         f"{len(mesh.vertices)} vertices.")
    # Nothing to draw: every vertex at one point, or every face without area (collinear corners).
    v = mesh.vertices - middle(mesh.vertices)
    r = float(np.abs(v).max())
    tri = v[mesh.faces] / (r or 1.0)
    if r == 0 or not (np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) > 1e-12).any():
        raise InputError(f"{origin}: the mesh has no area (every vertex at one point, or every face a line); "
                         "nothing of it could be drawn.")
    return mesh
