"""Renderer of `mesh`: the full mesh, rasterised with the shared shading and a shadow map."""
from __future__ import annotations

from .raster import RasterMesh


def build(ctx, src, value):
    return RasterMesh(ctx, src.bundle.surface(src.entry), src.scene.light, src.obj.material, src.shadow_map)
