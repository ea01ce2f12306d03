"""Technique `displaced`: conventional displacement mapping (Cook 1984), the base mesh subdivided and
displaced inward by the mesostructure, baked at each level, rasterised."""
from __future__ import annotations

from dataclasses import dataclass

from ..common import geometry
from ..bundle import budget, parts
from ..schema import Integer, ListOf, Technique, setting


@dataclass(frozen=True)
class Options:
    levels: tuple[int, ...] = setting((1, 2, 3), ListOf(Integer(0, 8)),
                                      "midpoint subdivisions of the base mesh (4^level faces per face)", knob="level")


def bake(job) -> dict:
    m = job.obj.mesostructure
    base = job.stored_mesh     # the base mesh the reference displaces too
    meshes = []
    for level in job.options.levels:
        faces = len(base.faces) * 4 ** level
        budget.check(faces * budget.DISPLACE_BYTES_PER_FACE, f"object {job.obj.name!r}: displaced level {level} "
                     f"({faces:,} faces)", "use fewer levels (techniques.displaced.levels) or a coarser base mesh")
        d = geometry.displaced(base, job.maps.heights, job.maps.normals, m.depth, m.tiling, level)
        if m.albedo is None:   # texture coordinates only for the tile albedo (vdmrender/techniques/displaced.py)
            d.uvs = None
        meshes.append({"level": level, "mesh": job.write(f"displaced-{level}", parts.MESH, d)})
        job.log(f"displaced level {level}: {len(d.faces)} faces")
    return {"meshes": meshes}


def reads(entry: dict, level: int, obj) -> dict:
    return {next(m["mesh"] for m in entry["meshes"] if m["level"] == level): parts.MESH}


TECHNIQUE = Technique("displaced", "conventional displacement mapping: the base mesh subdivided and displaced, "
                      "rasterised", ("surface",), Options, mesostructure=True, bake=bake, reads=reads,
                      triangles="made")
