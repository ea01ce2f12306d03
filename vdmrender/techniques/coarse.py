"""Renderer of `coarse`: one simplified mesh (baked by vdmbake) per ratio, rasterised like `mesh`."""
from __future__ import annotations

from ..passes.raster import RasterMesh


def build(ctx, src, ratio):
    rel = next(m["mesh"] for m in src.part["meshes"] if m["ratio"] == ratio)
    return RasterMesh(ctx, src.bundle.surface(src.entry, rel), src.scene.light, src.obj.material, src.shadow_map,
                      src.instances, src.mipmaps)
