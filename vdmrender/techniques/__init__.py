"""Renderers: vdmrender/techniques/NAME.py draws the technique NAME declared in vdmbake/techniques/.

A variant is one point on the error-against-time chart: a technique at one value of its quality
knob. Building a variant (the module's `build(ctx, source, value)`) uploads its data and compiles,
once per context, the programs it uses, so a scene compiles only the shaders of the techniques it
names. The renderer reads everything it draws from the bundle."""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Callable

from vdmbake.scene import REGISTRY, Object, Scene

from ..common.source import Source


@dataclass
class Variant:
    technique: str
    knob: str | None                   # name of the quality knob's value, e.g. "ratio"
    value: Any                         # its value for this variant, as plain data (the scene's spelling)
    label: str                         # e.g. coarse@0.1
    build: Callable                    # build(ctx) -> renderer with render(camera, target) and release()


def variants(obj: Object, entry: dict, bundle, scene: Scene, only=None) -> list[Variant]:
    """The variants of every technique the object names (restricted to `only` if given), in scene order."""
    out = []
    for name, options in obj.techniques.items():
        if only is not None and name not in only:
            continue
        t = REGISTRY[name]
        module = importlib.import_module(f"{__name__}.{name}")
        src = Source(obj, entry, entry["techniques"].get(name), bundle, scene, options)
        knob = t.knob and t.knob.metadata["knob"]
        plain = (lambda v: v.plain()) if t.combine else t.knob.metadata["type"].item.dump if t.knob else None
        out += [Variant(name, knob, plain and plain(value), t.label(value),
                        lambda ctx, build=module.build, src=src, value=value: build(ctx, src, value))
                for value in t.values(options)]
    return out
