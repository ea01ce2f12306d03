"""Technique `mesh`: the full mesh, rasterised, the baseline every surface variant is timed against.
Its only part is the full mesh, which every surface object has (the reference traces it)."""
from __future__ import annotations

from dataclasses import dataclass

from ..schema import Technique


@dataclass(frozen=True)
class Options:
    pass


TECHNIQUE = Technique("mesh", "the full mesh, rasterised, shared shading, shadow map", ("surface",), Options,
                      triangles="mesh")
