"""Technique `bump`: the base mesh shaded with the mesostructure's normals (Blinn 1978), the simplest
VDM peer. Needs the mesostructure maps, which every object with a mesostructure has."""
from __future__ import annotations

from dataclasses import dataclass

from ..schema import Technique


@dataclass(frozen=True)
class Options:
    pass


TECHNIQUE = Technique("bump", "the base mesh with the mesostructure's normals (Blinn 1978)", ("surface",), Options,
                      mesostructure=True)
