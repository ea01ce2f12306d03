"""Colour maps (issue 12), the report's measurements; writes OUT/colour-notes.json and prints markdown.

1. Bakes docs/bbcol-scripts/colour.toml (textured bunny, vertex-coloured airplane) and an uncoloured copy
   (the same meshes without their map / colours): part sizes of each technique, with and without colour.
2. Renders the coloured bundle with vdmrender (every variant against the coloured reference; overview).
3. In one process, interleaved (A, B, A, B, ...), ROUNDS rounds over both cameras: billboards
   hier+coarse and octahedral with their colour against the same renderer from the
   same bundle with the colour left out (colour maps dropped, the coarse mesh's colours dropped): CPU-time
   and wall-time medians per frame, error against the coloured reference.

    PYTHONPATH=. python docs/bbcol-scripts/measure.py OUT
"""
from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROUNDS = 5


def sh(*args):
    print("+", " ".join(map(str, args)), flush=True)
    subprocess.run([sys.executable, "-m", *map(str, args)], check=True)


def plain_assets(out: Path) -> str:
    """The scene with uncoloured copies of its meshes (positions and faces only, as PLY: an OBJ with UVs and
    no MTL gets trimesh's default 2x2 grey texture, which the loader takes for an albedo map), written next to
    it; returns the scene's path."""
    import trimesh

    from vdmbake.assets.meshes import resolve_path

    for name, spec in (("bunny", "bunny10k_textured.obj"), ("airplane", "colored_airplane.ply")):
        m = trimesh.load(resolve_path(f"pkg:pymeshlab/tests/sample_meshes/{spec}", Path(".")), process=False, force="mesh")
        trimesh.Trimesh(m.vertices, m.faces, process=False).export(out / f"{name}-plain.ply")
    text = (HERE / "colour.toml").read_text()
    text = text.replace("pkg:pymeshlab/tests/sample_meshes/bunny10k_textured.obj", "bunny-plain.ply")
    text = text.replace("pkg:pymeshlab/tests/sample_meshes/colored_airplane.ply", "airplane-plain.ply")
    (out / "plain.toml").write_text(text)
    return str(out / "plain.toml")


def sizes(bundle: Path) -> dict:
    m = json.loads((bundle / "manifest.json").read_text())
    out = {}
    for name, obj in m["objects"].items():
        t = obj["techniques"]
        rels = {"mesh": obj["mesh"], "albedo-map": obj.get("albedo_map"), "billboards": t["billboards"]["greedy"]["maps"],
                "bordered-billboards": t["billboards"]["greedy"]["bordered"], "billboards coarse": t["billboards"]["coarse"],
                "octahedral": next(iter(t["octahedral"].values())), "coarse@0.1": t["coarse"]["meshes"][0]["mesh"]}
        out[name] = {k: (m["parts"][r]["bytes"] if r else 0) for k, r in rels.items()}
        out[name]["bundle"] = sum(p["bytes"] for p in m["parts"].values())
    return out


def interleaved(bundle_path: Path, render_dir: Path) -> dict:
    from bench import interleave
    from vdmbake.bundle import parts
    from vdmbake.bundle.directory import Bundle
    from vdmbake.assets.meshes import TriMesh
    from vdmrender.gpu import gl
    from vdmrender.common.camera import cameras_for
    from vdmrender.techniques import Source
    from vdmrender.techniques.billboards_hier import HierBillboards
    from vdmrender.techniques.octahedral import Octahedral, shadow_size

    bundle = Bundle(bundle_path)
    scene = bundle.scene
    ctx = gl.create_context()
    out = {}
    for obj in scene.objects:
        entry = bundle.manifest["objects"][obj.name]
        w, h = scene.render.resolution
        cams = cameras_for(scene.camera, entry["centre"], entry["radius"], w, h)
        ref8 = interleave.reference8(render_dir, obj.name, len(cams), scene.render.background)
        src = Source(obj, entry, entry["techniques"]["billboards"], bundle, scene, None)
        g = src.part["greedy"]
        boards = bundle.read(g["maps"], parts.BILLBOARDS)
        maps = bundle.read(g["bordered"], parts.BORDERED)
        coarse = bundle.surface(entry, src.part["coarse"])
        plain_maps = [replace(m, albedo=None) for m in maps]
        plain_coarse = TriMesh(coarse.vertices, coarse.faces, coarse.normals)
        bounds = (entry["centre"], entry["radius"])
        atlas = bundle.read(next(iter(entry["techniques"]["octahedral"].values())), parts.OCTAHEDRAL)
        shadow = scene.render.shadow_map
        oct_shadow = shadow_size(atlas.resolution, 2.0, shadow)
        builds = {
            "hier+coarse colour": lambda c: HierBillboards(c, boards, maps, scene.light, obj.material, shadow, coarse,
                                                           bounds, shadow_mesh=coarse),
            "hier+coarse plain": lambda c: HierBillboards(c, boards, plain_maps, scene.light, obj.material, shadow,
                                                          plain_coarse, bounds, shadow_mesh=coarse),
            "octahedral colour": lambda c: Octahedral(c, atlas, scene.light, obj.material, oct_shadow),
            "octahedral plain": lambda c: Octahedral(c, replace(atlas, albedo=None), scene.light, obj.material, oct_shadow),
        }
        out[obj.name] = interleave.measure(ctx, builds, cams, ref8, scene.render.background, ROUNDS)
        print(obj.name, json.dumps(out[obj.name], indent=1), flush=True)
    ctx.release()
    return out


def main(out: Path):
    out.mkdir(parents=True, exist_ok=True)
    plain_scene = plain_assets(out)
    sh("vdmbake.cli", HERE / "colour.toml", "-o", out / "colour.bundle")
    sh("vdmbake.cli", plain_scene, "-o", out / "plain.bundle")
    result = {"sizes": {"colour": sizes(out / "colour.bundle"), "plain": sizes(out / "plain.bundle")}}
    if not (out / "colour" / "report.json").is_file():   # kept from an earlier run of the same bundle
        sh("vdmrender.cli", out / "colour.bundle", "-o", out / "colour")
    result["report"] = [{k: r[k] for k in ("object", "label", "median_ms", "mean_dluv", "p95_dluv", "iou", "flip_mean")}
                        for r in json.loads((out / "colour" / "report.json").read_text())["rows"]]
    timed = out / "interleaved.json"
    if not timed.is_file():
        timed.write_text(json.dumps(interleaved(out / "colour.bundle", out / "colour"), indent=1))
    result["interleaved"] = json.loads(timed.read_text())
    (out / "colour-notes.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
