"""The bake: what each object's techniques need, and nothing more, written as a bundle.

A surface object (mesh file or primitive) gets its full mesh: the reference traces it and
the `mesh` technique draws it; `coarse` adds one simplified mesh per requested ratio.
A surface object with a mesostructure also gets its height field, and, only if it names the
`vdm` technique, the VDM/MVM tables: sampled over the curvature range its base mesh has, ray
cast, compressed to the largest k the scene renders.
A quadrics object (molecule or inline spheres/cylinders) gets only its quadric list:
nothing is ray cast at bake time. Each part is baked only when a technique asks for it.
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import numpy as np

from . import __version__, coarse, curvature, heightfields, primitives, quadrics, texspace, vdm
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
    files += [o.mesostructure.height for o in scene.objects if o.mesostructure and _is_file(o.mesostructure.height)]
    inputs = {f: file_sha256(resolve_path(f, base)) for f in files}
    key = json.dumps({"format_version": FORMAT_VERSION, "tool_version": __version__,
                      "scene": scene.to_dict(), "inputs": inputs}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest(), inputs


def _is_file(height: str) -> bool:
    return height not in heightfields.PATTERNS and not height.startswith("skimage:")


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
        objects, timing, steps, t_all = {}, {}, {}, time.perf_counter()
        for obj in scene.objects:
            t0 = time.perf_counter()
            objects[obj.name] = _bake_object(writer, obj, base, log, steps.setdefault(obj.name, {}))
            timing[obj.name] = round(time.perf_counter() - t0, 4)
        stats = {"objects": len(objects), "parts": len(writer.parts),
                 "bytes": sum(p["bytes"] for p in writer.parts.values())}
        writer.commit({"scene": scene.to_dict(), "input_hash": digest, "inputs": inputs,
                       "objects": objects, "stats": stats},
                      {"bake_s": round(time.perf_counter() - t_all, 4), "objects_s": timing,
                       "steps_s": {k: v for k, v in steps.items() if v}})
    except BaseException:
        writer.abort()
        raise
    return {"up_to_date": False, "bundle": str(out), **stats, "bake_s": round(time.perf_counter() - t_all, 3)}


def _bake_object(writer: BundleWriter, obj: Object, base: Path, log, steps: dict) -> dict:
    """The object's parts and manifest entry; wall times of long steps go into `steps` (timing.json)."""
    if obj.kind == "quadrics":
        q, dropped = object_quadrics(obj, base)
        centre, radius = q.bounding_sphere()
        rel = writer.add_bytes(f"objects/{obj.name}/quadrics.ply", quadrics.to_bytes(q), "quadrics",
                               spheres=len(q.spheres), cylinders=len(q.cylinders))
        log(f"{obj.name}: {len(q.spheres)} spheres, {len(q.cylinders)} cylinders"
            + (f" (dropped without volume: {dropped})" if any(dropped.values()) else ""))
        return {"quadrics": rel, "centre": centre.tolist(), "radius": radius, **dropped}
    mesh = object_mesh(obj, base)
    if obj.mesostructure:
        if mesh.uvs is None:
            raise InputError(f"object {obj.name!r}: a mesostructure needs a base mesh with texture coordinates "
                             "(the built-in primitives have them; export a mesh file with UVs, e.g. OBJ vt).")
        if mesh.frame is None:   # a mesh file, or a primitive under a non-uniform scale: estimated, world space
            mesh.frame = curvature.estimate_frame(mesh.vertices, mesh.faces, mesh.normals, mesh.uvs)
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
    if obj.mesostructure:
        entry["mesostructure"] = _bake_mesostructure(writer, obj, mesh, base, log, steps)
    if "billboards" in obj.techniques:
        entry["billboards"] = _bake_billboards(writer, obj, mesh, log, steps)
    return entry


def _bake_billboards(writer: BundleWriter, obj: Object, mesh: TriMesh, log, steps: dict) -> dict:
    """Enhanced billboards (thesis ch. 3) for each projection the variants name, and the coarse mesh
    only if a variant fills holes with it. Maps: alpha, depth (0..1 of the box depth), world normal."""
    from . import billboard_maps, billboards

    opts = obj.techniques["billboards"]
    variants = opts["variants"]
    out = {}
    for mode in ("greedy", "axis"):
        if not any(v.startswith(mode + "-") for v in variants):
            continue
        t0 = time.perf_counter()
        res = billboards.bake(mesh, billboards.Settings(mode=mode, resolution=int(opts["resolution"])),
                              log=lambda m: log(f"{obj.name}: {mode} billboards: {m}"))
        steps[f"billboards_{mode}_s"] = round(time.perf_counter() - t0, 3)
        parts = {f"bb{i:03d}": {"A": b.alpha, "depth.Z": b.depth, **{f"normal.{a}": b.normal[..., k]
                                                                      for k, a in enumerate("XYZ")}}
                 for i, b in enumerate(res.billboards)}
        rel = writer.add_exr(f"objects/{obj.name}/billboards-{mode}.exr", parts, "billboards")
        out[mode] = {"maps": rel, "leftover": res.leftover, "candidates": res.candidates, "rays": res.rays,
                     "boards": [{"origin": b.origin.tolist(), "axes": b.axes.tolist(), "size": b.size.tolist(),
                                 "faces": len(b.faces)} for b in res.billboards]}
        log(f"{obj.name}: {mode} billboards: {len(res.billboards)} from {res.candidates} candidate directions, "
            f"{writer.parts[rel]['bytes'] / 2**20:.2f} MB; faces left out {res.leftover}")
        if any(v.startswith(mode + "-hier") for v in variants):   # the hierarchical march's maps and pyramids
            t0 = time.perf_counter()
            parts = billboard_maps.to_parts(res.billboards)
            steps[f"billboards_{mode}_hier_s"] = round(time.perf_counter() - t0, 3)
            out[mode]["hier"] = writer.add_exr(f"objects/{obj.name}/billboards-{mode}-hier.exr", parts, "billboards")
            out[mode]["pyramid_bytes"] = sum(a.nbytes for k, p in parts.items() if ".L" in k for a in p.values())
            log(f"{obj.name}: {mode} billboards: pyramids {out[mode]['pyramid_bytes'] / 2**20:.2f} MB (float32) in "
                f"{steps[f'billboards_{mode}_hier_s']:.2f} s")
    # the coarse mesh fills holes (+coarse) and casts the hierarchical march's shadows
    if any(v.endswith("+coarse") or "-hier" in v for v in variants):
        c = coarse.simplify(mesh, opts["coarse_ratio"])
        out["coarse"] = writer.add_mesh(f"objects/{obj.name}/billboards-coarse.ply", c, "coarse")
        log(f"{obj.name}: billboards' coarse mesh {len(c.faces)} faces")
    return out


def _bake_mesostructure(writer: BundleWriter, obj: Object, mesh: TriMesh, base: Path, log, steps: dict) -> dict:
    """The height field and, if `vdm` is rendered, the compressed VDM/MVM tables (sec. 3.1-3.3)."""
    m = obj.mesostructure
    heights = heightfields.from_spec(m.height, m.size, base)
    name = obj.name
    out = {"height": writer.add_exr(f"objects/{name}/height.exr", {"height": {"h": heights.astype(np.float32)}},
                                    "height")}
    if "vdm" not in obj.techniques:
        return out
    lo, hi = texspace.curvature_range(mesh.frame, mesh.normals, m.tiling)
    sampling = vdm.Sampling(m.size, m.phi, m.theta, vdm.curvature_samples(lo, hi, m.curvatures))
    t0 = time.perf_counter()
    table, theta_mvm, rays = vdm.bake_tables(heights, m.depth, sampling)
    t1 = time.perf_counter()
    ks = obj.techniques["vdm"]["k"]
    k = table.shape[3] * table.shape[4] + table.shape[4] if "all" in ks else max(ks)
    comp = vdm.compress(table, theta_mvm, k, report=[x for x in ks if x != "all"])
    t2 = time.perf_counter()
    n, k = m.size, comp.W.shape[-1]
    W = comp.W.transpose(2, 0, 1, 3).reshape(m.phi * n, n, k)          # rows: phi-major blocks of y
    parts = {"W": {f"W.{i:03d}": W[..., i] for i in range(k)},
             "E_vdm": {f"E.{i:03d}": comp.E_vdm[i].T for i in range(k)},   # rows c, columns theta
             "E_mvm": {f"E.{i:03d}": comp.E_mvm[i][None] for i in range(k)}}
    rel = writer.add_exr(f"objects/{name}/vdm.exr", parts, "vdm")
    out.update({
        "vdm": rel, "k": k, "rank": comp.rank, "curvatures": list(sampling.curvatures), "rays": rays,
        "table_bytes": table.nbytes + theta_mvm.nbytes,
        "compressed_bytes": comp.W.nbytes + comp.E_vdm.nbytes + comp.E_mvm.nbytes,
        "errors": {str(kk): {f: round(getattr(e, f), 6) for f in ("energy", "rms_vdm", "rms_mvm", "max_abs_vdm")}
                   for kk, e in comp.errors.items()}})
    steps.update(vdm_tables_s=round(t1 - t0, 3), vdm_svd_s=round(t2 - t1, 3))
    log(f"{name}: VDM {n}^2 x {m.phi} phi x {m.theta} theta x {len(sampling.curvatures)} curvatures "
        f"[{lo:.3g}, {hi:.3g}], {rays:,} rays in {t1 - t0:.2f} s; SVD k = {k} (rank {comp.rank}) in {t2 - t1:.2f} s, "
        f"{out['table_bytes'] / 2**20:.1f} MB -> {out['compressed_bytes'] / 2**20:.2f} MB")
    return out
