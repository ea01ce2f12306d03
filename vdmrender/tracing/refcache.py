"""The reference frames of a run: what they depend on (the cache key: the bundle's parts, the scene's
light, material and cameras, and the code the tracers run), their tracer, and the cache that reuses the
previous run's frames when nothing they depend on changed."""
from __future__ import annotations

import hashlib
import json
import time
import weakref
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from vdmbake import code_fingerprint, imported_closure
from vdmbake.common import instances
from vdmbake.formats import exr
from vdmbake.bundle import parts
from vdmbake.bundle.staging import StagedDir

from . import borders, reference
from ..common import images, mesostructure, progress
from ..common.source import Source


# What every reference runs: the tracers, the cameras' pixel rays and the placing of an object's copies.
REFERENCE_ROOTS = ("vdmrender.tracing.reference", "vdmrender.common.camera", "vdmbake.common.instances")


def reference_code(mesostructure: bool) -> str:
    """The fingerprint of the code a reference runs: REFERENCE_ROOTS and what they import (for a mesostructure,
    also the displaced mesh it traces), as installed."""
    roots = list(REFERENCE_ROOTS) + (["vdmrender.common.mesostructure"] if mesostructure else [])
    return code_fingerprint(imported_closure(roots))


def reference_key(geometry: dict, cams, light, material, background, code: str, spp: int = 1) -> str:
    """The cache key of a reference: what it traces, under which light, material, background and cameras,
    at how many samples per pixel, with which code."""
    blob = {"code": code, "geometry": geometry, "light": asdict(light), "material": asdict(material), "spp": spp,
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
    if obj.instances:
        geometry["instances"] = asdict(obj.instances)
    if obj.mesostructure:   # the truly displaced geometry: the base mesh, the maps and how they are mapped
        geometry.update(maps=bundle.manifest["parts"][entry["mesostructure"]]["sha256"],
                        mesostructure=asdict(obj.mesostructure))
    return geometry


# Per open bundle, the last object reference built: a sweep's sizes and the filtered and point references of an
# object trace one, built once (a mesostructure's displaced mesh and its Embree scene take seconds); gone with the
# bundle, and dropped before another is built (the memory rule counts one object's at a time: bundle.budget).
_LAST = weakref.WeakKeyDictionary()


def object_reference(obj, entry, bundle, scene):
    """The object's reference tracer (vdmrender.tracing.reference), and for a mesostructure object the Embree
    scene of its open border (vdmrender.tracing.borders; None otherwise); the same ones again while nothing they trace
    changed (_LAST). Their rays_cast counts every ray they traced: a caller counts its own as a difference."""
    key = json.dumps([obj.name, reference_geometry(obj, entry, bundle), asdict(scene.light), asdict(obj.material),
                      list(scene.camera.up)], sort_keys=True)
    last = _LAST.get(bundle)
    if last is not None and last[0] == key:
        return last[1]
    del last
    _LAST.pop(bundle, None)   # the previous object's gone before this one's is built
    _LAST[bundle] = (key, _object_reference(obj, entry, bundle, scene))
    return _LAST[bundle][1]


def _object_reference(obj, entry, bundle, scene):
    if obj.mesostructure:
        src = Source(obj, entry, None, bundle, scene, None)
        return (reference.MeshReference(mesostructure.reference_mesh(src), scene.light, obj.material),
                mesostructure.skirt_scene(src))
    if obj.kind == "surface":
        mesh = bundle.surface(entry)
        if obj.instances:   # every copy, merged (the memory guard counts them: render.held_geometry)
            mesh = instances.placed(mesh, instances.matrices(obj.instances, scene.camera.up, entry["centre"]))
        return reference.MeshReference(mesh, scene.light, obj.material), None
    q = bundle.read(entry["quadrics"], parts.QUADRICS)
    if obj.instances:   # every copy, merged (the memory guard counts them: render.held_geometry)
        q = instances.placed_quadrics(q, instances.matrices(obj.instances, scene.camera.up, entry["centre"]))
    return reference.QuadricReference(q, scene.light, obj.material), None


def _halves(layers: dict) -> reference.Halves | None:
    """A cached frame's Halves (reference.filtered): layers `half` and `samples`; None at 1 spp."""
    if "half" not in layers:
        return None
    return reference.Halves(np.stack([layers["half"][c] for c in "RGBA"], -1),
                            layers["samples"]["N"].astype(np.int32), layers["samples"]["A"].astype(np.int32))


def _read_frame(path: Path) -> tuple:
    """A reference frame as _write_frame wrote it: (frame, Halves or None, classes or None)."""
    p = exr.read(path)
    return (np.stack([p["reference"][c] for c in "RGBA"], -1), _halves(p),
            p["classes"]["C"].astype(np.uint8) if "classes" in p else None)


def _write_frame(path: Path, frame, halves, classes) -> None:
    """A reference frame as EXR, with its Halves (layers `half`: the first half's mean, and `samples`: each
    pixel's samples N, of which A in the first half) and its pixel classes where there are some."""
    layers = {"reference": {ch: frame[..., i] for i, ch in enumerate("RGBA")}}
    if halves is not None:   # the frame's noise (vdmrender.comparing.scoring.noise)
        layers["half"] = {ch: halves.first[..., i] for i, ch in enumerate("RGBA")}
        layers["samples"] = {"N": halves.traced.astype(np.float32), "A": halves.in_first.astype(np.float32)}
    if classes is not None:   # which pixels see an open border or the inside (vdmrender.tracing.borders)
        layers["classes"] = {"C": classes.astype(np.float32)}
    exr.write(path, layers)


def _frames(count: int) -> list[str]:
    return [f"{k:03d}.exr" for k in range(count)]


def previously(root: Path, folder: str, key: str, count: int) -> bool:
    """Whether the output folder `root` (the previous run's) holds the reference in `folder` made under `key`."""
    prev_key = Path(root, folder, "key.txt")
    return (prev_key.is_file() and prev_key.read_text().strip() == key
            and all(Path(root, folder, n).is_file() for n in _frames(count)))


def save_reference(out, folder: str, key: str, frames, halves, classes, background) -> None:
    """The reference frames as EXR (_write_frame: the cache) and PNG, the pixel classes also as a mask where there
    are some, and the key."""
    for k, (f, h, c) in enumerate(zip(frames, halves, classes)):
        n = f"{folder}/{k:03d}"
        if c is not None:
            images.save_rgb(out.file(n + "-classes.png"), np.dstack([borders.COLOURS[c], np.full(c.shape, 255, np.uint8)]))
        _write_frame(out.file(n + ".exr"), f, h, c)
        images.save_rgb(out.file(n + ".png"), images.encode(f, background))
    if halves and halves[0] is not None:   # what the run's filtering block reports (samples_traced)
        out.file(f"{folder}/samples.json").write_text(json.dumps(
            {"pixels": sum(h.traced.size for h in halves), "samples": sum(int(h.traced.sum()) for h in halves)}) + "\n")
    out.file(f"{folder}/key.txt").write_text(key + "\n")


@dataclass(frozen=True)
class Shared:
    """The reference cache by content key (--reference-cache, docs/cluster.md): FOLDER/KEY/NNN.exr and trace.json,
    in a folder every cluster worker and the client can read, each entry written whole (vdmbake.bundle.staging) by
    whoever traces it first. `run` names the run: what its own reference tasks traced is reported as traced by
    it (rows' reference_cached false, as on one machine), what an earlier run left as cached."""
    folder: str
    run: str

    def read(self, key: str, count: int) -> tuple[list, list, list, dict] | None:
        """The frames, Halves and classes of the entry `key`, and its info as load_or_trace's; None if absent."""
        entry = Path(self.folder, key)
        if not ((entry / "trace.json").is_file() and all((entry / n).is_file() for n in _frames(count))):
            return None
        frames, halves, classes = map(list, zip(*(_read_frame(entry / n) for n in _frames(count))))
        traced = json.loads((entry / "trace.json").read_text())
        ours = traced.pop("run") == self.run
        return frames, halves, classes, {"cached": not ours, **(traced if ours else {"trace_s": 0.0})}

    def trace(self, key: str, cams, trace, what: str) -> tuple[list, list, list, dict]:
        """The reference traced (_trace) into entry `key`, staged from the start: a writer killed mid-trace leaves
        only its hidden sibling, which the next writer of the key removes (vdmbake.bundle.staging.recover)."""
        entry = StagedDir(Path(self.folder, key), "trace.json", "reference cache entry")
        try:
            frames, halves, classes, info = _trace(cams, trace, what)
            for n, f, h, c in zip(_frames(len(frames)), frames, halves, classes):
                _write_frame(entry.file(n), f, h, c)
            entry.file("trace.json").write_text(json.dumps(
                {"run": self.run, "trace_s": info["trace_s"], "rays": info["rays"]}) + "\n")
            entry.commit()
        except BaseException:
            entry.abort()
            raise
        return frames, halves, classes, info


def _trace(cams, trace, what: str) -> tuple[list, list, list, dict]:
    t0 = time.perf_counter()
    frames, halves, classes, rays = trace(progress.bar(cams, f"{what}: reference"))
    return frames, halves, classes, {"cached": False, "trace_s": round(time.perf_counter() - t0, 3), "rays": rays}


def _logged(log, what: str, count: int, info: dict) -> None:
    log(f"{what}: reference {count} frames " +
        ("(cached)" if info["cached"] else f"traced in {info['trace_s']:.2f} s, {info['rays']} rays"))


def samples_traced(root) -> dict:
    """The samples per pixel the filtered references under `root` (a run's output folder) actually traced
    (reference.filtered's adaptive sampling), pooled over every pixel of every frame: report.json's
    filtering.reference_mean_spp; empty where no reference was filtered."""
    counts = [json.loads(p.read_text()) for p in sorted(root.glob("**/samples.json"))]
    pixels = sum(c["pixels"] for c in counts)
    return {"reference_mean_spp": round(sum(c["samples"] for c in counts) / pixels, 3)} if pixels else {}


def load_or_trace(out, folder: str, key: str, cams, trace, background, what: str, log,
                  shared: Shared | None = None) -> tuple[list, list, dict]:
    """The reference frames in `folder` (linear RGBA float32) and their pixel classes (None where not
    classified): the previous run's where made under `key`, else the shared cache's (`shared`), else traced by
    `trace(cams)` -> (frames, Halves, classes, rays cast) and put in the shared cache; saved (the next run's
    cache) and logged as WHAT. info["halves"]: each frame's Halves (reference.filtered), None at 1 spp."""
    if previously(out.path, folder, key, len(cams)):
        frames, halves, classes = map(list, zip(*(_read_frame(out.previous(f"{folder}/{n}"))
                                                  for n in _frames(len(cams)))))
        info = {"cached": True, "trace_s": 0.0}
    elif shared is None:
        frames, halves, classes, info = _trace(cams, trace, what)
    else:
        frames, halves, classes, info = shared.read(key, len(cams)) or shared.trace(key, cams, trace, what)
    info["halves"] = halves
    save_reference(out, folder, key, frames, halves, classes, background)
    _logged(log, what, len(cams), info)
    return frames, classes, info


def share(shared: Shared, key: str, cams, trace, what: str) -> dict | None:
    """A reference task of a cluster run (vdmrender.cluster): the reference traced into the shared cache unless it
    is there already; the trace's info as load_or_trace's (trace_s, rays), None where it was there."""
    return None if shared.read(key, len(cams)) is not None else shared.trace(key, cams, trace, what)[3]


def object_source(obj, entry, bundle, scene, cams, spp: int = 1):
    """One object's reference from `cams` at `spp` samples per pixel (reference.filtered): its cache key, and its
    tracer for load_or_trace, which also gives a mesostructure object's pixel classes (vdmrender.tracing.borders: open
    border, inside; of the pixel centres)."""
    key = reference_key(reference_geometry(obj, entry, bundle), cams, scene.light, obj.material,
                        scene.render.background, reference_code(obj.mesostructure is not None), spp)

    def trace(cams):
        ref, skirt = object_reference(obj, entry, bundle, scene)
        before = ref.scene.rays_cast
        frames, halves = zip(*(reference.filtered(ref.render, c, spp) for c in cams))
        classes = [borders.classify(c, ref.scene, skirt, ref.sphere) if obj.mesostructure else None for c in cams]
        return list(frames), list(halves), classes, ref.scene.rays_cast - before

    return key, trace
