"""Renderer of `relief`: the exact hierarchical tracer per pixel over the base mesh (shaders/relief.frag,
shaders/include/heightfield_trace.glsl) through the baked pyramid, at most `iterations` cell visits per ray."""
from __future__ import annotations

from vdmbake.bundle import parts

from ..passes import hftrace
from ..passes.mesostructure import MesostructurePass


class ReliefPass(MesostructurePass):
    """defines: e.g. ("FLAT",) for straight rays in the pixel's frame, as POM takes them."""

    def __init__(self, ctx, src, iterations: int, defines: tuple = ()):
        p = src.bundle.read(src.part["pyramid"], parts.PYRAMID)
        super().__init__(ctx, src, "relief.frag", heights=False, curvature="FLAT" not in defines, defines=defines,
                         u_iterations=int(iterations), u_depth=src.obj.mesostructure.depth, **hftrace.uniforms(p))
        self.textures["u_hf"] = hftrace.pyramid_texture(ctx, p)


def build(ctx, src, iterations):
    return ReliefPass(ctx, src, iterations)
