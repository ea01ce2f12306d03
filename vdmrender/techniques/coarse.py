"""Technique `coarse`: the simplified meshes baked by vdmbake, one variant per face ratio."""
from __future__ import annotations

from .mesh import RasterMesh


def variants(obj, entry, bundle, scene, options):
    def builder(rel):
        return lambda ctx: RasterMesh(ctx, bundle.mesh(rel), scene.light, obj.material, scene.render.shadow_map)
    return [(ratio, builder(entry["coarse"][f"{ratio:g}"])) for ratio in options["ratios"]]
