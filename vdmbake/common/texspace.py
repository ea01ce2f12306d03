"""The map between world space and mesostructure texture space, per vertex (Wang2003 §3.2).

A tile of the height field spans 1 x 1 texture units. Near a surface point the map from texture
space to world space is affine: M = [J | s_n N], J = [dP/du / tiling_u, dP/dv / tiling_v] (3 x 2,
world length per tile along u and v) and s_n = sqrt(|J_u x J_v|), the geometric-mean tile size,
so the world depth of the mesostructure is depth * s_n. The VDM tables hold an isotropic
mesostructure; ray casting commutes with affine maps, so a world ray is looked up by mapping it
into texture space: V_tex = (J+ V_t, (V . N) / s_n), J+ = (J^T J)^-1 J^T, V_t the tangential part.

Curvature in texture units along a unit texture direction e: the surface z = II(x) / 2 in world
tangent coordinates becomes z_t = II(J e, J e) t^2 / (2 s_n) with x = J e t, so
c(e) = II(J e, J e) / s_n, II(x, x) = k1 (x . d1)^2 + k2 (x . d2)^2 (Euler). This is the paper's
c_V = (c_max (V . C_max)^2 + c_min (V . C_min)^2) / (1 - (V . N)^2) for an isometric map, written
without its 0/0 at V = N: e is taken first, and any e will do when V has no tangential part.
shaders/include/mesostructure.glsl is the GLSL twin of these functions.
"""
from __future__ import annotations

import numpy as np

from .mesh import SurfaceFrame


def jacobian(frame: SurfaceFrame, tiling) -> np.ndarray:
    """(V, 3, 2): world length per tile along texture u and v."""
    return np.stack([frame.dpdu / tiling[0], frame.dpdv / tiling[1]], -1)


def normal_scale(J: np.ndarray) -> np.ndarray:
    """(V,) s_n = sqrt(|J_u x J_v|): the world length of one texture unit of depth."""
    return np.sqrt(np.linalg.norm(np.cross(J[..., 0], J[..., 1]), axis=-1))


def world_normals(J: np.ndarray, N: np.ndarray, n_tex: np.ndarray) -> np.ndarray:
    """(V, 3) unit world normals of texture-space normals n_tex (V, 3): M^-T n = J+^T n_xy + N n_z / s_n
    (J in the tangent plane of the unit normals N)."""
    G = np.einsum("vki,vkj->vij", J, J)
    # clamped relative to |J|^4 (as surface_frame in mesostructure.glsl): scale-free, finite when degenerate
    det = np.maximum(G[:, 0, 0] * G[:, 1, 1] - G[:, 0, 1] ** 2, 1e-12 * (G[:, 0, 0] + G[:, 1, 1]) ** 2 + 1e-300)
    inv = np.stack([np.stack([G[:, 1, 1], -G[:, 0, 1]], -1), np.stack([-G[:, 0, 1], G[:, 0, 0]], -1)], -2) / det[:, None, None]
    pinv = np.einsum("vij,vkj->vik", inv, J)                  # (V, 2, 3): rows of J+
    n = np.einsum("vik,vi->vk", pinv, n_tex[:, :2]) + N * (n_tex[:, 2] / np.sqrt(np.sqrt(det)))[:, None]
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def texture_curvature(frame: SurfaceFrame, normals: np.ndarray, tiling, e: np.ndarray) -> np.ndarray:
    """(V, D) curvature in texture units along the unit texture directions e (D, 2) at every vertex;
    0 where the texture map is degenerate (e.g. at a pole)."""
    J = jacobian(frame, tiling)
    x = np.einsum("vij,dj->vdi", J, e)                       # world tangent vectors J e
    d2 = np.cross(normals, frame.d1)
    ii = frame.k1[:, None] * np.einsum("vdi,vi->vd", x, frame.d1) ** 2 \
        + frame.k2[:, None] * np.einsum("vdi,vi->vd", x, d2) ** 2
    s = normal_scale(J)[:, None]
    # A (nearly) singular map, e.g. a pole where dP/du vanishes, has no texture-space curvature; the
    # same relative threshold as the GLSL twin's determinant clamp (|J_u x J_v|^2 vs (|J_u|^2 + |J_v|^2)^2).
    scale2 = (np.einsum("vi,vi->v", J[..., 0], J[..., 0]) + np.einsum("vi,vi->v", J[..., 1], J[..., 1]))[:, None]
    ok = s ** 4 > 1e-12 * scale2 ** 2
    return np.where(ok, ii / np.where(ok, s, 1.0), 0.0)


def curvature_range(frame: SurfaceFrame, normals: np.ndarray, tiling, directions: int = 64) -> tuple[float, float]:
    """The range of texture-space curvature the surface has, over every vertex and direction: the
    only part of the curvature axis the VDM table needs (a plane gets the single value 0)."""
    a = np.arange(directions) * np.pi / directions           # c(e) = c(-e): half the circle suffices
    c = texture_curvature(frame, normals, tiling, np.stack([np.cos(a), np.sin(a)], 1))
    lo, hi = float(c.min()), float(c.max())
    return (0.0, 0.0) if max(abs(lo), abs(hi)) < 1e-9 else (lo, hi)
