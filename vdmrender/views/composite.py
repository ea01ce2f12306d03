"""Composite frames (scene key `render.composite`): every object of the scene in one frame, each drawn by
the variant a set names, against a reference that traces every object together.

How the techniques meet (GL):
* One framebuffer, one depth buffer. The frame's target is cleared once; every technique then draws
  into it as it draws alone, but through a view of the target whose begin() binds it without clearing
  (`gl.Kept`). Every technique writes the exact window depth of what it shows (rasterised meshes, and
  gl_FragDepth: quadric impostors direct and deferred, billboards, octahedral impostors, VDM, POM and
  relief hits), under the same camera and near/far planes, so the depth test orders opaque surfaces of
  different techniques exactly as it orders those of one. Passes that work in their own targets (the
  deferred impostors' G-buffer, the hierarchical billboards' coarse-depth and occupancy passes) are
  untouched; the deferred shading pass is depth-tested with its hits' depth. Screen-space effects see
  only their own object: the deferred outlines' Sobel reads the impostors' G-buffer, so an impostor's
  silhouette against another object is outlined as against the background.
* One shadow map of the whole scene. It is fitted to the sphere holding every object; each technique's
  light pass draws into it (`ShadowView`: the same map in the technique's anchor-relative coordinates,
  not cleared), all light passes before any frame pass, so every object casts what its technique casts
  alone (billboards hier: its coarse mesh; VDM, POM, relief, bump: the base mesh) onto every other. The
  map spreads the scene's `shadow_map` texels over the whole scene, so each object gets fewer than alone.
* The state each technique starts its frame passes with is the one its own light pass leaves (depth
  test on, no culling, no blending), whatever the technique before it left.

The reference (vdmrender.tracing.reference.CompositeReference) traces every object's reference with the same
pixel rays, keeps per pixel the nearest hit, shaded with that object's material and colours, and blocks
every shadow ray by every object: the GL frame's shared shadow map and the reference agree on which
objects shadow which. Open borders of mesostructure surfaces are not scored apart in composites (every
pixel counts).

Cameras frame the whole scene: the orbit is placed on a sphere holding every object's bounding sphere
(vdmrender.common.camera.enclosing_sphere) and the near and far planes hug it.
"""
from __future__ import annotations

from dataclasses import asdict

import moderngl
import numpy as np

from ..common import images
from ..common.camera import cameras_for, enclosing_sphere
from ..comparing import change, scoring
from ..comparing.metrics import summarise
from ..passes.raster import Passes
from ..passes.shadowmap import ShadowMap, ShadowView
from ..techniques import variants
from ..tracing import refcache, reference

FOLDER = "composite"   # OUT/composite/: reference/, frames/SET/, heatmaps/SET/, overview.png


class Composite(Passes):
    """Several objects' renderers (vdmrender.techniques: each with `anchor`, `shadow` and `passes`) in one
    frame with one depth buffer and one shadow map of the whole scene (centre, radius)."""

    def __init__(self, ctx, renderers: dict, centre, radius: float, light, shadow_size: int):
        self.ctx, self.renderers = ctx, dict(renderers)
        self.centre = np.asarray(centre, np.float64)
        self.shadow = ShadowMap(ctx, shadow_size, light.direction, radius)
        self.own = {}                                 # each renderer's own shadow map, given back on release
        for name, r in self.renderers.items():
            self.own[name] = r.shadow
            r.shadow = ShadowView(self.shadow, np.asarray(r.anchor, np.float64) - self.centre)
        self.faces = sum(getattr(r, "faces", None) or 0 for r in self.renderers.values())

    def passes(self, camera, target) -> list:
        """Clear the target and the scene's shadow map; every object's light pass; then every object's other
        passes in scene order, each object's first one from its light pass's GL state."""
        kept = target.kept()

        def clear():
            self.shadow.begin()
            target.begin()

        light, frame = [], []
        for name, r in self.renderers.items():
            first = True
            for pass_name, run in r.passes(camera, kept):
                if pass_name == "shadow":
                    light.append((f"{name} shadow", run))
                    continue
                if first:
                    frame.append((f"{name} state", lambda: self.ctx.enable_only(moderngl.DEPTH_TEST)))
                    first = False
                frame.append((f"{name} {pass_name}", run))
        return [("clear", clear)] + light + frame

    def release(self) -> None:
        for name, r in self.renderers.items():
            r.shadow = self.own[name]
            r.release()
        self.shadow.release()


def set_label(chosen: dict) -> str:
    """A variant set as reports name it: OBJECT:VARIANT, space-separated, in scene order."""
    return " ".join(f"{o}:{v}" for o, v in chosen.items())


def scene_sphere(bundle, scene) -> tuple[np.ndarray, float]:
    objs = bundle.manifest["objects"]
    return enclosing_sphere([objs[o.name]["centre"] for o in scene.objects], [objs[o.name]["radius"] for o in scene.objects])


def reference_source(bundle, scene, cams, spp: int = 1):
    """The composite reference from `cams` at `spp` samples per pixel (reference.filtered): its cache key, and its
    tracer for refcache.load_or_trace."""
    entries = bundle.manifest["objects"]
    geometry = {o.name: {**refcache.reference_geometry(o, entries[o.name], bundle), "material": asdict(o.material)}
                for o in scene.objects}
    key = refcache.reference_key(geometry, cams, scene.light, scene.material, scene.render.background,
                                 refcache.reference_code(any(o.mesostructure for o in scene.objects)), spp)

    def trace(cams):
        ref = reference.CompositeReference(refcache.object_reference(o, entries[o.name], bundle, scene)[0]
                                           for o in scene.objects)
        before = ref.rays_cast
        frames, halves = zip(*(reference.filtered(ref.render, c, spp) for c in cams))
        return list(frames), list(halves), [None] * len(frames), ref.rays_cast - before

    return key, trace


def variant_sets(scene, only) -> list[dict]:
    """The variant sets of render.composite that a run draws: those whose techniques --technique keeps (`only`)."""
    return [s for s in scene.render.composite if only is None or all(v.split("@")[0] in only for v in s.values())]


def cameras(bundle, scene, width: int, height: int) -> list:
    """The composite's cameras: the scene's orbit around the sphere that holds every object."""
    return cameras_for(scene.camera, *scene_sphere(bundle, scene), width, height)


def render_sets(harness, out, bundle, scene, sets, cams, refs, opts, device, log) -> list[dict]:
    """The variant sets `sets` (variant_sets'), drawn from `cams` (cameras'): timed, scored against the composite
    reference `refs` (scoring.References), written under OUT/composite/; one report row per set. A set none of
    whose frames has a pixel to score is an error (vdmrender.cli) unless every object sets expect_empty."""
    ctx = harness.ctx
    centre, radius = scene_sphere(bundle, scene)
    sheet, rows, drawn = [("reference", refs.filtered)], [], {}
    entries = bundle.manifest["objects"]
    full = {o.name: change.full_asset(o, entries[o.name], bundle, scene) for o in scene.objects}

    def composed(chosen: dict):
        def build():
            builds = {}
            for obj in scene.objects:
                v = full[obj.name] if chosen[obj.name] == full[obj.name].label else next(
                    v for v in variants(obj, entries[obj.name], bundle, scene) if v.label == chosen[obj.name])
                builds[obj.name] = v.build(ctx)
            return Composite(ctx, builds, centre, radius, scene.light, scene.render.shadow_map)
        return build

    for k, chosen in enumerate(sets, start=1):
        label = set_label(chosen)
        cost, frames, aliased = harness.measure(composed(chosen), cams, f"composite {k}")
        scores, heats, enc = scoring.score_frames(frames, refs.filtered, refs.classes, out, f"{FOLDER}/frames/{k}",
                                          f"{FOLDER}/heatmaps/{k}", opts.heat_max, scene.render.background, opts.flip,
                                          f"composite {k} scoring")
        row = {"set": k, "label": label, "variants": dict(chosen), "frames": len(cams),
               "expect_empty": all(o.expect_empty for o in scene.objects), **cost,
               **summarise(scores), **refs.aliased(aliased, frames, scene.render.background, scores), "device": device,
               "reference_cached": refs.cached}
        rows.append(row)
        drawn[label] = enc
        sheet += [(f"{k}: {label}", enc), (f"{k}: error", heats)]
        log(f"composite {k} ({label}): {scoring.row_line(row)}")
    whole = {o: v.label for o, v in full.items()}   # every object by its full asset (vdmrender.comparing.change)
    change.attach(rows, drawn, set_label(whole), composed(whole), harness, cams, refs, opts.flip,
                  scene.render.background)
    images.overview(sheet, out.file(f"{FOLDER}/overview.png"), heat_max=opts.heat_max)
    return rows
