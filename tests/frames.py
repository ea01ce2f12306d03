"""One renderer's frame and its score against the Embree reference of a mesh, shared by the GL tests of
the per-object techniques (billboards, octahedral impostors): one light, one material, one background."""
from __future__ import annotations

import numpy as np

from vdmbake.scene import Light, Material
from vdmrender import gl, images, metrics, reference

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
