"""Per-copy LOD drawn as an engine draws it (issue 23): every copy of an instanced object by the variant its screen
size selects in a chain that vdmrender.deciding.lod chose, per frame; the lod@CHAIN variant a report row measures."""
from __future__ import annotations

import math

import numpy as np

from vdmbake.common import instances

from ..common.camera import framed
from .composite import Composite
from ..techniques import Variant, variants


def screen_px(camera, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Each sphere's silhouette diameter in pixels as vdmrender.views.sweep measures it (seen at the image centre: what
    an engine's screen-size test computes), infinite for a sphere around the eye."""
    f = 0.5 * camera.height / math.tan(math.radians(camera.fov_deg) / 2)
    d2 = ((centres - camera.eye) ** 2).sum(1)
    gap = d2 - radii ** 2
    with np.errstate(divide="ignore"):
        return np.where(gap > 0, 2 * f * radii / np.sqrt(np.maximum(gap, 1e-300)), np.inf)


def pick(entries: list[dict], sizes: np.ndarray) -> np.ndarray:
    """Each size's entry index: the band (min_px, max_px] it falls in; above the chain's top, its finest entry."""
    lows = np.array([e["min_px"] for e in entries], float)   # decreasing
    return np.clip((sizes <= lows[:, None]).sum(0), 0, len(entries) - 1)


def chosen(entries: list[dict], camera, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Each copy's variant label under `camera`: the entry whose band its screen size falls in (pick)."""
    return np.array([e["variant"] for e in entries])[pick(entries, screen_px(camera, centres, radii))]


class LodMix(Composite):
    """Per-instance LOD, as an engine does it: per frame every copy of the object is drawn by the variant its
    screen size selects in the chain (`entries`, lod.json's), all in one frame with one depth buffer and one
    shadow map (vdmrender.views.composite.Composite: each copy casts what its variant casts). renderers: {variant label:
    renderer built with every copy, with `place`}; world: the copies' matrices; sphere: the object's bounding
    sphere (centre, radius); around: the sphere holding every copy."""

    def __init__(self, ctx, renderers: dict, entries: list[dict], world: np.ndarray, sphere, around, light,
                 shadow_size: int):
        super().__init__(ctx, renderers, *around, light, shadow_size)
        self.all, self.entries, self.world = dict(self.renderers), entries, world
        self.centres, self.radii = instances.spheres(world, *sphere)

    def passes(self, camera, target) -> list:
        labels = chosen(self.entries, camera, self.centres, self.radii)
        self.renderers = {}
        for label, r in self.all.items():   # a variant may hold several bands: all its copies at once
            mine = self.world[labels == label]
            if len(mine):
                r.place(mine)
                self.renderers[label] = r
        return super().passes(camera, target)

    def release(self) -> None:
        self.renderers = self.all
        super().release()


def mixed(obj, entry, bundle, scene, name: str, entries: list[dict], world) -> Variant:
    """The variant lod@NAME of an instanced object whose copies `world` places: every copy drawn by the variant of
    chain NAME (its `entries`) its screen size selects, per frame (LodMix)."""
    builds = {v.label: v.build for v in variants(obj, entry, bundle, scene)}
    labels = list(dict.fromkeys(e["variant"] for e in entries))

    def build(ctx):
        return LodMix(ctx, {label: builds[label](ctx) for label in labels}, entries, world,
                      (entry["centre"], entry["radius"]), framed(obj, entry, scene), scene.light, scene.render.shadow_map)

    return Variant("lod", "chain", name, f"lod@{name}", build)


def copies_chosen(entry, world, entries, cams) -> dict:
    """How many copies each variant of the chain drew, summed over the cameras (chosen, as LodMix draws)."""
    centres, radii = instances.spheres(world, entry["centre"], entry["radius"])
    which = np.concatenate([chosen(entries, c, centres, radii) for c in cams])
    return {label: int((which == label).sum()) for label in dict.fromkeys(e["variant"] for e in entries)}
