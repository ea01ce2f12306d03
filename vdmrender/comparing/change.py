"""What a switch changes (issue 39): each variant's frames against the object's full asset drawn the same way (the
same cameras, screen size and anti-aliasing mode), beside its error against the reference (its fidelity).

The error against the reference cannot decide at small sizes or in crowds: there, the full asset's own error
grows (every pixel is an edge pixel, a GL frame shades once per pixel where the reference averages many samples)
and the reference's sampling noise is as large as the differences between variants. Neither depends on the
variant, so the change against the full asset is what a level-of-detail switch is decided on (the rule of
engines' LOD tools, which compare each level's render with the full model's at that size); the full asset's
fidelity is the floor, what the pipeline and not the representation costs (a variant lands below it only where it
smooths what the full asset aliases), reported beside it with the reference's noise (vdmrender.comparing.scoring)."""
from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np

from vdmbake.bundle import parts
from vdmbake.common import geometry
from vdmbake.scene import LIMIT_ON, REGISTRY

from ..common import images
from ..common.mesostructure import reference_mesh
from ..common.source import Source
from ..passes.raster import RasterMesh
from .metrics import compare, flip_values, pooled
from ..techniques import Variant, variants

# The row fields of the change against the full asset, by the field of the same error against the reference.
FIELDS = {LIMIT_ON["reference"][k]: LIMIT_ON["change"][k] for k in LIMIT_ON["change"]}


def full_asset(obj, entry: dict, bundle, scene) -> Variant:
    """The object's exact representation, as a variant its rows' labels name: the full mesh (`mesh`) for mesh files
    and primitives, the ray-cast quadrics (`impostor@direct`) for molecules and inline quadrics, and for a
    mesostructure the truly displaced surface the reference traces, rasterised (`displaced@L`, L the reference's
    subdivision level: the `displaced` technique at that level)."""
    if obj.mesostructure is None:
        name = "mesh" if obj.kind == "surface" else "impostor"
        options = REGISTRY[name].options(**({"shading": ("direct",)} if name == "impostor" else {}))
        return variants(dataclasses.replace(obj, techniques={name: options}), entry, bundle, scene)[0]
    src = Source(obj, entry, None, bundle, scene, None)
    m = obj.mesostructure
    level = geometry.reference_levels(bundle.read(entry["mesh"], parts.MESH), m.size, m.tiling)
    mesh = cache(lambda: reference_mesh(src))   # built once, drawn at every size

    def build(ctx):
        return RasterMesh(ctx, mesh(), scene.light, obj.material, src.shadow_map, src.instances, mipmaps=src.mipmaps)

    return Variant("displaced", "level", level, f"displaced@{level}", build)


def fields(frames: list, full: list, flip: bool) -> dict:
    """A variant's change against the full asset, its frames (sRGB uint8 with coverage, as scoring encodes them)
    against the full asset's of the same views, pooled as its error against the reference is (metrics.pooled:
    mean and p95 ΔLuv over both coverage masks, the coverage-weighted IoU) and, with `flip`, the mean FLIP."""
    cs = [compare(f, g) for f, g in zip(frames, full)]
    p = pooled(cs)
    out = {FIELDS[k]: p[k] for k in ("mean_dluv", "p95_dluv", "iou")}
    if flip:
        fl = np.concatenate([flip_values(f, g, c["scored"]) for f, g, c in zip(frames, full, cs)])
        out[FIELDS["flip_mean"]] = round(float(fl.mean()), 5) if fl.size else None
    return out


def floor(full: list, refs) -> dict:
    """The full asset's own error against the reference at these views (scoring.References): the floor, what the
    pipeline and not the representation costs, with the reference's noise, below which no difference shows."""
    p = pooled([compare(f, r, c) for f, r, c in zip(full, refs.filtered, refs.classes)])
    return {"floor_dluv": p["mean_dluv"], "floor_p95_dluv": p["p95_dluv"], "floor_iou": p["iou"],
            "reference_noise_dluv": refs.noise_dluv}


def attach(rows: list[dict], frames: dict, label: str, build, harness, cams, refs, flip: bool, background) -> None:
    """Each row's change against the full asset and the floor of these views (floor). `frames`: each row's sRGB
    frames by its label; the full asset's are those labelled `label` where it was one of the rows, else drawn here
    by build() as the rows were shipped, untimed (measure.Harness.frames), and put there too."""
    if label not in frames:
        frames[label] = [images.encode(f, background) for f in harness.frames(build, cams)]
    full = frames[label]
    below = floor(full, refs)
    for r in rows:
        r.update(fields(frames[r["label"]], full, flip), change_against=label, **below)
