"""Renderer of `pom`: parallax occlusion mapping per pixel over the base mesh (shaders/pom.frag)."""
from __future__ import annotations

from ..passes.mesostructure import MesostructurePass


def build(ctx, src, steps):
    return MesostructurePass(ctx, src, "pom.frag", u_steps=steps)
