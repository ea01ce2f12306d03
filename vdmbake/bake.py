"""The bake: what each object's techniques need, and nothing more, written as a bundle.

A surface object (mesh file or primitive) gets its full mesh: the reference traces it and
the `mesh` technique draws it; `coarse` adds one simplified mesh per requested ratio.
A quadrics object (molecule or inline spheres/cylinders) gets only its quadric list:
nothing is ray cast at bake time. Each part is baked only when a technique asks for it.
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

from . import __version__, coarse, primitives, quadrics
from .bundle import FORMAT_VERSION, Bundle, BundleWriter
from .errors import InputError
from .meshes import TriMesh, file_sha256, load_mesh_file, resolve_path, transformed, validate
from .scene import Object, Scene, load_scene


def object_mesh(obj: Object, base: Path) -> TriMesh:
    """The object's full-resolution mesh in world space."""
    if obj.primitive:
        mesh = primitives.build(obj.primitive, obj.params)
    else:
        mesh = load_mesh_file(resolve_path(obj.mesh, base))
    world = transformed(mesh, obj.transform)
    return validate(world, f"object {obj.name!r}")


def object_quadrics(obj: Object, base: Path) -> tuple[quadrics.QuadricSet, dict]:
    """The object's spheres and cylinders in world space, and counts of what was dropped."""
    if obj.molecule:
        from .molecules import load_molecule  # gemmi is imported only for molecule scenes
        q = load_molecule(resolve_path(obj.molecule, base), obj.style)
    else:
        q = quadrics.inline(obj.spheres, obj.cylinders, obj.material.albedo)
    origin = f"object {obj.name!r}"
    return quadrics.cleaned(quadrics.transformed(q, obj.transform, origin), origin)


def input_hash(scene: Scene, base: Path) -> tuple[str, dict]:
    """One hash over the resolved scene, the input files' contents and the format/tool versions."""
    files = [f for o in scene.objects for f in (o.mesh, o.molecule) if f]
    inputs = {f: file_sha256(resolve_path(f, base)) for f in files}
    key = json.dumps({"format_version": FORMAT_VERSION, "tool_version": __version__,
                      "scene": scene.to_dict(), "inputs": inputs}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest(), inputs


def up_to_date(out: Path, digest: str) -> bool:
    """A complete bundle baked from the same inputs and settings, every part intact."""
    try:
        bundle = Bundle(out)
        if bundle.manifest.get("input_hash") != digest:
            return False
        for rel in bundle.manifest["parts"]:
            bundle.read_bytes(rel)
        return True
    except InputError:
        return False


def bake(scene_path: Path, out: Path, force: bool = False, log=lambda msg: None) -> dict:
    """Bake the scene into the bundle at `out`; returns the manifest's statistics (or that it was up to date)."""
    scene_path = Path(scene_path)
    scene = load_scene(scene_path)
    base = scene_path.parent
    digest, inputs = input_hash(scene, base)
    if not force and up_to_date(out, digest):
        log(f"{out}: up to date (inputs and settings unchanged); use --force to bake again")
        return {"up_to_date": True, "bundle": str(out)}
    writer = BundleWriter(out)
    try:
        objects, timing, t_all = {}, {}, time.perf_counter()
        for obj in scene.objects:
            t0 = time.perf_counter()
            objects[obj.name] = _bake_object(writer, obj, base, log)
            timing[obj.name] = round(time.perf_counter() - t0, 4)
        stats = {"objects": len(objects), "parts": len(writer.parts),
                 "bytes": sum(p["bytes"] for p in writer.parts.values())}
        writer.commit({"scene": scene.to_dict(), "input_hash": digest, "inputs": inputs,
                       "objects": objects, "stats": stats},
                      {"bake_s": round(time.perf_counter() - t_all, 4), "objects_s": timing})
    except BaseException:
        writer.abort()
        raise
    return {"up_to_date": False, "bundle": str(out), **stats, "bake_s": round(time.perf_counter() - t_all, 3)}


def _bake_object(writer: BundleWriter, obj: Object, base: Path, log) -> dict:
    if obj.kind == "quadrics":
        q, dropped = object_quadrics(obj, base)
        centre, radius = q.bounding_sphere()
        rel = writer.add_bytes(f"objects/{obj.name}/quadrics.ply", quadrics.to_bytes(q), "quadrics",
                               spheres=len(q.spheres), cylinders=len(q.cylinders))
        log(f"{obj.name}: {len(q.spheres)} spheres, {len(q.cylinders)} cylinders"
            + (f" (dropped without volume: {dropped})" if any(dropped.values()) else ""))
        return {"quadrics": rel, "centre": centre.tolist(), "radius": radius, **dropped}
    mesh = object_mesh(obj, base)
    centre, radius = mesh.bounding_sphere()
    entry = {"mesh": writer.add_mesh(f"objects/{obj.name}/mesh.ply", mesh),
             "centre": centre.tolist(), "radius": radius}
    log(f"{obj.name}: {len(mesh.faces)} faces")
    if "coarse" in obj.techniques:
        entry["coarse"] = {}
        for ratio in obj.techniques["coarse"]["ratios"]:
            c = coarse.simplify(mesh, ratio)
            entry["coarse"][f"{ratio:g}"] = writer.add_mesh(f"objects/{obj.name}/coarse-{ratio:g}.ply", c, "coarse")
            log(f"{obj.name}: coarse {ratio:g} -> {len(c.faces)} faces")
    return entry
