"""Renderer of `mesh`: the full mesh, rasterised with the shared shading and a shadow map. Under a mesostructure
with a colour tile, the base surface textured by it (plain texture mapping: the mesostructure techniques'
flat baseline)."""
from __future__ import annotations

from ..common.mesostructure import textured
from ..passes.raster import RasterMesh


def build(ctx, src, value):
    mesh = src.bundle.surface(src.entry)
    return RasterMesh(ctx, textured(mesh, src) if src.obj.mesostructure else mesh, src.scene.light,
                      src.obj.material, src.shadow_map, src.instances, src.mipmaps)
