"""One renderer's frame and its score against the Embree reference of a mesh, shared by the GL tests of
the per-object techniques (billboards, octahedral impostors): one light, one material, one background; and the
billboard tests' models (baked once per process), cameras and frames."""
from __future__ import annotations

import numpy as np

from vdmbake.assets import primitives
from vdmbake.common.mesh import TriMesh
from vdmbake.kernels import billboard_maps, coarse
from vdmbake.kernels import billboards as bb
from vdmbake.scene import Light, Material
from vdmrender.gpu import gl
from vdmrender.common import images
from vdmrender.comparing import metrics
from vdmrender.tracing import reference
from vdmrender.common.camera import Camera, clip_planes
from vdmrender.techniques.billboards import Billboards

BG = (0.05, 0.05, 0.06)
LIGHT = Light()          # its direction normalised by the scene type
MATERIAL = Material()


def draw(r, camera) -> np.ndarray:
    """One frame of renderer r, which is released after."""
    target = gl.Target(r.ctx, camera.width, camera.height)
    try:
        r.render(camera, target)
        return target.read()
    finally:
        target.release()
        r.release()


def score(frame, mesh, camera) -> tuple[float, float]:
    """(mean dLuv, IoU) against the traced full mesh; every pixel must be finite."""
    assert np.isfinite(frame).all()
    ref = reference.MeshReference(mesh, LIGHT, MATERIAL).render(camera)
    m = metrics.compare(images.encode(frame, BG), images.encode(ref, BG))
    return m["mean"], m["iou"]


SHADOW = 512
MESHES = {"sphere": lambda: primitives.sphere(1.0, 64, 32), "torus": lambda: primitives.torus(1.0, 0.35, 64, 32)}
_cache: dict = {}


def model(name: str, res: int = 128, offset=(0.0, 0.0, 0.0)):
    """(mesh, bake result, coarse mesh at 10% of the faces), baked once per process."""
    key = (name, res, tuple(offset))
    if key not in _cache:
        m = MESHES[name]()
        m = TriMesh(m.vertices + np.asarray(offset), m.faces, m.normals)
        _cache[key] = (m, bb.bake(m, bb.Settings(resolution=res)), coarse.simplify(m, 0.1))
    return _cache[key]


def orbit_camera(mesh, azimuth, elevation, size=96, distance=2.8, fov=40.0) -> Camera:
    c, r = mesh.bounding_sphere()
    a, e = np.radians(azimuth), np.radians(elevation)
    eye = c + distance * r * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    return Camera(eye, c, np.array([0.0, 0.0, 1.0]), fov, size, size, *clip_planes(eye, c, c, r))


def bordered(boards) -> list:
    """The bordered maps the bake stores beside the billboards (no pyramids)."""
    return [billboard_maps.bordered(b, False) for b in boards]


def render(ctx, boards, camera, method="improved", hit_range=0.01, coarse_mesh=None, **kw) -> np.ndarray:
    return draw(Billboards(ctx, boards, bordered(boards), LIGHT, MATERIAL, SHADOW, method, hit_range, coarse_mesh, **kw),
                camera)
