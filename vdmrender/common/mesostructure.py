"""A mesostructure object's surface as data, no GL (Wang et al. 2003 §3.2): its height field and normal map, its
colour tile, and the truly displaced geometry the reference traces and the full asset draws."""
from __future__ import annotations

import numpy as np

from vdmbake.bundle import parts
from vdmbake.common import geometry
from vdmbake.common.embree import RayScene
from vdmbake.errors import InputError


def maps(src) -> parts.MesostructureMaps:
    return src.bundle.read(src.entry["mesostructure"], parts.MESOSTRUCTURE)


def tile_albedo(src):
    """The mesostructure's colour tile (an albedo map, vdmbake.assets.meso_albedo), None where the scene gives none."""
    rel = src.entry.get("mesostructure_albedo")
    return src.bundle.read(rel, parts.ALBEDO_MAP) if rel else None


def textured(mesh, src):
    """A mesh carrying the base mesh's texture coordinates (the base mesh, a displaced one) with the tile
    albedo as its only colour, read at the tile coordinate T = uv * tiling as an asset's albedo map is read at
    its UVs (vdmbake.common.texture); unchanged where the mesostructure has no albedo."""
    tile = tile_albedo(src)
    if tile is not None:
        if mesh.uvs is None:
            raise InputError(f"{src.bundle.path}: object {src.obj.name!r}: a mesh without texture coordinates "
                             "under a mesostructure albedo; re-bake with vdmbake --force.")
        mesh.uvs, mesh.texture = mesh.uvs * np.asarray(src.obj.mesostructure.tiling), tile
        mesh.colors = None           # the tile is the albedo under a mesostructure, as in the reference
    return mesh


def reference_mesh(src):
    """The truly displaced geometry the reference traces: the base mesh subdivided until no edge spans
    more than half a texel, and displaced (the reference of docs/architecture.md §1 step 4), textured by
    the tile albedo if any. Too large to bake (8 M faces on the benchmark's torus), it is built here from
    the bundle's base mesh and maps by the same kernel the `displaced` bake uses."""
    m = src.obj.mesostructure
    base = src.bundle.read(src.entry["mesh"], parts.MESH)
    meso = maps(src)
    return textured(geometry.displaced(base, meso.heights, meso.normals, m.depth, m.tiling,
                                       geometry.reference_levels(base, m.size, m.tiling)), src)


def skirt_scene(src):
    """The Embree scene of the base mesh's shell side wall (vdmbake.common.geometry.skirt), None on a closed surface."""
    m = src.obj.mesostructure
    v, f = geometry.skirt(src.bundle.read(src.entry["mesh"], parts.MESH), m.depth, m.tiling)
    return RayScene(v, f) if len(f) else None
