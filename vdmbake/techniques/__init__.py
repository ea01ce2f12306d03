"""The technique registry. Each technique is declared once, in its own module here: the objects it
draws, its typed settings with the knob swept into an error-against-time curve, and the bake step
that writes the parts it needs (vdmbake.schema.Technique). Its renderer is the module of the same
name in vdmrender/techniques/, its shaders are in shaders/. Adding a technique: a module here, a
line below, a renderer there, its shaders."""
from __future__ import annotations

from ..schema import Technique
from . import billboards, bump, coarse, displaced, impostor, mesh, octahedral, pom, relief, tessellated, vdm

REGISTRY: dict[str, Technique] = {t.name: t for t in (
    mesh.TECHNIQUE, coarse.TECHNIQUE, impostor.TECHNIQUE, tessellated.TECHNIQUE, vdm.TECHNIQUE, pom.TECHNIQUE,
    relief.TECHNIQUE, bump.TECHNIQUE, displaced.TECHNIQUE, billboards.TECHNIQUE,
    octahedral.TECHNIQUE)}
