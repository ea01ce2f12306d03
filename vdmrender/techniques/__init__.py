"""Techniques: each module turns an object's bundle parts into renderable variants.

A variant is one point on the error-against-time chart: a technique at one value of its
quality knob. Building a variant uploads its data and compiles (once) the programs it uses,
so a scene compiles only the shaders of the techniques it names.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from vdmbake.scene import TECHNIQUES

from . import billboards, coarse, impostor, mesh, mesostructure, tessellated


@dataclass
class Variant:
    technique: str
    knob: str | None          # name of the quality knob's value, e.g. "ratio"
    value: float | int | str | None   # its value for this variant
    build: Callable           # build(ctx) -> renderer with render(camera, target) and release()

    @property
    def label(self) -> str:
        if self.knob is None:
            return self.technique
        return f"{self.technique}@{self.value:g}" if isinstance(self.value, float) else f"{self.technique}@{self.value}"


REGISTRY = {"mesh": mesh.variants, "coarse": coarse.variants, "impostor": impostor.variants,
            "tessellated": tessellated.variants, "vdm": mesostructure.vdm_variants, "bump": mesostructure.bump_variants,
            "pom": mesostructure.pom_variants, "relief": mesostructure.relief_variants,
            "displaced": mesostructure.displaced_variants,
            "billboards": billboards.variants}


def variants(obj, entry: dict, bundle, scene, only=None) -> list[Variant]:
    """The variants of every technique the object names (restricted to `only` if given), in scene order.
    Each technique module returns (knob value, build) pairs; the knob's name comes from its spec."""
    out = []
    for name, options in obj.techniques.items():
        if only is None or name in only:
            knob = TECHNIQUES[name].knob
            out += [Variant(name, knob and knob.label, value, build)
                    for value, build in REGISTRY[name](obj, entry, bundle, scene, options)]
    return out
