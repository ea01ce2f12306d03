"""Renderer of `displaced`: the displaced mesh baked at this subdivision level, rasterised like `mesh`."""
from __future__ import annotations

from vdmbake import parts

from .raster import RasterMesh


def build(ctx, src, level):
    rel = next(m["mesh"] for m in src.part["meshes"] if m["level"] == level)
    return RasterMesh(ctx, src.bundle.read(rel, parts.MESH), src.scene.light, src.obj.material, src.shadow_map)
