"""Pure geometry shared by the bake and the renderer (numpy, no I/O, no GL): orthonormal frames,
midpoint subdivision, surfaces of revolution, the icosphere, periodic bilinear sampling of a
height field, and conventional displacement mapping (Cook 1984), which is both the `displaced`
technique (baked at a few levels) and, subdivided to half-texel edges, the truly displaced
geometry the mesostructure reference traces (the reference of docs/architecture.md §1 step 4).
"""
from __future__ import annotations

import numpy as np

from . import texspace
from .mesh import SurfaceFrame, TriMesh, weld


def onb(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors u, v completing the unit vectors w (N, 3) to right-handed orthonormal frames
    (u, v, w), branch-free and stable for every direction (Duff et al. 2017, "Building an Orthonormal
    Basis, Revisited"). GLSL twin: shaders/include/frame.glsl."""
    x, y, z = w[:, 0], w[:, 1], w[:, 2]
    s = np.where(z >= 0, 1.0, -1.0)
    a = -1.0 / (s + z)
    b = x * y * a
    return np.stack([1.0 + s * x * x * a, s * b, -s * x], 1), np.stack([b, s + y * y * a, -y], 1)


def subdivide(faces: np.ndarray, attrs: dict[str, np.ndarray]) -> tuple[np.ndarray, dict]:
    """One level of midpoint subdivision (every triangle into four) of per-vertex attributes,
    interpolated linearly ("normal" renormalised). Shared edges get one midpoint, so the mesh
    stays watertight. An integer "weld" attribute (position ids, see weld) is carried exactly: a
    midpoint gets the id of its edge's end ids, so the two copies of an edge split at a UV seam
    give midpoints with the same id (and, from bit-identical ends, the same position)."""
    n = len(attrs["pos"])
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1).astype(np.int64)
    keys, inv = np.unique(e[:, 0] * n + e[:, 1], return_inverse=True)   # an edge's key orders as its (a, b) row
    a, b = np.divmod(keys, n)
    out = {k: np.concatenate([v, 0.5 * (v[a] + v[b])]) for k, v in attrs.items() if k != "weld"}
    out["normal"] /= np.maximum(np.linalg.norm(out["normal"], axis=1, keepdims=True), 1e-300)
    if "weld" in attrs:
        w = attrs["weld"]
        top = int(w.max()) + 1
        _, mid = np.unique(np.minimum(w[a], w[b]) * top + np.maximum(w[a], w[b]), return_inverse=True)  # one key per edge
        out["weld"] = np.concatenate([w, top + mid.ravel()])
    m = n + inv.reshape(3, -1).T                          # midpoints of edges 01, 12, 20 per face
    f = np.concatenate([np.stack([faces[:, 0], m[:, 0], m[:, 2]], 1), np.stack([faces[:, 1], m[:, 1], m[:, 0]], 1),
                        np.stack([faces[:, 2], m[:, 2], m[:, 1]], 1), m])
    return f, out


# Surfaces of revolution about +Z: a profile (r(t), z(t)), t in [0, 1], swept by the angle phi. With
# P = (r cos phi, r sin phi, z), dP/dphi x dP/dt = r (z' cos phi, z' sin phi, -r'), so the unit normal
# is (z' cos phi, z' sin phi, -r') / |(r', z')|, exact at every vertex, poles included. UVs:
# u = phi / 2pi (the seam column is duplicated), v = t; every texture map is right-handed seen from outside
# ((dP/du x dP/dv) . n > 0), as standard (OBJ / glTF) UVs are, so a picture lands upright and unmirrored,
# v = 1 at its top (vdmbake.assets.heightfields flips image rows to that convention). Principal curvatures (do Carmo, sec. 3-3):
# along the parallel k_p = z' / (r |(r', z')|), along the meridian k_m = (r' z'' - z' r'') / |(r', z')|^3,
# positive where the surface bends away from its normal; at a pole (r = 0) k_p takes the limit k_m.

def grid_faces(rows: int, cols: int) -> np.ndarray:
    """Two counter-clockwise triangles per cell of a (rows+1) x (cols+1) vertex grid."""
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = (i * (cols + 1) + j).ravel()
    b, c, d = a + 1, a + cols + 1, a + cols + 2
    return np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]).astype(np.int64)


def revolve(profile, segments: int, rings: int) -> TriMesh:
    """Sweep profile(t) -> (r, z, r', z', r'', z'') around +Z; rings along t, segments along phi."""
    t = np.linspace(0.0, 1.0, rings + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    ring = np.repeat(np.arange(rings + 1), segments + 1)            # each vertex's ring (row-major grid)
    r, z, dr, dz, ddr, ddz = (np.broadcast_to(np.asarray(a, float), t.shape)[ring] for a in profile(t))
    P = np.tile(phi, rings + 1)
    c, s = np.cos(P), np.sin(P)
    speed = np.hypot(dr, dz)                                     # |dP/dt|
    v = np.stack([r * c, r * s, z], -1)
    n = np.stack([dz * c, dz * s, -dr], -1) / speed[:, None]
    uv = np.stack([P / (2 * np.pi), t[ring]], -1)
    k_m = (dr * ddz - dz * ddr) / speed ** 3
    with np.errstate(divide="ignore", invalid="ignore"):
        k_p = np.where(r > 1e-12 * speed, dz / (r * speed), k_m)
    parallel = np.stack([-s, c, np.zeros_like(c)], -1)
    frame = SurfaceFrame(dpdu=2 * np.pi * r[:, None] * parallel,
                         dpdv=np.stack([dr * c, dr * s, dz], -1), k1=k_p, k2=k_m, d1=parallel)
    return TriMesh(v, grid_faces(rings, segments), n, uv, frame)


def disk(radius: float, z: float, segments: int, up: bool) -> TriMesh:
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)[:-1]
    v = np.concatenate([[[0.0, 0.0, z]], np.stack([radius * np.cos(phi), radius * np.sin(phi), np.full_like(phi, z)], 1)])
    k = np.arange(segments)
    f = np.stack([np.zeros_like(k), 1 + k, 1 + (k + 1) % segments], 1)
    if not up:
        f = f[:, ::-1]
    n = np.tile([0.0, 0.0, 1.0 if up else -1.0], (len(v), 1))
    mirror = 1.0 if up else -1.0            # seen from below, u runs along -X so the picture is not mirrored
    uv = 0.5 + 0.5 * v[:, :2] / radius * [mirror, 1.0]
    return TriMesh(v, f.astype(np.int64), n, uv, flat_frame(len(v), 2 * radius, mirror))


def flat_frame(count: int, size: float, u_sign: float = 1.0) -> SurfaceFrame:
    """A planar patch: u along u_sign * X, v along +Y, no curvature."""
    zero = np.zeros(count)
    return SurfaceFrame(np.tile([u_sign * size, 0.0, 0.0], (count, 1)), np.tile([0.0, size, 0.0], (count, 1)),
                        zero, zero.copy(), np.tile([u_sign, 0.0, 0.0], (count, 1)))


def cylinder(radius: float, height: float, segments: int, rings: int, caps: int) -> TriMesh:
    """A cylinder about Z centred on the origin, closed by two disks if caps (the `cylinder` primitive,
    and at radius 1, height 2 the tessellated quadrics' prism)."""
    side = revolve(lambda t: (radius, (t - 0.5) * height, 0.0, height, 0.0, 0.0), segments, rings)
    if not caps:
        return side
    return TriMesh.concatenate([side, disk(radius, -0.5 * height, segments, False),
                                disk(radius, 0.5 * height, segments, True)])


def icosphere(level: int) -> TriMesh:
    """The unit sphere as an icosahedron subdivided `level` times (20 * 4^level faces), normals radial."""
    g = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, g, 0], [1, g, 0], [-1, -g, 0], [1, -g, 0], [0, -1, g], [0, 1, g],
                  [0, -1, -g], [0, 1, -g], [g, 0, -1], [g, 0, 1], [-g, 0, -1], [-g, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(level):   # midpoints pushed out to the sphere: on the unit sphere position = normal
        f, a = subdivide(f, {"pos": v, "normal": v})
        v = a["normal"]
    return TriMesh(v, f.astype(np.int64), v.copy())


def sample(h: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Periodic bilinear interpolation of texel-centre samples at tile coordinates uv (..., 2)
    (u along columns, v along rows): the surface the VDM bake's mesostructure mesh spans."""
    n = h.shape[0]
    x, y = uv[..., 0] * n - 0.5, uv[..., 1] * n - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    i0, j0 = y0.astype(np.int64) % n, x0.astype(np.int64) % n
    i1, j1 = (i0 + 1) % n, (j0 + 1) % n
    return ((1 - fy) * ((1 - fx) * h[i0, j0] + fx * h[i0, j1]) + fy * ((1 - fx) * h[i1, j0] + fx * h[i1, j1]))


def edge_texels(mesh: TriMesh, size: int, tiling) -> float:
    """The longest base-mesh edge, measured in height-field texels of the tiled UVs."""
    d = mesh.uvs[mesh.faces] - mesh.uvs[np.roll(mesh.faces, 1, axis=1)]
    return float(np.abs(d * np.asarray(tiling) * size).max())


def reference_levels(mesh: TriMesh, size: int, tiling) -> int:
    """Subdivision levels that bring every edge under half a texel (the reference's displaced mesh)."""
    # a relative hair below each power of two: an edge of 8 + 4e-14 texels takes 4 levels, not 5 (4x the faces)
    return max(0, int(np.ceil(np.log2(max(edge_texels(mesh, size, tiling), 1e-9) / 0.5) - 1e-9)))


def displaced(mesh: TriMesh, heights: np.ndarray, normals: np.ndarray, depth: float, tiling, levels: int) -> TriMesh:
    """The base mesh (with UVs and frame) midpoint-subdivided `levels` times, linearly over its facets
    (it is the reference surface every mesostructure technique starts from), carrying the
    interpolated normal, UV and texture tangents; each vertex moves inward by depth * s_n * (1 - h)
    against its normal. Seams live in the texture coordinates only: vertices split for their UVs are
    welded by position first (mesh.weld), take one position and one normal, and move by the mean of
    their copies' displacements (equal where the height field is continuous across the seam), so the
    displaced surface has no cracks. The shading normals are those every per-pixel technique uses: the
    mesostructure's texture-space normals `normals` (MesostructureMaps) mapped through the
    interpolated frame, so the comparison measures geometry, not a different normal. The texture
    coordinates are the base mesh's, interpolated (the tile albedo is read at them times `tiling`)."""
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
    amount = depth * texspace.normal_scale(J) * (1.0 - sample(np.asarray(heights, np.float64), T))
    w = a["weld"]
    amount = (np.bincount(w, amount) / np.bincount(w))[w]   # the copies of a seam vertex move together
    moved = a["pos"] - a["normal"] * amount[:, None]
    n_tex = np.stack([sample(np.asarray(c, np.float64), T) for c in np.moveaxis(normals, -1, 0)], -1)
    return TriMesh(moved, f, texspace.world_normals(J, a["normal"], n_tex), a["uv"])


# Open boundaries (Wang2003 §5: "VDMs will be extended to model open surface boundaries, which are not
# handled in our current implementation"). The mesostructure fills a shell under the base surface, down
# to depth * s_n; on a closed surface the shell has no sides. Where the base surface has a border (a
# plane, an open mesh) the shell is open there, and what a view sees through that side is modelled by no
# per-pixel method (they all start their rays on the base surface), while the displaced reference sheet
# shows its cut edge and, from behind, its underside. The side wall, the `skirt`, is every border edge
# swept from the base surface to the shell's floor; vdmrender/tracing/borders.py scores the pixels that see it
# apart from the surface. Borders are found on the surface, not on its UV charts (welded by position),
# so a UV seam is never a border.

def boundary_edges(faces: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """(E, 2) vertex index pairs of the edges used by exactly one face, keyed by the position ids
    `ids` (mesh.weld), in their face's winding order (so the surface lies to the left)."""
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
