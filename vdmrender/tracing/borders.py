"""Which pixels see an open border of a surface with mesostructure (vdmbake.common.geometry.skirt), so the metric
scores the surface apart from its border: the reference and the metric agree on what a border is.

Per pixel, the primary ray (the reference's, clipped to the same near / far planes) is classed:
- BORDER: it crosses the shell's side wall (the skirt) before its reference hit, or crosses it and
  hits nothing: what it sees depends on how the open side of the mesostructure is closed, which no
  per-pixel method models (Wang2003 §5);
- INSIDE: its reference hit is the displaced sheet seen from behind (the base surface's back, below
  the mesostructure): a height field has no underside, so nothing there is the surface's to render;
- SURFACE: everything else, the pixels the techniques are scored on.
A closed surface has no skirt and is seen only from outside: every pixel is SURFACE.
"""
from __future__ import annotations

import numpy as np

from . import reference

SURFACE, BORDER, INSIDE = 0, 1, 2
COLOURS = np.array([[0, 0, 0], [255, 160, 0], [40, 110, 255]], np.uint8)   # class mask PNGs


def classify(camera, sheet, skirt, sphere=None) -> np.ndarray:
    """(H, W) uint8 classes for one camera. sheet: the RayScene of the displaced reference mesh;
    skirt: the RayScene of the shell's side wall, or None (no border); sphere: the sheet's bounding sphere, whose
    screen box confines the rays where there is no skirt (reference.may_meet: a ray that misses is SURFACE)."""
    rays = np.arange(camera.width * camera.height)
    keep = None if skirt is not None or sphere is None else reference.may_meet(camera, *sphere, rays)
    eye, d = camera.pixel_rays(pixels=None if keep is None else rays[keep])
    o, tfar = eye + d * camera.near, camera.far - camera.near
    h = sheet.intersect(o, d, tfar)
    cls = np.where((h.prim >= 0) & (np.einsum("ij,ij->i", h.ng, d) > 0), INSIDE, SURFACE).astype(np.uint8)
    if skirt is not None:
        s = skirt.intersect(o, d, tfar)
        cls[(s.prim >= 0) & (s.t <= h.t)] = BORDER      # h.t is inf where the sheet is missed
    if keep is not None:
        every = np.full(rays.size, SURFACE, np.uint8)
        every[keep] = cls
        cls = every
    return cls.reshape(camera.height, camera.width)
