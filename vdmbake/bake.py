"""The bake: what each object's techniques need, and nothing more, written as a bundle.

Every object gets what its reference needs: a surface object (mesh file or primitive) its full
mesh, a quadrics object (molecule or inline spheres/cylinders) its quadric list, and an object
with a mesostructure its height field and normal map. Then each technique it names bakes its own
parts through its declaration (vdmbake/techniques/): coarse meshes, VDM tables, displaced meshes,
billboards. Nothing else is baked or ray cast.
"""
from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from . import __version__, code_fingerprint, package_modules
from .library import cache as part_cache
from .kernels import curvature, quadric_mesh, quadrics, vdm
from .assets import heightfields, meso_albedo, primitives
from .bundle import parts, staging
from .common import instances
from .bundle.directory import FORMAT_VERSION, MANIFEST, Bundle, BundleWriter, RefusedBundle, update_scene
from .errors import InputError
from .assets.meshes import file_sha256, load_mesh_file, resolve_path
from .common.mesh import transformed, validate
from .common.mesh import TriMesh
from .assets.references import reached_files
from .scene import Object, Scene, load_scene
from .schema import dump
from .techniques import REGISTRY


def object_mesh(obj: Object, base: Path, warn=None) -> TriMesh:
    """The object's full-resolution mesh in world space; `warn` hears what of the file was left out (printed to
    stderr if None)."""
    if obj.primitive:
        mesh = primitives.build(obj.primitive, obj.params)
    else:
        mesh = load_mesh_file(resolve_path(obj.mesh, base), obj.textures == "use", warn, root=assets_root(obj, base))
    world = transformed(mesh, obj.transform)
    return validate(world, f"object {obj.name!r}")


def object_quadrics(obj: Object, base: Path, warn=lambda m: None) -> tuple[quadrics.QuadricSet, dict]:
    """The object's spheres and cylinders in world space, and counts of what was dropped; `warn` hears
    what of the input file was ignored to read it."""
    if obj.molecule:
        from .assets.molecules import load_molecule  # gemmi is imported only for molecule scenes
        q = load_molecule(resolve_path(obj.molecule, base), obj.style, warn)
    else:
        q = quadrics.inline(obj.spheres, obj.cylinders, obj.material.albedo)
    origin = f"object {obj.name!r}"
    return quadrics.cleaned(quadrics.transformed(q, obj.transform, origin), origin)


def bake_code() -> str:
    """The fingerprint of the bake's code: every source file of the vdmbake package as installed, so
    a local edit or an upgrade (say to vdmbake/kernels/vdm.py) makes every bundle baked before it stale."""
    return code_fingerprint(package_modules(__name__.partition(".")[0]))


def assets_root(obj: Object, base: Path) -> Path:
    """The folder inside which the files the object's mesh file names may lie (besides its own folder): the scene's
    `assets` folder, else the scene file's (base)."""
    return base / obj.assets if obj.assets else base


RENDER_ONLY = "render"   # the scene's table the bake never reads: how vdmrender renders, measures and decides


def input_hash(scene: Scene, base: Path, code: str | None = None) -> tuple[str, dict]:
    """One hash over the resolved scene but for its render settings (RENDER_ONLY: changing the anti-aliasing, the
    reference's samples or the sweep re-bakes nothing), the input files' contents, the format/tool versions and
    the bake code's fingerprint (`code`, bake_code() by default). The input files include what each mesh file
    reaches (its MTL, textures, glTF buffers), keyed by the chain of names that reaches them
    (`bunny.obj > bunny.mtl > bunny.png`)."""
    files = [o.molecule for o in scene.objects if o.molecule]
    for m in (o.mesostructure for o in scene.objects if o.mesostructure):   # height and albedo pictures
        files += [spec for spec, patterns in ((m.height, heightfields.PATTERNS), (m.albedo, meso_albedo.PATTERNS))
                  if spec and _is_file(spec, patterns)]
    inputs = {f: file_sha256(resolve_path(f, base)) for f in files}
    for o in (o for o in scene.objects if o.mesh):
        for chain, f in reached_files(resolve_path(o.mesh, base), o.mesh, o.textures == "use",
                                      assets_root(o, base)).items():
            inputs[" > ".join(chain)] = hashlib.sha256(f.data).hexdigest()
    baked = {k: v for k, v in scene.to_dict().items() if k != RENDER_ONLY}
    key = json.dumps({"format_version": FORMAT_VERSION, "tool_version": __version__, "code": code or bake_code(),
                      "scene": baked, "inputs": inputs}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest(), inputs


def _is_file(spec: str, patterns) -> bool:
    return spec not in patterns and not spec.startswith("skimage:")


def object_inputs(obj: Object, base: Path) -> dict:
    """The sha256 of every file the object reads, keyed as input_hash keys them (the part cache's key)."""
    files = [obj.molecule] if obj.molecule else []
    if obj.mesostructure:
        m = obj.mesostructure
        files += [spec for spec, patterns in ((m.height, heightfields.PATTERNS), (m.albedo, meso_albedo.PATTERNS))
                  if spec and _is_file(spec, patterns)]
    inputs = {f: file_sha256(resolve_path(f, base)) for f in files}
    if obj.mesh:
        for chain, f in reached_files(resolve_path(obj.mesh, base), obj.mesh, obj.textures == "use",
                                      assets_root(obj, base)).items():
            inputs[" > ".join(chain)] = hashlib.sha256(f.data).hexdigest()
    return inputs


def stale(out: Path, digest: str, code: str) -> str | None:
    """Why the bundle at `out` must be baked (again), or None if it is complete, baked from the same
    inputs and settings by the same code, and every part is intact."""
    try:
        bundle = Bundle(out)
        if bundle.manifest.get("input_hash") != digest:
            old = bundle.manifest.get("code_fingerprint")
            return (f"baked by other code: bake code {str(old)[:12]}, now {code[:12]}" if old != code
                    else "inputs or settings changed")
        for rel in bundle.manifest["parts"]:
            bundle.read_bytes(rel)
        return None
    except InputError as e:
        return "no bundle yet" if not Path(out).exists() else f"unusable ({e})"


@dataclass
class Job:
    """What a technique's bake step gets (vdmbake.schema.Technique.bake): its object and settings,
    what the object's own bake made, and where to write."""
    obj: Object
    options: Any                            # the technique's settings (its Options dataclass)
    mesh: TriMesh | None                    # surface objects: the full mesh, world space (with its frame
                                            # under a mesostructure)
    stored_mesh: TriMesh | None             # the same as the bundle holds it (what the renderer reads)
    maps: parts.MesostructureMaps | None    # objects with a mesostructure: as stored in the bundle
    writer: BundleWriter
    log: Callable[[str], None]
    steps: dict                             # wall seconds of long steps, for timing.json

    def write(self, name: str, kind: parts.PartKind, value) -> str:
        """Store `value` as the object's part `name` (suffix added); returns its path in the bundle."""
        return self.writer.add(f"objects/{self.obj.name}/{name}", kind, value)


def bake(scene_path: Path, out: Path, force: bool = False, log=lambda msg: None,
         cache: part_cache.PartCache | None = None) -> dict:
    """Bake the scene into the bundle at `out`; returns the manifest's statistics (or that it was up to date).
    With a part cache (vdmbake.library.cache), each step's parts are taken from it when it holds them, and stored in
    it when baked; the bundle's bytes are the same either way (timing.json says which parts came from it)."""
    scene_path = Path(scene_path)
    scene = load_scene(scene_path)
    base = scene_path.parent
    code = bake_code()
    digest, inputs = input_hash(scene, base, code)
    _recover(out, log)
    reason = "--force" if force else stale(out, digest, code)
    if reason is None:
        if update_scene(out, scene.to_dict()):
            log(f"{out}: up to date (inputs, settings and bake code unchanged); its render settings rewritten in "
                "the manifest, no part baked again")
        else:
            log(f"{out}: up to date (inputs, settings and bake code unchanged); use --force to bake again")
        return {"up_to_date": True, "bundle": str(out)}
    log(f"{out}: baking ({reason})")
    try:
        try:
            return _write(scene, scene_path, out, digest, code, inputs, log, cache)
        except RefusedBundle as e:
            if cache is None or not cache.counters.taken:
                raise
            n = part_cache.refuse_taken(cache)     # an entry passed its own checks but not the bundle's
            log(f"{out}: {e}; the {n} cache entries it took removed, baking without them")
            return _write(scene, scene_path, out, digest, code, inputs, log, cache)
    finally:
        if cache is not None:
            cache.record(scene=str(scene_path))


def _recover(out: Path, log) -> None:
    """What an interrupted run left at `out` put right (vdmbake.bundle.staging.recover); each staging folder of a
    bake whose writer is gone (vdmbake.bundle.staging: its process no longer runs, or on another machine its lease
    went stale) that this removed, or put back as the bundle, is named in the log."""
    for did, kind, pid, name, why in staging.recover(out, MANIFEST):
        if kind == "tmp":
            log(f"{out}: {did} {name}, left by a bake that did not finish ({why})")


def _write(scene: Scene, scene_path: Path, out: Path, digest: str, code: str, inputs: dict, log,
           cache: part_cache.PartCache | None) -> dict:
    """The bundle of `scene` written at `out` (bake's work once it is known to be stale): its statistics."""
    base = scene_path.parent
    writer = BundleWriter(out)
    try:
        objects, timing, steps, t_all = {}, {}, {}, time.perf_counter()
        for obj in scene.objects:
            t0 = time.perf_counter()
            objects[obj.name] = entry = _bake_object(writer, obj, base, log, steps.setdefault(obj.name, {}), cache)
            if obj.instances is not None:    # copies the reference cannot hold are refused as the object would be
                instances.check(instances.matrices(obj.instances, scene.camera.up, entry["centre"]), entry["centre"],
                                entry["radius"], f"object {obj.name!r}")
            timing[obj.name] = round(time.perf_counter() - t0, 4)
        stats = {"objects": len(objects), "parts": len(writer.parts),
                 "bytes": sum(p["bytes"] for p in writer.parts.values())}
        record = {"bake_s": round(time.perf_counter() - t_all, 4), "objects_s": timing,
                  "steps_s": {k: v for k, v in steps.items() if v}}
        took = {}                                  # not in the manifest: its bytes are the same with or without a cache
        if cache is not None:
            c = cache.counters
            took = {"parts_from_cache": c.parts_from_cache, "steps_from_cache": c.hits, "steps_baked": c.misses}
            record["cache"] = {"dir": str(cache.root), "steps": dict(c.events), "steps_from_cache": c.hits,
                               "steps_baked": c.misses, "corrupt_entries": c.corrupt,
                               "parts_from_cache": c.parts_from_cache}
        writer.commit({"scene": scene.to_dict(), "input_hash": digest, "code_fingerprint": code, "inputs": inputs,
                       "objects": objects, "stats": stats}, record)
    except BaseException:
        writer.abort()
        raise
    return {"up_to_date": False, "bundle": str(out), **stats, **took, "bake_s": round(time.perf_counter() - t_all, 3)}


def _bake_object(writer: BundleWriter, obj: Object, base: Path, log, steps: dict,
                 cache: part_cache.PartCache | None) -> dict:
    """The object's manifest entry: what its reference needs, then each technique's own parts; each of these
    steps through `cache` when the bake has one (vdmbake.library.cache.run_step), else is baked."""
    say = lambda m: log(f"{obj.name}: {m}")  # noqa: E731
    prefix = f"objects/{obj.name}/"
    obj_dict = dump(obj)
    okey = part_cache.object_key(obj_dict, object_inputs(obj, base)) if cache is not None else None
    made = {}     # what the object step gives the technique steps: (mesh, stored mesh, maps), once it ran here

    def own(log_) -> dict:
        entry, made["base"] = _object_parts(writer, obj, base, log_)
        return entry

    def prepare() -> None:
        """A technique step to bake after the object's parts came from the cache: its inputs, made again (the
        same bytes are written again)."""
        if "base" not in made:
            made["base"] = _object_parts(writer, obj, base, lambda m: None)[1]

    entry = part_cache.run_step(cache, writer, okey, prefix, obj.name, own, say)
    entry["techniques"] = {}
    for name, options in obj.techniques.items():
        technique = REGISTRY[name]
        if technique.bake is None:
            continue
        tkey = part_cache.technique_key(okey, name, obj_dict["techniques"][name]) if okey else None

        def step(log_, technique=technique, options=options):
            return technique.bake(Job(obj, options, *made["base"], writer, log_, steps))
        entry["techniques"][name] = part_cache.run_step(cache, writer, tkey, prefix, f"{obj.name}/{name}", step, say,
                                                        prepare, technique=name)
    return entry


def _object_parts(writer: BundleWriter, obj: Object, base: Path, say) -> tuple[dict, tuple]:
    """The object's own parts (what its reference needs) written, and its manifest entry without the techniques;
    with what the technique steps read: (mesh, stored mesh, mesostructure maps)."""
    mesh = stored_mesh = maps = None
    if obj.kind == "quadrics":
        q, dropped = object_quadrics(obj, base, lambda m: say(f"warning: {m}"))
        centre, radius = q.bounding_sphere()
        entry = {"kind": obj.kind, "centre": centre.tolist(), "radius": radius,
                 "quadrics": writer.add(f"objects/{obj.name}/quadrics", parts.QUADRICS, q), **dropped}
        say(f"{len(q.spheres)} spheres, {len(q.cylinders)} cylinders"
            + (f" (dropped without volume: {dropped})" if any(dropped.values()) else ""))
        if obj.viewer_mesh is not None:
            entry["viewer_mesh"] = writer.add(f"objects/{obj.name}/viewer-mesh", parts.VIEWER_MESH,
                                              quadric_mesh.tessellate(q, obj.viewer_mesh))
    else:
        mesh = object_mesh(obj, base, lambda m: say(f"warning: {m}"))
        if mesh.uvs is not None and not np.isfinite(mesh.uvs).all():
            if obj.mesostructure:
                raise InputError(f"object {obj.name!r}: {int((~np.isfinite(mesh.uvs)).any(1).sum())} vertices have NaN "
                                 "or Inf texture coordinates, which the mesostructure is mapped by; fix the mesh's UVs.")
            mesh.uvs = None                        # nothing else reads them
        if obj.mesostructure:
            if mesh.uvs is None:
                raise InputError(f"object {obj.name!r}: a mesostructure needs a base mesh with texture coordinates "
                                 "(the built-in primitives have them; export a mesh file with UVs, e.g. OBJ vt).")
            if mesh.frame is None:   # a mesh file, or a primitive under a non-uniform scale: estimated, world space
                mesh.frame = curvature.estimate_frame(mesh.vertices, mesh.faces, mesh.normals, mesh.uvs)
        centre, radius = mesh.bounding_sphere()
        rel, stored_mesh = writer.add_read(f"objects/{obj.name}/mesh", parts.MESH, mesh)
        entry = {"kind": obj.kind, "centre": centre.tolist(), "radius": radius, "mesh": rel}
        if mesh.texture is not None:   # the asset's own colour, read by every technique that shades it
            entry["albedo_map"] = writer.add(f"objects/{obj.name}/albedo", parts.ALBEDO_MAP, mesh.texture)
        say(f"{len(mesh.faces)} faces" + (f", albedo map {mesh.texture.shape[1]}x{mesh.texture.shape[0]}"
                                          if mesh.texture is not None else ""))
        if obj.mesostructure:
            m = obj.mesostructure
            heights = heightfields.from_spec(m.height, m.size, base).astype(np.float32)
            maps = parts.MesostructureMaps(heights, vdm.height_normals(heights.astype(np.float64), m.depth)
                                           .astype(np.float32))
            entry["mesostructure"] = writer.add(f"objects/{obj.name}/mesostructure", parts.MESOSTRUCTURE, maps)
            if m.albedo:   # the tile's colour, read by every mesostructure technique and the reference
                tile = meso_albedo.from_spec(m.albedo, m.size, base)
                entry["mesostructure_albedo"] = writer.add(f"objects/{obj.name}/mesostructure-albedo", parts.ALBEDO_MAP,
                                                           tile)
                say(f"mesostructure albedo {tile.shape[1]}x{tile.shape[0]}")
    return entry, (mesh, stored_mesh, maps)
