"""One render run: every object's frames with each technique variant and the reference,
the error of each frame, the time per frame, and the report."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path


from vdmbake import __version__
from vdmbake.bundle import budget as memory
from vdmbake.bundle import parts
from vdmbake.bundle.directory import Bundle
from vdmbake.common import geometry, instances
from vdmbake.errors import InputError
from vdmbake.bundle.staging import StagedDir
from vdmbake.scene import ANTIALIAS, REGISTRY, Scene
from vdmbake.schema import overridable

from .common import images
from .common.camera import cameras_for, framed
from .comparing import change, scoring
from .comparing.metrics import summarise
from .deciding import baseline, lod, pricing
from .gpu import device as gpu, gl
from .measuring import interleaved, measure, timing
from .reporting import chains, html, report
from .techniques import variants
from .tracing import refcache, reference
from .views import composite, lodmix, sweep


def held_geometry(bundle) -> tuple[memory.Geometry, ...]:
    """What each object gives the render to hold (vdmbake.bundle.budget.Geometry), from the manifest and, for a
    mesostructure, its base mesh: every mesh part of the object and its quadrics, times its copies (the reference
    merges them), and the faces of the displaced reference (the base mesh subdivided to reference_levels)."""
    out = []
    for obj in bundle.scene.objects:
        entry, copies = bundle.manifest["objects"][obj.name], instances.count(obj.instances) if obj.instances else 1
        prefix = f"objects/{obj.name}/"
        faces = sum(m["faces"] for rel, m in bundle.manifest["parts"].items()
                    if rel.startswith(prefix) and m["kind"] == "mesh")
        q = bundle.manifest["parts"][entry["quadrics"]] if entry.get("quadrics") else {"spheres": 0, "cylinders": 0}
        displaced = 0
        if obj.mesostructure:
            m, base = obj.mesostructure, bundle.read(entry["mesh"], parts.MESH)
            displaced = len(base.faces) * 4 ** geometry.reference_levels(base, m.size, m.tiling)
        out.append(memory.Geometry(obj.name, faces * copies, (q["spheres"] + q["cylinders"]) * copies, displaced))
    return tuple(out)


def memory_need(bundle, width: int, height: int, opts: "Options") -> memory.Render:
    """What the run holds at its peak, as vdmbake.bundle.budget estimates it (`opts` resolved by filtering): the
    reference at this size on reference.workers() threads, every object's geometry, the targets."""
    scene = bundle.scene
    return memory.Render(width, height, len(cameras_for(scene.camera, (0.0, 0.0, 0.0), 1.0, width, height)),
                         opts.reference_spp, reference.workers(), ANTIALIAS[opts.antialias], held_geometry(bundle),
                         together=bool(scene.render.composite))


# The scene's settings a run overrides, each declared once in vdmbake.scene (`setting(..., flag=...)`): the
# option `vdmrender --NAME` and the field NAME of Options, None for the scene's value.
OVERRIDES = overridable(Scene)
Overrides = dataclasses.make_dataclass(
    "Overrides", [(f.name, f"{f.type} | None", dataclasses.field(default=None)) for _, f in OVERRIDES],
    namespace={"__module__": __name__})


@dataclass
class Options(Overrides):
    techniques: tuple[str, ...] | None = None    # render only these (the scene's list otherwise)
    warmup_s: float | None = None                # timing.Budget: minimum warm-up time
    sample_s: float | None = None                # timing.Budget: minimum sampling time
    device: str | None = None
    heat_max: float = 10.0                       # delta-Luv at the top of the heat-map colour scale
    flip: bool = True                            # also score each frame with NVIDIA FLIP
    baseline: Path | None = None                 # an earlier run's report.json to compare with
    max_error_increase: float | None = None      # its thresholds (vdmrender.deciding.baseline)
    max_slowdown: float | None = None
    compare_devices: bool = False                # compare times with a baseline from another device
    counters: bool = True                        # count each variant's work (vdmrender.measuring.counters)
    reference_cache: refcache.Shared | None = None   # references by content key, shared by a cluster's workers


def filtering(opts: Options, scene) -> Options:
    """The options with the reference's samples per pixel and the anti-aliasing mode resolved (the scene's where
    the options leave them)."""
    return dataclasses.replace(opts, reference_spp=opts.reference_spp or scene.render.reference_spp,
                               antialias=opts.antialias or scene.render.antialias)


def _technique_filter(opts: Options, scene) -> set | None:
    if not opts.techniques:
        return None
    named = {t for o in scene.objects for t in o.techniques}
    for t in opts.techniques:
        if t not in REGISTRY:
            raise InputError(f"--technique {t!r}: unknown; known techniques: {', '.join(REGISTRY)}.")
        if t not in named:
            raise InputError(f"--technique {t!r}: no object of this bundle's scene names it "
                             f"(they name: {', '.join(sorted(named))}).")
    return set(opts.techniques)


def budget(opts: Options, scene) -> timing.Budget:
    """The timing budget: the scene's render.warmup and render.repeats, overridden by the options; warmup = 0
    and no --warmup-s: no warm-up at all."""
    d = timing.Budget()
    warmup = scene.render.warmup if opts.warmup is None else opts.warmup
    return timing.Budget(warmup=warmup, warmup_s=(d.warmup_s if warmup else 0.0) if opts.warmup_s is None else opts.warmup_s,
                         warmup_max_s=max(d.warmup_max_s, 3 * (opts.warmup_s or 0)),
                         repeats=opts.repeats or scene.render.repeats,
                         sample_s=d.sample_s if opts.sample_s is None else opts.sample_s)


TIMING = ("GPU time per frame: the sum of the frame's passes' GL timer queries (GL_TIME_ELAPSED), after a "
          "warm-up until successive windows' median GPU times agree within the tolerance (warmup_s, warmup_frames, "
          "steady); median_ms and q1_ms/q3_ms over every timed frame, spread_ms the within-camera interquartile "
          "range (median over cameras), passes_ms the per-pass medians; wall_ms is the first call to "
          "ctx.finish() returning, submit_ms the renderer's calls returning (CPU); a frame with a pass over 4.29 s "
          "saturates its 32-bit query and is timed by wall time (counted in saturated). The target's clear before "
          "each frame is outside every query, timed apart as clear_ms (after each variant's sampling, median). ratio_to_baseline divides median_ms by "
          "the baseline row of the same object and run")


CHANGE = ("change_*: the variant's frames against its object's full asset (change_against: the full mesh `mesh`, the "
          "ray-cast quadrics `impostor@direct`, the truly displaced surface the reference traces `displaced@L`; for "
          "a composite every object's) drawn the same way, same cameras, size and anti-aliasing, pooled as the error "
          "is (change_dluv, change_p95_dluv over both coverage masks, change_iou, change_flip): what a viewer sees "
          "change when the full asset is swapped for the variant; the full asset's own row changes nothing. "
          "floor_dluv, floor_p95_dluv, floor_iou: the full asset's error against the reference at the same views, what the "
          "pipeline costs whatever the representation; reference_noise_dluv: the reference's own sampling noise, "
          "from two halves of its strata (vdmrender.comparing.scoring.noise), below which no two errors can be told apart")


SWEEP = ("every view again with the camera moved along its line of sight, aimed at the object's bounding-sphere "
         "centre, to where the sphere's silhouette is size_px pixels across (vdmrender.views.sweep.distance_for; "
         "distance_radii: the first view's eye distance in radii); frame size, field of view and timing as the rows'; frames "
         "under sizes/NNNpx/")


def run(bundle_path: Path, out_path: Path, opts: Options, log=lambda m: None) -> dict:
    bundle = Bundle(bundle_path)
    scene = bundle.scene
    width, height = opts.resolution or scene.render.resolution
    plan = budget(opts, scene)
    only = _technique_filter(opts, scene)
    old = baseline.load(opts.baseline) if opts.baseline else None
    if old is not None and opts.max_slowdown is not None:
        baseline.check_spread(old, plan.repeats)       # before any rendering: no spread, no slowdown to judge
    opts = filtering(opts, scene)
    memory.check_render(memory_need(bundle, width, height, opts))   # the one memory guard, before any work
    ctx = gl.create_context(opts.device)
    device = gl.renderer_name(ctx)
    why_not = old and baseline.times_comparable(old, {"time": "gpu", "device": device}, opts.compare_devices)
    if why_not and opts.max_slowdown is not None:
        ctx.release()
        raise InputError(f"--max-slowdown with --baseline {opts.baseline}: {why_not}.")
    errors_not = old and baseline.errors_comparable(old, filtering_note(opts))
    if errors_not and opts.max_error_increase is not None:
        ctx.release()
        raise InputError(f"--max-error-increase with --baseline {opts.baseline}: {errors_not}.")
    device_info, nvml = gpu.describe(ctx), gpu.nvml_clocks()
    try:   # its anti-aliased target is checked against the device's limits: refused before the output is staged
        harness = measure.Harness(ctx, gl.Target(ctx, width, height), plan, opts.counters, opts.antialias)
    except BaseException:
        ctx.release()
        raise
    out = StagedDir(out_path, "report.json", "vdmrender output folder")
    try:
        sizes = _sizes(opts, scene)
        lod_sets = scene.render.sweep.lod if sizes and scene.render.sweep else ()
        drawn = view_sets(bundle, scene, only, sizes, width, height)
        rows, sweep_rows, per_object = [], [], {}
        for obj in scene.objects:   # each object once: its sweep, its chains, then its cameras (vdmrender.views.lodmix)
            views = render_views(harness, out, bundle, scene, obj, [v for v in drawn if v.obj and v.obj.name == obj.name],
                                 only, opts, device, log, lod_sets)
            rows += views.rows
            sweep_rows += views.sweep
            if views.chains:
                per_object[obj.name] = views.chains
        sized = {"sweep": {"sizes_px": sizes, "how": SWEEP, "rows": sweep_rows}} if sizes else {}
        if lod_sets:
            sized["lod"] = lod.chains(per_object, sweep_rows, lod_sets, device, (width, height), filtering_note(opts))
            sized["lod"]["bundle"] = {"manifest_sha256": bundle.identity}   # vdmexport refuses another's
            if any(r["technique"] == "lod" for r in rows):
                lod.priced_on_field(sized["lod"], rows)
                _log_chains(sized["lod"], log, "priced on the field")
        report.add_baseline_ratios(rows)
        whole = [v for v in drawn if v.obj is None]
        composite_rows = composite.render_sets(harness, out, bundle, scene, composite.variant_sets(scene, only),
                                               whole[0].cams, _references(out, bundle, scene, whole[0], opts, log),
                                               opts, device, log) if whole else []
        result = {"tool_version": __version__, "bundle": str(bundle.path), "device": device,
                  "gl": device_info, "nvml": nvml, "resolution": [width, height], "budget": asdict(plan),
                  "time": "gpu", "timing": TIMING,
                  "clear_ms": harness.clear_ms(),
                  "error": "delta-L*u*v* (CIE 1976, sRGB/D65) against the reference over the union of both "
                           "coverage masks (thesis eq. 2.2); a frame where neither covers a pixel is empty: no "
                           "error, flagged, counted in empty_frames and left out of the averages; for a "
                           "mesostructure object, pixels that see an open border or the surface from inside "
                           "(reference/OBJECT/NNN-classes.png) are scored apart: border_px, inside_px, "
                           "mean_dluv_apart, and every pixel together in mean_dluv_all, iou_all",
                  "change": CHANGE,
                  "flip": "NVIDIA FLIP (LDR, 67 pixels per degree) of the sRGB frames, averaged over the same "
                          "pixels as the error (flip_mean pools a variant's frames like mean_dluv)" if opts.flip else "not computed",
                  "heatmap_max_dluv": opts.heat_max, "rows": rows,
                  "filtering": {**filtering_note(opts), **refcache.samples_traced(out.tmp)}}
        if composite_rows:   # render.composite: every object in one frame, per variant set (vdmrender.views.composite)
            result["composite"] = composite_rows
        result.update(sized)
        if old is not None:
            result["baseline"] = {"report": str(opts.baseline),
                                  **baseline.compare(old, result, opts.max_error_increase, opts.max_slowdown,
                                                     opts.compare_devices)}
        result = report.finite(result)
        report.write(out.tmp, result)
        if "sweep" in result:
            sweep.write(out.tmp, result)
        if "lod" in result:
            chains.write(out.tmp, result["lod"], result["sweep"]["rows"])
        html.write(out.tmp, result)   # last: it links the files written above
        out.commit()
    except BaseException:
        out.abort()
        raise
    finally:
        harness.release()
        ctx.release()
    return result


def _log_chains(chains: dict, log, how: str) -> None:
    for c in chains["chains"]:
        for obj, ch in c["objects"].items():
            _log_chain(c["name"], obj, ch["entries"], log, how)


def _log_chain(name: str, obj: str, entries: list[dict], log, how: str) -> None:
    log(f"LOD chain {name} of {obj} ({how}): " + ", ".join(
        f"{e['variant']} {e['min_px']}-{e['max_px']} px{'' if e['meets'] else ' (over the limits)'}" for e in entries))


def filtering_note(opts: Options) -> dict:
    """How the frames and the reference were filtered (report.json's `filtering`)."""
    n = math.isqrt(opts.reference_spp)
    return {"reference_spp": opts.reference_spp, "reference_filter": "box" if n > 1 else "none (pixel centre)",
            "reference_samples": f"up to {n} x {n} correlated multi-jittered (Kensler 2013), a pattern per pixel "
                                 f"(seeded by its index); adaptive: {len(reference.first_samples(n * n))} first, the rest only "
                                 "where they disagree (coverage, colour, an edge beside), reference_mean_spp the mean "
                                 "traced" if n > 1 else "1",
            "antialias": opts.antialias,
            "aliased": "aliased_*: the variant's frames without anti-aliasing against the pixel-centre reference "
                       "(one sample per pixel on both sides), beside the error against what a viewer sees"}


def _measure(harness, v, cams, refs, out, obj, opts, background, prefix="", what=None):
    """One variant: time it, read its frames back, compare each with the reference, write its
    frames and heat maps (under `prefix`). Returns its report row and the frames and heat maps for the
    overview. A frame with no pixel to score has no data: it is flagged `empty`, has no error, counts in
    `empty_frames` and stays out of the row's averages (metrics.summarise)."""
    name, what = obj.name, what or obj.name
    cost, frames, aliased = harness.measure(lambda: v.build(harness.ctx), cams, f"{what}: {v.label}")
    scores, heats, enc = scoring.score_frames(frames, refs.filtered, refs.classes, out, f"{prefix}frames/{name}/{v.label}",
                                      f"{prefix}heatmaps/{name}/{v.label}", opts.heat_max, background, opts.flip,
                                      f"{what}: {v.label} scoring")
    row = {"object": name, "technique": v.technique, "knob": v.knob, "value": v.value, "label": v.label,
           "frames": len(cams), "expect_empty": obj.expect_empty, **cost, **summarise(scores),
           **refs.aliased(aliased, frames, background, scores)}
    return row, enc, heats


def render_object(harness, out, bundle, scene, view, chosen, full, opts, device, log, keep: dict | None = None) -> list[dict]:
    """One object's variants from the cameras of `view` (a ViewSet), against its reference and, for their change,
    its full asset (`full`: change.full_asset's variant, drawn untimed where it is not one of `chosen`): their
    report rows; frames, heat maps, reference and overview sheet written under the view's prefix (a screen-size
    sweep's sizes/NNNpx/); keep: also each variant's frames (sRGB, by label) put here."""
    obj, cams, prefix, what = view.obj, view.cams, view.prefix, view.what
    background = scene.render.background
    refs = _references(out, bundle, scene, view, opts, log)
    sheet, rows, frames = [("reference", refs.filtered)], [], {}
    for v in chosen:
        row, enc, heats = _measure(harness, v, cams, refs, out, obj, opts, background, prefix, what)
        rows.append({**row, "device": device, "reference_cached": refs.cached})
        sheet += [(v.label, enc), (f"{v.label} error", heats)]
        frames[v.label] = enc
        log(f"{what}: {v.label:>14}  {scoring.row_line(row)}"
            + (f"  empty frames {row['empty_frames']}/{row['frames']}" if row["empty_frames"] else "")
            + (f"  (border {row['border_px']} px, inside {row['inside_px']} px apart)" if "border_px" in row else ""))
    change.attach(rows, frames, full.label, lambda: full.build(harness.ctx), harness, cams, refs, opts.flip, background)
    if keep is not None:
        keep.update(frames)
    images.overview(sheet, out.file(f"{prefix}overview/{obj.name}.png"), heat_max=opts.heat_max)
    return rows


@dataclass(frozen=True)
class ViewSet:
    """Cameras a run draws from, scored against the reference traced from them (in `folder`): an object's (`obj`;
    one copy at `size` px in the sweep, its files under `prefix` sizes/NNNpx/) or, `obj` None, the composite's;
    `what` names it in the log."""
    obj: object | None
    cams: list
    prefix: str = ""
    what: str = ""
    size: int | None = None

    @property
    def folder(self) -> str:
        return f"{self.prefix}reference/{self.obj.name}" if self.obj else f"{composite.FOLDER}/reference"

    def named(self, spp: int) -> str:
        """How the log names its reference at `spp` samples per pixel."""
        return self.what + (f" ({spp} spp)" if spp > 1 else "")

    def source(self, bundle, scene, spp: int):
        """Its reference at `spp` samples per pixel: (cache key, tracer) for refcache.load_or_trace."""
        if self.obj is None:
            return composite.reference_source(bundle, scene, self.cams, spp)
        return refcache.object_source(self.obj, bundle.manifest["objects"][self.obj.name], bundle, scene, self.cams, spp)


def _sizes(opts: Options, scene) -> list[int]:
    """The screen sizes of the sweep, largest first."""
    return sorted(opts.sizes or (scene.render.sweep.sizes if scene.render.sweep else ()), reverse=True)


def view_sets(bundle, scene, only, sizes, width: int, height: int) -> list[ViewSet]:
    """Every set of views a run draws, in its order, without GL: each object that has a variant to draw, one copy at
    each size of the sweep (the chain is the object's), then from its own cameras; then the composite's, where it
    draws a variant set. run() draws these; vdmrender.cluster traces their references on workers first
    (references)."""
    out = []
    for obj in scene.objects:
        entry = bundle.manifest["objects"][obj.name]
        if not variants(obj, entry, bundle, scene, only):
            continue
        one = dataclasses.replace(obj, instances=None)
        centre, radius = framed(one, entry, scene)
        own = cameras_for(scene.camera, centre, radius, width, height)
        out += [ViewSet(one, sweep.sized(own, centre, radius, size), f"sizes/{size}px/", f"{obj.name} @{size}px", size)
                for size in sizes]
        out.append(ViewSet(obj, cameras_for(scene.camera, *framed(obj, entry, scene), width, height), what=obj.name))
    if composite.variant_sets(scene, only):
        out.append(ViewSet(None, composite.cameras(bundle, scene, width, height), what="composite"))
    return out


def references(bundle, opts: Options) -> list[tuple[ViewSet, str, int]]:
    """Every reference a run of `bundle` under `opts` traces, (view set, folder, samples per pixel): each view set's
    (view_sets) filtered and pixel-centre ones (scoring.folders). Bad input raises InputError as run() does."""
    scene = bundle.scene
    opts = filtering(opts, scene)
    width, height = opts.resolution or scene.render.resolution
    return [(v, folder, spp) for v in view_sets(bundle, scene, _technique_filter(opts, scene), _sizes(opts, scene),
                                                width, height)
            for folder, spp in scoring.folders(v.folder, opts.reference_spp)]


def _references(out, bundle, scene, view: ViewSet, opts: Options, log) -> scoring.References:
    """The references `view` is scored against (refcache.load_or_trace: the previous run's, the shared cache's, or
    traced here)."""
    def load(spp, folder):
        key, trace = view.source(bundle, scene, spp)
        return refcache.load_or_trace(out, folder, key, view.cams, trace, scene.render.background, view.named(spp),
                                      log, opts.reference_cache)
    return scoring.References.traced(load, view.folder, opts.reference_spp, scene.render.background)


@dataclass
class Views:
    """One object's rows: at its cameras (`rows`, with an instanced object's lod@CHAIN rows), at each size of the
    sweep (`sweep`, one copy, with size_px), and the chains chosen from the sweep ({name: lod.object_chains'})."""
    rows: list[dict]
    sweep: list[dict]
    chains: dict


def render_views(harness, out, bundle, scene, obj, views, only, opts, device, log, lod_sets) -> Views:
    """One object, once, from its view sets (view_sets'; none: it draws nothing): its variants at each screen size
    of the sweep (one copy: the chain is the object's), its LOD chains chosen from those rows (vdmrender.deciding.lod, no
    drawing), then its variants from its cameras, an instanced object's also per chain with each copy drawn by the
    variant its screen size selects (lod@CHAIN: vdmrender.views.lodmix)."""
    if not views:
        return Views([], [], {})
    *sized, own = views
    entry = bundle.manifest["objects"][obj.name]
    chosen = variants(obj, entry, bundle, scene, only)
    sweep_rows, frames = _sweep(harness, out, bundle, scene, obj, only, opts, device, log, sized) if sized else ([], {})
    chains = lod.object_chains(sweep_rows, lod_sets, harness.target.size[1], scoring.pops(frames)) \
        if lod_sets else {}
    for name, c in chains.items():
        _log_chain(name, obj.name, c["entries"], log, "from the sweep")
    world = instances.matrices(obj.instances, scene.camera.up, entry["centre"]) if obj.instances else None
    mixes = {name: c["entries"] for name, c in chains.items()} if world is not None else {}
    rows = render_object(harness, out, bundle, scene, own,
                         chosen + [lodmix.mixed(obj, entry, bundle, scene, name, entries, world)
                                   for name, entries in mixes.items()], change.full_asset(obj, entry, bundle, scene),
                         opts, device, log)
    for row in rows:
        if row["technique"] == "lod":
            row["lod_copies"] = lodmix.copies_chosen(entry, world, mixes[row["value"]], own.cams)
    return Views(rows, sweep_rows, chains)


def _sweep(harness, out, bundle, scene, obj, only, opts, device, log, views) -> tuple[list[dict], dict]:
    """An object's variants at each screen size (vdmrender.views.sweep) from `views` (its sized view sets, one copy each):
    rows as render_object's, with size_px; and the frames, {size: {label: sRGB frames}} (the LOD chains' pops)."""
    height = harness.target.size[1]
    entry = bundle.manifest["objects"][obj.name]
    obj = dataclasses.replace(obj, instances=None)   # one copy: the chain is the object's
    chosen = variants(obj, entry, bundle, scene, only)
    full = change.full_asset(obj, entry, bundle, scene)   # one for every size: a mesostructure's is built once
    rows, frames = [], {}
    for view in views:
        size, cams = view.size, view.cams
        distance = round(sweep.distance_for(size, 1.0, cams[0].fov_deg, height), 4)
        here = [{**r, "size_px": size, "distance_radii": distance}
                for r in render_object(harness, out, bundle, scene, view, chosen, full, opts, device, log,
                                       frames.setdefault(size, {}))]
        contest = lod.contenders(here, scene.render.sweep.lod if scene.render.sweep else ())
        if len(contest) > 1:   # the chains' choice decided on frames timed side by side (vdmrender.deciding.pricing)
            times = interleaved.gpu_ms(harness, {v.label: partial(v.build, harness.ctx) for v in chosen
                                                 if v.label in contest}, cams, pricing.MAX_ROUNDS, pricing.settled,
                                       pricing.MIN_ROUNDS)
            for r in here:
                if r["label"] in times:
                    r["interleaved_ms"] = times[r["label"]]
            log(f"{obj.name} @{size}px: {', '.join(sorted(contest))} timed interleaved, "
                f"{len(next(iter(times.values()))) // len(cams)} rounds")
        rows += here
    return rows, frames
