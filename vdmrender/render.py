"""One render run: every object's frames with each technique variant and the reference,
the error of each frame, the time per frame, and the report."""
from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from vdmbake import __version__, code_fingerprint, exr, imported_closure, parts
from vdmbake.bundle import Bundle
from vdmbake.errors import InputError
from vdmbake.staging import StagedDir
from vdmbake.scene import REGISTRY

from . import baseline, borders, composite, gl, images, measure, progress, reference, report, timing
from . import device as gpu
from .camera import cameras_for
from .metrics import compare, flip_values, summarise
from .techniques import Source, mesostructure, variants

# Peak working memory of the reference per pixel, with 2x headroom: tracemalloc measured 242 bytes
# (mesh reference, 512^2 and 1024^2) and 402 bytes (quadric reference, 4JSV at 512^2).
BYTES_PER_PIXEL = 800
# Peak memory of an object's geometry (the reference's Embree scene and the uploaded buffers; llvmpipe
# keeps them in RAM), with about 4x headroom: peak RSS over 80k -> 200k inline spheres (impostor, 48^2)
# grew 2.15 kB per sphere, over 200k -> 800k mesh faces (mesh, 48^2) 150 bytes per face.
BYTES_PER_QUADRIC = 8192
BYTES_PER_FACE = 600


def geometry_bytes(bundle) -> tuple[int, str]:
    """The largest object's geometry memory (every mesh part of the object counted, the quadrics) and a
    description of it, from the manifest alone."""
    worst, what = 0, ""
    for name, entry in bundle.manifest["objects"].items():
        prefix = f"objects/{name}/"
        meshes = [m for rel, m in bundle.manifest["parts"].items() if rel.startswith(prefix) and m["kind"] == "mesh"]
        faces = sum(m["faces"] for m in meshes)
        q = bundle.manifest["parts"][entry["quadrics"]] if entry.get("quadrics") else {"spheres": 0, "cylinders": 0}
        quadrics = q["spheres"] + q["cylinders"]
        need = faces * BYTES_PER_FACE + quadrics * BYTES_PER_QUADRIC
        if need > worst:
            worst, what = need, f"object {name!r}: {faces} mesh faces and {quadrics} spheres and cylinders"
    return worst, what


@dataclass
class Options:
    techniques: tuple[str, ...] | None = None    # render only these (the scene's list otherwise)
    resolution: tuple[int, int] | None = None    # override the scene's
    repeats: int | None = None
    warmup: int | None = None
    warmup_s: float | None = None                # timing.Budget: minimum warm-up time
    sample_s: float | None = None                # timing.Budget: minimum sampling time
    device: str | None = None
    heat_max: float = 10.0                       # delta-Luv at the top of the heat-map colour scale
    flip: bool = True                            # also score each frame with NVIDIA FLIP
    baseline: Path | None = None                 # an earlier run's report.json to compare with
    max_error_increase: float | None = None      # its thresholds (vdmrender.baseline)
    max_slowdown: float | None = None
    compare_devices: bool = False                # compare times with a baseline from another device
    counters: bool = True                        # count each variant's work (vdmrender.counters)


def check_memory(width: int, height: int, available: int | None = None, geometry: tuple[int, str] = (0, "")) -> None:
    """Refuse resolutions and geometry (bytes, what) whose reference and buffers would not fit in memory,
    before any work starts."""
    if available is None:
        available = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    need = width * height * BYTES_PER_PIXEL
    if need + geometry[0] > 0.8 * available:
        raise InputError(f"resolution {width}x{height} ({need / 2**30:.1f} GiB for the reference)"
                         + (f" and the geometry of {geometry[1]} (about {geometry[0] / 2**30:.1f} GiB)" if geometry[0] else "")
                         + f" need more than 80% of the {available / 2**30:.1f} GiB available; lower render.resolution "
                         "or --resolution, or bake fewer or simpler objects.")


def reference_code(mesostructure: bool) -> str:
    """The fingerprint of the code a reference runs: the tracers, the cameras' pixel rays and what
    they import (for a mesostructure, also the displaced mesh it traces), as installed."""
    roots = ["vdmrender.reference", "vdmrender.camera"] + (["vdmrender.techniques.mesostructure"] if mesostructure
                                                           else [])
    return code_fingerprint(imported_closure(roots))


def _reference_key(geometry: dict, cams, light, material, background, code: str) -> str:
    blob = {"code": code, "geometry": geometry, "light": asdict(light), "material": asdict(material),
            "background": list(background),
            "cameras": [[c.eye.tolist(), c.target.tolist(), c.up.tolist(), c.fov_deg, c.width, c.height,
                         c.near, c.far] for c in cams]}
    return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()


def reference_geometry(obj, entry, bundle) -> dict:
    """What an object's reference depends on in the bundle (part hashes, its mesostructure), for cache keys."""
    part = entry.get("mesh") or entry["quadrics"]
    geometry = {"part": bundle.manifest["parts"][part]["sha256"]}
    for key in ("albedo_map", "mesostructure_albedo"):   # colour textures
        if entry.get(key):
            geometry[key] = bundle.manifest["parts"][entry[key]]["sha256"]
    if obj.mesostructure:   # the truly displaced geometry: the base mesh, the maps and how they are mapped
        geometry.update(maps=bundle.manifest["parts"][entry["mesostructure"]]["sha256"],
                        mesostructure=asdict(obj.mesostructure))
    return geometry


def object_reference(obj, entry, bundle, scene):
    """The object's reference tracer (vdmrender.reference), and for a mesostructure object the Embree
    scene of its open border (vdmrender.borders; None otherwise)."""
    if obj.mesostructure:
        src = Source(obj, entry, None, bundle, scene, None)
        return (reference.MeshReference(mesostructure.reference_mesh(src), scene.light, obj.material),
                mesostructure.skirt_scene(src))
    if obj.kind == "surface":
        return reference.MeshReference(bundle.surface(entry), scene.light, obj.material), None
    return reference.QuadricReference(bundle.read(entry["quadrics"], parts.QUADRICS), scene.light, obj.material), None


def cached_reference(out, folder: str, key: str, count: int):
    """The previous run's reference frames and classes in `folder` if they were made under `key`, else None."""
    prev_key = out.previous(f"{folder}/key.txt")
    names = [f"{folder}/{k:03d}" for k in range(count)]
    if not (prev_key.is_file() and prev_key.read_text().strip() == key
            and all(out.previous(n + ".exr").is_file() for n in names)):
        return None
    cached = [exr.read(out.previous(n + ".exr")) for n in names]
    return ([np.stack([p["reference"][c] for c in "RGBA"], -1) for p in cached],
            [p["classes"]["C"].astype(np.uint8) if "classes" in p else None for p in cached])


def save_reference(out, folder: str, key: str, frames, classes, background) -> None:
    """The reference frames as EXR (the cache) and PNG, the pixel classes where there are some, and the key."""
    for k, (f, c) in enumerate(zip(frames, classes)):
        n = f"{folder}/{k:03d}"
        layers = {"reference": {ch: f[..., i] for i, ch in enumerate("RGBA")}}
        if c is not None:   # which pixels see an open border or the inside (vdmrender.borders), as a mask too
            layers["classes"] = {"C": c.astype(np.float32)}
            images.save_rgb(out.file(n + "-classes.png"), np.dstack([borders.COLOURS[c], np.full(c.shape, 255, np.uint8)]))
        exr.write(out.file(n + ".exr"), layers)
        images.save_rgb(out.file(n + ".png"), images.encode(f, background))
    out.file(f"{folder}/key.txt").write_text(key + "\n")


def reference_frames(out, obj, entry, bundle, scene, cams, log) -> tuple[list[np.ndarray], list, dict]:
    """The reference frames (linear RGBA float32) and, for a mesostructure object, each frame's pixel
    classes (vdmrender.borders; None otherwise), traced or taken from the previous run's cache."""
    folder = f"reference/{obj.name}"
    key = _reference_key(reference_geometry(obj, entry, bundle), cams, scene.light, obj.material,
                         scene.render.background, reference_code(obj.mesostructure is not None))
    cached = cached_reference(out, folder, key, len(cams))
    if cached is not None:
        frames, classes = cached
        info = {"cached": True, "trace_s": 0.0}
    else:
        t0 = time.perf_counter()
        ref, skirt = object_reference(obj, entry, bundle, scene)
        frames = [ref.render(c) for c in progress.bar(cams, f"{obj.name}: reference")]
        classes = [borders.classify(c, ref.scene, skirt) if obj.mesostructure else None for c in cams]
        info = {"cached": False, "trace_s": round(time.perf_counter() - t0, 3), "rays": ref.scene.rays_cast}
    save_reference(out, folder, key, frames, classes, scene.render.background)
    log(f"{obj.name}: reference {len(cams)} frames " +
        ("(cached)" if info["cached"] else f"traced in {info['trace_s']:.2f} s, {info['rays']} rays"))
    return frames, classes, info


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


def run(bundle_path: Path, out_path: Path, opts: Options, log=lambda m: None) -> dict:
    bundle = Bundle(bundle_path)
    scene = bundle.scene
    width, height = opts.resolution or scene.render.resolution
    plan = budget(opts, scene)
    only = _technique_filter(opts, scene)
    old = baseline.load(opts.baseline) if opts.baseline else None
    check_memory(width, height, geometry=geometry_bytes(bundle))
    ctx = gl.create_context(opts.device)
    device = gl.renderer_name(ctx)
    why_not = old and baseline.times_comparable(old, {"time": "gpu", "device": device}, opts.compare_devices)
    if why_not and opts.max_slowdown is not None:
        ctx.release()
        raise InputError(f"--max-slowdown with --baseline {opts.baseline}: {why_not}.")
    device_info, nvml = gpu.describe(ctx), gpu.nvml_clocks()
    out = StagedDir(out_path, "report.json", "vdmrender output folder")
    harness = measure.Harness(ctx, gl.Target(ctx, width, height), plan, opts.counters)
    try:
        rows = _render_all(harness, out, bundle, scene, only, opts, device, log)
        report.add_baseline_ratios(rows)
        composite_rows = composite.render_sets(harness, out, bundle, scene, only, opts, device, log)
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
                  "flip": "NVIDIA FLIP (LDR, 67 pixels per degree) of the sRGB frames, averaged over the same "
                          "pixels as the error (flip_mean pools a variant's frames like mean_dluv)" if opts.flip else "not computed",
                  "heatmap_max_dluv": opts.heat_max, "rows": rows}
        if composite_rows:   # render.composite: every object in one frame, per variant set (vdmrender.composite)
            result["composite"] = composite_rows
        if old is not None:
            result["baseline"] = {"report": str(opts.baseline),
                                  **baseline.compare(old, result, opts.max_error_increase, opts.max_slowdown,
                                                     opts.compare_devices)}
        report.write(out.tmp, result)
        out.commit()
    except BaseException:
        out.abort()
        raise
    finally:
        harness.release()
        ctx.release()
    return result


def _measure(harness, v, cams, ref8, classes, out, obj, opts, background):
    """One variant: time it, read its frames back, compare each with the reference, write its
    frames and heat maps. Returns its report row and the frames and heat maps for the overview.
    A frame with no pixel to score has no data: it is flagged `empty`, has no error, counts in
    `empty_frames` and stays out of the row's averages (metrics.summarise)."""
    name = obj.name
    cost, frames = harness.measure(lambda: v.build(harness.ctx), cams, f"{name}: {v.label}")
    scores, heats, enc = score_frames(frames, ref8, classes, out, f"frames/{name}/{v.label}",
                                      f"heatmaps/{name}/{v.label}", opts.heat_max, background, opts.flip,
                                      f"{name}: {v.label} scoring")
    row = {"object": name, "technique": v.technique, "knob": v.knob, "value": v.value, "label": v.label,
           "frames": len(cams), "expect_empty": obj.expect_empty, **cost, **summarise(scores)}
    return row, enc, heats


def score_frames(frames, ref8, classes, out, frame_dir: str, heat_dir: str, heat_max, background, flip, desc: str):
    """Each frame against its reference: its scores (metrics.compare, with FLIP, coverage and non-finite
    pixels), and its sRGB frame and heat map, also written as FRAME_DIR/NNN.png and HEAT_DIR/NNN.png."""
    scores, heats, enc = [], [], []
    for k, (f, r8, cls) in enumerate(progress.bar(list(zip(frames, ref8, classes)), desc)):
        f8 = images.encode(f, background)
        c = compare(f8, r8, cls)
        c.update(flip=flip_values(f8, r8, c["scored"]) if flip else np.zeros(0),
                 coverage=float((r8[..., 3] > 0).mean()), nonfinite=int((~np.isfinite(f)).any(-1).sum()))
        heat = images.heatmap(c["dist"], heat_max)
        images.save_rgb(out.file(f"{frame_dir}/{k:03d}.png"), f8)
        images.save_rgb(out.file(f"{heat_dir}/{k:03d}.png"), heat)
        scores.append(c)
        heats.append(heat)
        enc.append(f8)
    return scores, heats, enc


def _show(x, width: int, digits: int) -> str:
    return f"{'-':>{width}}" if x is None else f"{x:{width}.{digits}f}"


def time_line(row: dict) -> str:
    """A row's time as the log shows it: GPU median, spread, wall time, and a flag when not steady or noisy."""
    flags = [f for f, bad in (("not steady", row["steady"] is False), ("noisy", row["spread_warning"]),
                              ("wall time: query saturated", row["saturated"])) if bad]
    px = row.get("per_pixel")
    return (f"{row['median_ms']:9.3f} ms/frame GPU (±{row['spread_ms']:.3f}, wall {row['wall_ms']:.3f})"
            + (f" [{', '.join(flags)}]" if flags else "")
            + (f"  per px: {px['fragments']:.2f} frag {px['fetches']:.1f} fetch {px['steps']:.1f} step"
               if px and px["fragments"] is not None else ""))


def _render_all(harness, out, bundle, scene, only, opts, device, log) -> list[dict]:
    width, height = harness.target.size
    rows = []
    for obj in scene.objects:
        entry = bundle.manifest["objects"][obj.name]
        cams = cameras_for(scene.camera, entry["centre"], entry["radius"], width, height)
        chosen = variants(obj, entry, bundle, scene, only)
        if not chosen:
            continue
        ref_frames, ref_classes, ref_info = reference_frames(out, obj, entry, bundle, scene, cams, log)
        ref8 = [images.encode(f, scene.render.background) for f in ref_frames]
        sheet = [("reference", ref8)]
        for v in chosen:
            row, enc, heats = _measure(harness, v, cams, ref8, ref_classes, out, obj, opts, scene.render.background)
            rows.append({**row, "device": device, "reference_cached": ref_info["cached"]})
            sheet += [(v.label, enc), (f"{v.label} error", heats)]
            log(f"{obj.name}: {v.label:>14}  {time_line(row)}  mean dLuv {_show(row['mean_dluv'], 7, 3)}"
                f"  p95 {_show(row['p95_dluv'], 7, 3)}  IoU {_show(row['iou'], 6, 4)}  FLIP {_show(row['flip_mean'], 6, 4)}"
                + (f"  empty frames {row['empty_frames']}/{row['frames']}" if row["empty_frames"] else "")
                + (f"  (border {row['border_px']} px, inside {row['inside_px']} px apart)" if "border_px" in row else ""))
        images.overview(sheet, out.file(f"overview/{obj.name}.png"))
    return rows
