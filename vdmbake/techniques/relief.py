"""Technique `relief`: relief mapping by an exact hierarchical height-field tracer (beyond the VDM
paper): the view ray and the shadow ray traced through the min/max mip pyramid of the depth field
(Tevs, Ihrke & Seidel 2008; Drobot 2009) to their exact first hit of the bilinear surface, both bent
by the base surface's curvature at the pixel (curved relief mapping, Oliveira & Policarpo 2005).
The bake builds the pyramid (vdmbake/common/pyramid.py); the knob caps the cell visits per ray."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..bundle import parts
from ..common import pyramid
from ..schema import Integer, ListOf, Technique, setting


@dataclass(frozen=True)
class Options:
    iterations: tuple[int, ...] = setting((8, 16, 32), ListOf(Integer(1, 4096)),
                                          "pyramid cells a ray may visit (exact when the ray needs fewer)",
                                          knob="iterations")


def bake(job) -> dict:
    """The min/max pyramid of the depth field depth * (1 - h) (texture units, float32), tiled."""
    m = job.obj.mesostructure
    t0 = time.perf_counter()
    depth = m.depth * (1.0 - job.maps.heights.astype(np.float64))
    p = pyramid.build(depth.astype(np.float32), pyramid.WRAP)
    job.steps["relief_pyramid_s"] = round(time.perf_counter() - t0, 4)
    job.log(f"relief pyramid {p.top + 1} levels, {p.nbytes / 2**10:.0f} KB")
    return {"pyramid": job.write("relief", parts.PYRAMID, p)}


TECHNIQUE = Technique("relief", "relief mapping by an exact hierarchical tracer: the view and shadow rays through "
                      "the height field's min/max pyramid to the exact bilinear hit, bent by the surface's "
                      "curvature", ("surface",), Options, mesostructure=True, bake=bake,
                      reads=lambda entry, iterations, obj: {entry["pyramid"]: parts.PYRAMID})
