"""Technique `tessellated`: the impostors' peer, quadrics as instanced triangle meshes (icospheres and
capped prisms of vdmbake.common.geometry). Needs only the quadric list."""
from __future__ import annotations

from dataclasses import dataclass

from ..schema import Integer, ListOf, Technique, setting


@dataclass(frozen=True)
class Options:
    levels: tuple[int, ...] = setting((0, 1, 2, 3), ListOf(Integer(0, 6)),
                                      "subdivision levels: icospheres of 20 * 4^level faces, prisms of 4 * 2^level "
                                      "sides", knob="level")


TECHNIQUE = Technique("tessellated", "instanced icospheres and prisms, rasterised", ("quadrics",), Options,
                      triangles="made")
