"""Renderer of `displaced`: the displaced mesh baked at this subdivision level, rasterised like `mesh` (the tile
albedo, if any, read at the interpolated tile coordinate as `mesh` reads an asset's albedo map)."""
from __future__ import annotations

from vdmbake.bundle import parts

from ..common.mesostructure import textured
from ..passes.raster import RasterMesh


def build(ctx, src, level):
    rel = next(m["mesh"] for m in src.part["meshes"] if m["level"] == level)
    return RasterMesh(ctx, textured(src.bundle.read(rel, parts.MESH), src), src.scene.light, src.obj.material,
                      src.shadow_map, mipmaps=src.mipmaps)
