"""Pinhole cameras (pure numpy): view and projection matrices, pixel rays, orbit placement.

Conventions: right-handed world, the camera looks down its -Z axis, vertical field of
view, pixel (x, y) has its centre at (x + 0.5, y + 0.5) with row 0 at the top of the image.
Near and far planes hug the object's bounding sphere, and the reference clips to the same
near plane as the rasteriser, so both see the same geometry.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vdmbake.common import instances


@dataclass(frozen=True)
class Camera:
    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov_deg: float
    width: int
    height: int
    near: float
    far: float

    def basis(self) -> np.ndarray:
        """Rows: camera right, up, back (+Z) in world space. Built as right = up x back, then
        up = back x right, so the frame is orthonormal to rounding even when `up` nearly
        parallels the view direction (subtracting the projection would cancel digits there)."""
        back = self.eye - self.target
        back = back / np.linalg.norm(back)
        right = np.cross(self.up, back)
        if np.linalg.norm(right) < 1e-12 * np.linalg.norm(self.up):  # looking along `up`: any perpendicular
            right = np.cross([1.0, 0.0, 0.0] if abs(back[0]) < 0.9 else [0.0, 1.0, 0.0], back)
        right = right / np.linalg.norm(right)
        return np.stack([right, np.cross(back, right), back])

    def view(self) -> np.ndarray:
        r = self.basis()
        m = np.eye(4)
        m[:3, :3] = r
        m[:3, 3] = -r @ self.eye
        return m

    def projection(self) -> np.ndarray:
        f = 1.0 / np.tan(np.radians(self.fov_deg) / 2)
        n, fa, a = self.near, self.far, self.width / self.height
        return np.array([[f / a, 0, 0, 0], [0, f, 0, 0],
                         [0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)], [0, 0, -1, 0]])

    def pixel_rays(self, offset: np.ndarray | None = None,
                   pixels: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """World-space directions through every pixel centre, scaled so that one unit of the ray
        parameter is one unit of view depth (camera-space z = -1); (H*W, 3) float64, row-major.
        offset: (H, W, 2) positions within each pixel, (x right, y down) in [0, 1), instead of its centre
        (the filtered reference's samples: reference.filtered). pixels: (P,) row-major pixel indices, a pixel
        as often as it is sampled: only their rays, (P, 3), offset then (P, 2)."""
        t = np.tan(np.radians(self.fov_deg) / 2)
        a = self.width / self.height
        if pixels is None:
            X, Y = np.meshgrid(np.arange(self.width, dtype=float), np.arange(self.height, dtype=float))
        else:
            Y, X = np.divmod(np.asarray(pixels), self.width)
            X, Y = X.astype(float), Y.astype(float)
        if offset is None:
            X, Y = X + 0.5, Y + 0.5
        else:
            X, Y = X + offset[..., 0], Y + offset[..., 1]
        X = (X / self.width * 2 - 1) * t * a
        Y = (1 - Y / self.height * 2) * t
        d_cam = np.stack([X, Y, -np.ones_like(X)], -1).reshape(-1, 3)
        # einsum, not @: a BLAS product of a frame's rays runs on BLAS's own threads, which spin against the
        # reference's (reference.filtered) and doubled its CPU time per frame
        return np.broadcast_to(self.eye, d_cam.shape), np.einsum("ij,jk->ik", d_cam, self.basis())


def pixel_ray(inv_view_proj: np.ndarray, viewport, frag_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ray through window positions frag_xy (N, 2) in pixels (GL's: origin at the bottom left)
    between the near and the far plane, p = near_point + s * segment, s in [0, 1]: (N, 3) each.
    Numpy twin of shaders/include/camera.glsl pixel_ray."""
    ndc = np.asarray(frag_xy, np.float64) / np.asarray(viewport, np.float64) * 2.0 - 1.0
    ends = []
    for z in (-1.0, 1.0):
        h = np.concatenate([ndc, np.full((len(ndc), 1), z), np.ones((len(ndc), 1))], 1) @ np.asarray(inv_view_proj).T
        ends.append(h[:, :3] / h[:, 3:])
    return ends[0], ends[1] - ends[0]


def window_depth(view_proj: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Window-space depth in [0, 1] of points p (N, 3) (default depth range). Numpy twin of
    shaders/include/camera.glsl window_depth."""
    c = np.concatenate([np.asarray(p, np.float64), np.ones((len(p), 1))], 1) @ np.asarray(view_proj).T
    return np.clip(0.5 + 0.5 * c[:, 2] / c[:, 3], 0.0, 1.0)


def clip_planes(eye, target, centre, radius) -> tuple[float, float]:
    """Near/far planes enclosing the bounding sphere along the view axis (near kept > 0)."""
    fwd = (target - eye) / np.linalg.norm(target - eye)
    depth = float(np.dot(centre - eye, fwd))
    far = depth + radius * 1.01
    near = max(depth - radius * 1.01, far * 1e-4)
    return near, max(far, near * 2)


def orbit(orbit_spec, up, centre, radius, width, height) -> list[Camera]:
    """`count` cameras evenly around `up` at a fixed elevation, looking at the centre."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    a = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = a - up * np.dot(a, up)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    cams = []
    el = np.radians(orbit_spec.elevation_deg)
    for k in range(orbit_spec.count):
        az = np.radians(orbit_spec.azimuth_deg) + 2 * np.pi * k / orbit_spec.count
        d = np.cos(el) * (np.cos(az) * e1 + np.sin(az) * e2) + np.sin(el) * up
        eye = centre + d * orbit_spec.distance * radius
        cams.append(Camera(eye, centre, up, orbit_spec.fov_deg, width, height,
                           *clip_planes(eye, centre, centre, radius)))
    return cams


def cameras_for(scene_camera, centre, radius, width, height) -> list[Camera]:
    """The scene's orbit cameras around this object, then its explicit poses."""
    centre = np.asarray(centre, float)
    cams = orbit(scene_camera.orbit, scene_camera.up, centre, radius, width, height) if scene_camera.orbit else []
    up = np.asarray(scene_camera.up, float)
    for p in scene_camera.poses:
        eye, target = np.asarray(p.eye, float), np.asarray(p.target, float)
        cams.append(Camera(eye, target, up, p.fov_deg, width, height, *clip_planes(eye, target, centre, radius)))
    return cams


def enclosing_sphere(centres, radii) -> tuple[np.ndarray, float]:
    """A sphere holding every given sphere (a composite frame's objects): centred on the box of the
    spheres, as large as the farthest sphere's surface from there. Not the smallest such sphere, but
    within a factor sqrt(3) of it, and one sphere comes back as itself."""
    c, r = np.atleast_2d(np.asarray(centres, float)), np.asarray(radii, float).ravel()
    centre = 0.5 * ((c - r[:, None]).min(0) + (c + r[:, None]).max(0))
    if len(r) == 1:
        return c[0].copy(), float(r[0])
    return centre, float((np.linalg.norm(c - centre, axis=1) + r).max())


def framed(obj, entry, scene) -> tuple[np.ndarray, float]:
    """The sphere an object's cameras frame (scene object `obj`, its manifest `entry`): its bounding sphere, or
    one holding every copy of it."""
    if not obj.instances:
        return np.asarray(entry["centre"], float), entry["radius"]
    return instances.enclosing(instances.matrices(obj.instances, scene.camera.up, entry["centre"]), entry["centre"],
                               entry["radius"])
