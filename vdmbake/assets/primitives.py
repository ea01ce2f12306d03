"""Built-in primitives with analytic normals and UVs (pure numpy).

Sphere, cylinder, cone, torus and vase are surfaces of revolution about +Z (vdmbake.common.geometry.revolve,
which gives exact normals, UVs and principal curvatures from the profile); the plane is a grid; the
teapot is the Utah teapot's Bezier patches, tessellated by vdmbake.assets.teapot.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, is_dataclass

import numpy as np

from ..common.geometry import cylinder, disk, flat_frame, grid_faces, revolve
from ..common.mesh import TriMesh
from ..schema import Integer, Number, setting
from .teapot import teapot


def plane(size: float, segments: int) -> TriMesh:
    """A square in the XY plane centred on the origin, normal +Z."""
    u = np.linspace(0.0, 1.0, segments + 1)
    V, U = np.meshgrid(u, u, indexing="ij")
    v = np.stack([(U - 0.5) * size, (V - 0.5) * size, np.zeros_like(U)], -1).reshape(-1, 3)
    n = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    return TriMesh(v, grid_faces(segments, segments), n, np.stack([U, V], -1).reshape(-1, 2),
                   flat_frame(len(v), size))


def sphere(radius: float, segments: int, rings: int) -> TriMesh:
    a = np.pi
    return revolve(lambda t: (radius * np.sin(a * t), -radius * np.cos(a * t),
                              radius * a * np.cos(a * t), radius * a * np.sin(a * t),
                              -radius * a * a * np.sin(a * t), radius * a * a * np.cos(a * t)), segments, rings)


def cone(radius: float, height: float, segments: int, rings: int, caps: int) -> TriMesh:
    """A right circular cone on the XY plane's centre, apex up (+Z), closed by a base disk if caps."""
    side = revolve(lambda t: (radius * (1.0 - t), (t - 0.5) * height, -radius, height, 0.0, 0.0), segments, rings)
    return side if not caps else TriMesh.concatenate([side, disk(radius, -0.5 * height, segments, False)])


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


def _length(default: float, doc: str):
    return setting(default, Number(1e-9, 1e9), doc)


def _count(default: int, doc: str):
    return setting(default, Integer(1, 4096), doc)


# Each primitive's parameters (the scene's `params` table), lengths in scene units.
@dataclass(frozen=True)
class PlaneParams:
    size: float = _length(2.0, "side of the square")
    segments: int = _count(8, "grid cells per side")


@dataclass(frozen=True)
class SphereParams:
    radius: float = _length(1.0, "radius")
    segments: int = _count(96, "cells around the Z axis")
    rings: int = _count(48, "cells from pole to pole")


@dataclass(frozen=True)
class CylinderParams:
    radius: float = _length(0.5, "radius")
    height: float = _length(2.0, "height along Z, centred on the origin")
    segments: int = _count(96, "cells around the Z axis")
    rings: int = _count(8, "cells along Z")
    caps: int = setting(1, Integer(0, 1), "1: closed by two disks")


@dataclass(frozen=True)
class ConeParams:
    radius: float = _length(0.6, "base radius")
    height: float = _length(1.5, "height along Z, apex up")
    segments: int = _count(96, "cells around the Z axis")
    rings: int = _count(8, "cells along Z")
    caps: int = setting(1, Integer(0, 1), "1: closed by the base disk")


@dataclass(frozen=True)
class TorusParams:
    major: float = _length(1.0, "radius of the ring")
    minor: float = _length(0.35, "radius of the tube")
    segments: int = _count(128, "cells around the ring")
    rings: int = _count(64, "cells around the tube")


@dataclass(frozen=True)
class VaseParams:
    radius: float = _length(0.5, "radius at the foot")
    height: float = _length(2.0, "height along Z")
    segments: int = _count(96, "cells around the Z axis")
    rings: int = _count(64, "cells along the profile")


@dataclass(frozen=True)
class TeapotParams:
    size: float = _length(1.0, "height along Z (bottom at z = 0, spout along +X)")
    segments: int = setting(8, Integer(2, 512), "cells per side of each of its 32 Bezier patches (8: the "
                            "4032 triangles of the VDM paper's Fig. 9 teapot)")


# name -> (builder, parameters)
PRIMITIVES = {"plane": (plane, PlaneParams), "sphere": (sphere, SphereParams), "cylinder": (cylinder, CylinderParams),
              "cone": (cone, ConeParams), "torus": (torus, TorusParams), "vase": (vase, VaseParams),
              "teapot": (teapot, TeapotParams)}


def build(name: str, params) -> TriMesh:
    """The primitive `name` with its parameters (a *Params instance, or a dict of them)."""
    return PRIMITIVES[name][0](**(asdict(params) if is_dataclass(params) else params))
