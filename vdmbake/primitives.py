"""Built-in primitives with analytic normals and UVs (pure numpy).

Sphere, cylinder, torus and vase are surfaces of revolution about +Z: a profile
(r(t), z(t)), t in [0, 1], swept by the angle phi. With P = (r cos phi, r sin phi, z),
dP/dphi x dP/dt = r (z' cos phi, z' sin phi, -r'), so the unit normal is
(z' cos phi, z' sin phi, -r') / |(r', z')|, exact at every vertex, poles included.
UVs: u = phi / 2pi (the seam column is duplicated), v = t. Every texture map is right-handed seen
from outside ((dP/du x dP/dv) . n > 0), as standard (OBJ / glTF) UVs are: a picture lands upright and
unmirrored, v = 1 at its top (vdmbake.heightfields flips image rows to that convention).
Principal curvatures are analytic too (do Carmo, sec. 3-3, surfaces of revolution): along the
parallel k_p = z' / (r |(r', z')|), along the meridian k_m = (r' z'' - z' r'') / |(r', z')|^3,
positive where the surface bends away from its normal; at a pole (r = 0) k_p takes the limit k_m.
"""
from __future__ import annotations

import numpy as np

from .meshes import SurfaceFrame, TriMesh, subdivide


def _grid_faces(rows: int, cols: int) -> np.ndarray:
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
    return TriMesh(v, _grid_faces(rings, segments), n, uv, frame)


def _disk(radius: float, z: float, segments: int, up: bool) -> TriMesh:
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)[:-1]
    v = np.concatenate([[[0.0, 0.0, z]], np.stack([radius * np.cos(phi), radius * np.sin(phi), np.full_like(phi, z)], 1)])
    k = np.arange(segments)
    f = np.stack([np.zeros_like(k), 1 + k, 1 + (k + 1) % segments], 1)
    if not up:
        f = f[:, ::-1]
    n = np.tile([0.0, 0.0, 1.0 if up else -1.0], (len(v), 1))
    mirror = 1.0 if up else -1.0            # seen from below, u runs along -X so the picture is not mirrored
    uv = 0.5 + 0.5 * v[:, :2] / radius * [mirror, 1.0]
    return TriMesh(v, f.astype(np.int64), n, uv, _flat_frame(len(v), 2 * radius, mirror))


def _flat_frame(count: int, size: float, u_sign: float = 1.0) -> SurfaceFrame:
    """A planar patch: u along u_sign * X, v along +Y, no curvature."""
    zero = np.zeros(count)
    return SurfaceFrame(np.tile([u_sign * size, 0.0, 0.0], (count, 1)), np.tile([0.0, size, 0.0], (count, 1)),
                        zero, zero.copy(), np.tile([u_sign, 0.0, 0.0], (count, 1)))


def plane(size: float, segments: int) -> TriMesh:
    """A square in the XY plane centred on the origin, normal +Z."""
    u = np.linspace(0.0, 1.0, segments + 1)
    V, U = np.meshgrid(u, u, indexing="ij")
    v = np.stack([(U - 0.5) * size, (V - 0.5) * size, np.zeros_like(U)], -1).reshape(-1, 3)
    n = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    return TriMesh(v, _grid_faces(segments, segments), n, np.stack([U, V], -1).reshape(-1, 2),
                   _flat_frame(len(v), size))


def sphere(radius: float, segments: int, rings: int) -> TriMesh:
    a = np.pi
    return revolve(lambda t: (radius * np.sin(a * t), -radius * np.cos(a * t),
                              radius * a * np.cos(a * t), radius * a * np.sin(a * t),
                              -radius * a * a * np.sin(a * t), radius * a * a * np.cos(a * t)), segments, rings)


def cylinder(radius: float, height: float, segments: int, rings: int, caps: int) -> TriMesh:
    side = revolve(lambda t: (radius, (t - 0.5) * height, 0.0, height, 0.0, 0.0), segments, rings)
    if not caps:
        return side
    return TriMesh.concatenate([side, _disk(radius, -0.5 * height, segments, False),
                                _disk(radius, 0.5 * height, segments, True)])


def cone(radius: float, height: float, segments: int, rings: int, caps: int) -> TriMesh:
    """A right circular cone on the XY plane's centre, apex up (+Z), closed by a base disk if caps."""
    side = revolve(lambda t: (radius * (1.0 - t), (t - 0.5) * height, -radius, height, 0.0, 0.0), segments, rings)
    return side if not caps else TriMesh.concatenate([side, _disk(radius, -0.5 * height, segments, False)])


def torus(major: float, minor: float, segments: int, rings: int) -> TriMesh:
    a = 2.0 * np.pi
    return revolve(lambda t: (major + minor * np.cos(a * t), minor * np.sin(a * t),
                              -minor * a * np.sin(a * t), minor * a * np.cos(a * t),
                              -minor * a * a * np.cos(a * t), -minor * a * a * np.sin(a * t)), segments, rings)


def vase(radius: float, height: float, segments: int, rings: int) -> TriMesh:
    """An open vase: r(t) = R (1 + 0.45 sin(1.6 pi t + 0.35) - 0.35 t), a belly, a neck and a lip."""
    w = 1.6 * np.pi
    return revolve(lambda t: (radius * (1.0 + 0.45 * np.sin(w * t + 0.35) - 0.35 * t), height * t,
                              radius * (0.45 * w * np.cos(w * t + 0.35) - 0.35), height,
                              -radius * 0.45 * w * w * np.sin(w * t + 0.35), 0.0), segments, rings)


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


BUILDERS = {"plane": plane, "sphere": sphere, "cylinder": cylinder, "cone": cone, "torus": torus, "vase": vase}


def build(name: str, params: dict) -> TriMesh:
    return BUILDERS[name](**params)
