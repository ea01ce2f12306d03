"""Renderer of `bump`: the base mesh shaded with the mesostructure's normals (shaders/bump.frag)."""
from __future__ import annotations

from ..passes.mesostructure import MesostructurePass


def build(ctx, src, value):
    return MesostructurePass(ctx, src, "bump.frag", heights=False, cull=False)
