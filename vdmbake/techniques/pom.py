"""Technique `pom`: parallax occlusion mapping (Tatarchuk 2006), a VDM peer. Needs the mesostructure maps."""
from __future__ import annotations

from dataclasses import dataclass

from ..schema import Integer, ListOf, Technique, setting


@dataclass(frozen=True)
class Options:
    steps: tuple[int, ...] = setting((8, 16, 32), ListOf(Integer(2, 1024)),
                                     "layers of the linear search (then one secant step; the same toward the light)",
                                     knob="steps")


TECHNIQUE = Technique("pom", "parallax occlusion mapping: a linear search plus a secant step, the same search "
                      "toward the light", ("surface",), Options, mesostructure=True)
