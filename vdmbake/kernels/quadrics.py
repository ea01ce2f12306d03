"""Quadric lists: spheres and capped cylinders (atoms and bonds), for per-pixel ray casting.

Nothing is ray cast at bake time (dePoel2009 §3): the bake only parses,
transforms, drops what has no volume, computes bounds, and stores the lists as PLY
elements `sphere` (x y z radius red green blue) and `cylinder` (x0 y0 z0 x1 y1 z1 radius
red green blue), positions in float64.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..formats import ply
from ..errors import InputError
from ..common.mesh import rotation_xyz

_XYZ = [(n, "<f8") for n in "xyz"]
_RGB = [(n, "<f4") for n in ("red", "green", "blue")]
_SPHERE = np.dtype(_XYZ + [("radius", "<f8")] + _RGB)
_CYLINDER = np.dtype([(n, "<f8") for n in ("x0", "y0", "z0", "x1", "y1", "z1", "radius")] + _RGB)


@dataclass
class QuadricSet:
    spheres: np.ndarray        # (N, 4) float64: x, y, z, radius
    sphere_rgb: np.ndarray     # (N, 3) float32 linear RGB albedo
    cylinders: np.ndarray      # (M, 7) float64: x0, y0, z0, x1, y1, z1, radius
    cylinder_rgb: np.ndarray   # (M, 3) float32

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """Centre of the bounding box of every quadric and a radius enclosing them all (infinite, without a
        warning, for quadrics too far out to measure: parts.check_extent refuses them)."""
        s, c = self.spheres, self.cylinders
        with np.errstate(over="ignore", invalid="ignore"):
            lo = np.concatenate([s[:, :3] - s[:, 3:], c[:, :3] - c[:, 6:], c[:, 3:6] - c[:, 6:]]).min(0)
            hi = np.concatenate([s[:, :3] + s[:, 3:], c[:, :3] + c[:, 6:], c[:, 3:6] + c[:, 6:]]).max(0)
            centre = 0.5 * (lo + hi)
            reach = np.concatenate([np.linalg.norm(s[:, :3] - centre, axis=1) + s[:, 3],
                                    np.linalg.norm(c[:, :3] - centre, axis=1) + c[:, 6],
                                    np.linalg.norm(c[:, 3:6] - centre, axis=1) + c[:, 6]])
        return centre, float(reach.max())


    def instances(self, anchor) -> tuple[np.ndarray, np.ndarray]:
        """Per-instance float32 rows for the GPU, positions relative to `anchor`:
        spheres (x, y, z, radius, r, g, b), cylinders (x0, y0, z0, x1, y1, z1, radius, r, g, b)."""
        s = np.concatenate([self.spheres[:, :3] - anchor, self.spheres[:, 3:], self.sphere_rgb], 1)
        c = np.concatenate([self.cylinders[:, :3] - anchor, self.cylinders[:, 3:6] - anchor,
                            self.cylinders[:, 6:], self.cylinder_rgb], 1)
        return s.astype(np.float32), c.astype(np.float32)


def inline(spheres, cylinders, albedo) -> QuadricSet:
    """Quadrics listed in the scene, all with the object's material albedo."""
    s = np.asarray(spheres, np.float64).reshape(-1, 4)
    c = np.asarray(cylinders, np.float64).reshape(-1, 7)
    rgb = np.asarray(albedo, np.float32)
    return QuadricSet(s, np.tile(rgb, (len(s), 1)), c, np.tile(rgb, (len(c), 1)))


def transformed(q: QuadricSet, transform, origin: str) -> QuadricSet:
    """Uniform scale, rotation, translation (a non-uniform scale would make ellipsoids: refused)."""
    sx, sy, sz = transform.scale
    if not (sx == sy == sz):
        raise InputError(f"{origin}: transform.scale {list(transform.scale)} is not uniform; spheres and "
                         "cylinders need one scale factor (e.g. scale = 2.0).")
    m = rotation_xyz(transform.rotate_deg) * sx
    t = np.asarray(transform.translate)
    s, c = q.spheres.copy(), q.cylinders.copy()
    s[:, :3] = s[:, :3] @ m.T + t
    s[:, 3] *= sx
    c[:, :3], c[:, 3:6] = c[:, :3] @ m.T + t, c[:, 3:6] @ m.T + t
    c[:, 6] *= sx
    return QuadricSet(s, q.sphere_rgb, c, q.cylinder_rgb)


def cleaned(q: QuadricSet, origin: str) -> tuple[QuadricSet, dict]:
    """Drop what has no volume (zero radius, zero-length cylinders: they cover no pixel of the
    reference either) and count it; refuse non-finite data and an empty result."""
    for name, a in (("spheres", q.spheres), ("cylinders", q.cylinders)):
        if not np.isfinite(a).all():
            raise InputError(f"{origin}: {name} hold NaN or Inf values; every coordinate and radius must be finite.")
    keep_s = q.spheres[:, 3] > 0
    length = np.linalg.norm(q.cylinders[:, 3:6] - q.cylinders[:, :3], axis=1)
    keep_c = (q.cylinders[:, 6] > 0) & (length > 0)
    out = QuadricSet(q.spheres[keep_s], q.sphere_rgb[keep_s], q.cylinders[keep_c], q.cylinder_rgb[keep_c])
    if len(out.spheres) + len(out.cylinders) == 0:
        raise InputError(f"{origin}: no sphere or cylinder with a positive radius and length to draw.")
    return out, {"spheres_dropped": int((~keep_s).sum()), "cylinders_dropped": int((~keep_c).sum())}


def to_bytes(q: QuadricSet) -> bytes:
    s = np.zeros(len(q.spheres), _SPHERE)
    for k, n in enumerate(("x", "y", "z", "radius")):
        s[n] = q.spheres[:, k]
    c = np.zeros(len(q.cylinders), _CYLINDER)
    for k, n in enumerate(("x0", "y0", "z0", "x1", "y1", "z1", "radius")):
        c[n] = q.cylinders[:, k]
    for a, rgb in ((s, q.sphere_rgb), (c, q.cylinder_rgb)):
        a["red"], a["green"], a["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    return ply.elements_to_bytes({"sphere": s, "cylinder": c}, "vdmbake quadrics")


def from_bytes(data: bytes, origin: str) -> QuadricSet:
    e = ply.elements_from_bytes(data, origin)
    if set(e) != {"sphere", "cylinder"}:
        raise InputError(f"{origin}: expected PLY elements sphere and cylinder, found {sorted(e)}.")
    s, c = e["sphere"], e["cylinder"]

    def cols(a, names, dt):
        return np.stack([a[n] for n in names], 1).astype(dt).reshape(len(a), len(names))
    rgb = ("red", "green", "blue")
    return QuadricSet(cols(s, ("x", "y", "z", "radius"), np.float64), cols(s, rgb, np.float32),
                      cols(c, ("x0", "y0", "z0", "x1", "y1", "z1", "radius"), np.float64), cols(c, rgb, np.float32))
