"""make bench, octahedral-impostor part: octahedral impostors against the enhanced billboards at equal
GPU texture bytes, written to JSON and markdown, never asserted.

Models as in bench_billboards (sphere, torus, cone, cylinder primitives and the scanned bunny), 16
cameras each (8 on an orbit at 25 degrees, then top-down, near-top, two grazing, from below, two
close-ups and one inside the bounding sphere), at 800x600 and 400x300. Per model the billboards
(greedy projection, 512^2 maps; the hierarchical trace, hier, with and without the coarse mesh filling
holes; it casts hier's shadows either way) are baked first; the larger variant's GPU asset bytes (bordered
maps, pyramid atlases, coarse mesh and occupancy-box buffers; not the per-frame depth and occupancy
targets, reported apart) fix the octahedral atlases: N x N views of R^2 texels at 8 bytes a texel (RGBA16)
with 8 N^2 R^2 as close as possible to the billboards' bytes, for N = 5, 9, 13, and N = 9 at a quarter
of them. All variants of a model are timed interleaved (vdmrender.measuring.interleaved, one round: per camera one
render each, in turn) after a warm-up to steady times as vdmrender's rows, each pass in its own timer query (vdmrender/measuring/timing.py); the shadow map pass
is part of every frame (billboards: the scene's 1024^2 map of the coarse mesh; octahedral: its own, shadow_scale 2, and one
row with the scene's 1024^2 map for a like-for-like comparison). Octahedral rows also give the frame pass's
texture fetches (atlas lookups, the albedo atlas's, the shadow map's) and search steps per covered pixel
(instrumented, vdmrender/measuring/counters.py, one camera) and the shadow pass's time.

    python -m bench.octahedral -o out/bench [--quick]
"""
from __future__ import annotations

import json
import statistics
from pathlib import Path

import click
import numpy as np

from vdmbake.bundle import parts
from vdmbake.bake import bake, object_mesh
from vdmbake.bundle.directory import Bundle
from vdmbake.scene import load_scene
from vdmbake.techniques.octahedral import VARIANT as OCT_VARIANT

from bench import publish, tables
from vdmrender.measuring import counters, interleaved
from vdmrender.gpu import gl
from vdmrender.common import images
from vdmrender.tracing import reference
from vdmrender import techniques
from vdmrender.common.camera import cameras_for
from vdmrender.comparing.metrics import compare, pooled
from vdmrender.techniques import octahedral
from vdmrender.measuring.timing import Budget, FrameTimer
from vdmrender.passes.shadowmap import ShadowMap
from vdmrender.common.markdown import number

MODELS = [("sphere", 'primitive = "sphere"'), ("torus", 'primitive = "torus"'), ("cone", 'primitive = "cone"'),
          ("cylinder", 'primitive = "cylinder"'), ("bunny", 'mesh = "pkg:pymeshfix/examples/StanfordBunny.ply"')]
RESOLUTIONS = [(800, 600), (400, 300)]
BILLBOARDS = ["greedy-hier", "greedy-hier+coarse"]   # the best billboard variants (issue 9)
SHADOW_MAP = 1024
TEXEL_BYTES = 8   # the atlas texture: RGBA16 unorm

# The cameras after the orbit: (label, azimuth deg, elevation deg, distance in radii, fov deg).
POSES = [("top-down", 0.0, 90.0, 2.6, 40.0), ("near-top", 60.0, 80.0, 2.6, 40.0), ("grazing-0", 15.0, 0.0, 2.6, 40.0),
         ("grazing-5", 105.0, 5.0, 2.6, 40.0), ("below", 200.0, -30.0, 2.6, 40.0), ("close", 300.0, 20.0, 1.4, 50.0),
         ("close-wide", 150.0, 35.0, 1.2, 90.0), ("inside", 240.0, 15.0, 0.95, 70.0)]
ORBIT = 8

SCENE = """
[render]
resolution = [{w}, {h}]
shadow_map = {shadow_map}
[camera]
orbit = {{ count = {orbit}, elevation_deg = 25, azimuth_deg = 30, distance = 2.6, fov_deg = 40 }}
{poses}
[[objects]]
name = "{name}"
{source}
techniques = {{ mesh = {{}}{techniques} }}
"""


def _poses(centre, radius, poses) -> str:
    out = []
    for _, az, el, dist, fov in poses:
        a, e = np.radians(az), np.radians(el)
        eye = centre + dist * radius * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        out.append(f"[[camera.poses]]\neye = {eye.tolist()}\ntarget = {list(map(float, centre))}\nfov_deg = {fov}")
    return "\n".join(out)


def gpu_bytes(renderer) -> tuple[int, int]:
    """(asset, targets): bytes of the textures and buffers a renderer uploads for its asset (maps, pyramid
    atlases, coverage, the coarse mesh's and the occupancy boxes' buffers, the atlas), and of the textures
    it renders into every frame (the occupancy and depth pre-pass targets, at the frame's size; its shadow
    map is neither)."""
    objs = counters.gl_objects(renderer, skip=(ShadowMap,))
    drawn = {id(a) for f in objs if type(f).__name__ == "Framebuffer"
             for a in (*f.color_attachments, f.depth_attachment) if a is not None}
    asset = targets = 0
    for o in objs:
        name = type(o).__name__
        if name in ("Texture", "TextureArray"):
            if id(o) in drawn:
                targets += counters.texture_bytes(o)
            else:
                asset += counters.texture_bytes(o)
        elif name == "Buffer":
            asset += o.size
    return asset, targets


def _equal_bytes_resolution(target: int, views: int) -> int:
    return int(min(16384 // views, max(16, np.sqrt(target / TEXEL_BYTES) // views)))


def _bake(out: Path, tag: str, text: str):
    """Bake the scene (forced); its bundle, scene, only object, the object's entry and bake steps, and its
    variants from the registry by label."""
    path = out / "scenes" / f"{tag}.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    bundle = out / "bundles" / f"{tag}.bundle"
    bake(path, bundle, force=True)
    b, scene = Bundle(bundle), load_scene(path)
    obj = scene.objects[0]
    entry = b.manifest["objects"][obj.name]
    steps = json.loads((bundle / "timing.json").read_text())["steps_s"].get(obj.name, {})
    return b, scene, obj, entry, steps, {v.label: v for v in techniques.variants(obj, entry, b, scene)}


def _model(out: Path, name: str, source: str, quick: bool) -> list[dict]:
    w0, h0 = RESOLUTIONS[-1] if not quick else (200, 150)
    poses = POSES if not quick else POSES[:1] + POSES[5:6]
    orbit = ORBIT if not quick else 2
    bb_res = 512 if not quick else 64
    base = SCENE.format(w=w0, h=h0, shadow_map=SHADOW_MAP, orbit=orbit, poses="", name=name, source=source,
                        techniques="")
    probe = out / "scenes" / f"oct-{name}-probe.toml"
    probe.parent.mkdir(parents=True, exist_ok=True)
    probe.write_text(base)
    centre, radius = object_mesh(load_scene(probe).objects[0], probe.parent).bounding_sphere()
    pose_text = _poses(centre, radius, poses)
    labels = [f"orbit-{k}" for k in range(orbit)] + [p[0] for p in poses]

    def scene_text(techniques):
        return SCENE.format(w=w0, h=h0, shadow_map=SHADOW_MAP, orbit=orbit, poses=pose_text, name=name,
                            source=source, techniques=techniques)

    bb_tech = f", billboards = {{ variants = {json.dumps(BILLBOARDS)}, resolution = {bb_res} }}"
    bbb, scene, obj, entry, bb_steps, bb_variants = _bake(out, f"oct-{name}-billboards", scene_text(bb_tech))
    mesh = bbb.read(entry["mesh"], parts.MESH)
    bb_bake_s = sum(v for k, v in bb_steps.items() if k.startswith("billboards"))
    bb_info = {"billboards": len(entry["techniques"]["billboards"]["greedy"]["faces"]), "map_resolution": bb_res}

    ctx = gl.create_context()
    try:
        bb_bytes = 0
        for v in BILLBOARDS:    # the largest billboard variant's bytes fix the atlases' sizes
            r = bb_variants[f"billboards@{v}"].build(ctx)
            bb_bytes = max(bb_bytes, gpu_bytes(r)[0])
            r.release()
        sizes = {n: _equal_bytes_resolution(bb_bytes, n) for n in (5, 9, 13)}
        small = max(16, sizes[9] // 2)
        oct_values = [f"full-{n}x{r}-march" for n, r in sizes.items()] + [
            f"full-9x{sizes[9]}-virtual", f"hemi-9x{sizes[9]}-march", f"full-9x{small}-march"]
        oct_tech = f", octahedral = {{ variants = {json.dumps(oct_values)} }}"
        octb, _, oobj, oentry, oct_steps, oct_variants = _bake(out, f"oct-{name}-octahedral", scene_text(oct_tech))

        builds = {"mesh": (bb_variants["mesh"].build, 0.0, {})}
        for v in BILLBOARDS:
            builds[f"billboards@{v}"] = (bb_variants[f"billboards@{v}"].build, bb_bake_s, bb_info)
        like = OCT_VARIANT.parse(oct_values[1])     # N = 9 at equal bytes, with the scene's shadow map
        for v in oct_values + [f"{like}@shadow{SHADOW_MAP}"]:
            o = OCT_VARIANT.parse(v.split("@")[0])
            shadow = SHADOW_MAP if "@" in v else octahedral.shadow_size(
                o.resolution, oobj.techniques["octahedral"].shadow_scale, SHADOW_MAP)
            build = (oct_variants[f"octahedral@{v}"].build if "@" not in v else
                     lambda ctx, o=o: octahedral.Octahedral(
                         ctx, octb.read(oentry["techniques"]["octahedral"][o.atlas], parts.OCTAHEDRAL), scene.light,
                         obj.material, SHADOW_MAP, o.method))
            builds[f"octahedral@{v}"] = (build, oct_steps[f"octahedral_{o.atlas}_s"],
                                         {"views": o.views, "view_resolution": o.resolution,
                                          "atlas": o.views * o.resolution, "shadow_map": shadow})
        rows = []
        for w, h in ([(w0, h0)] if quick else RESOLUTIONS):
            rows += _measure(ctx, name, scene, obj, mesh, entry, builds, w, h, labels)
        return rows
    finally:
        ctx.release()


# The cameras by kind (bench cameras' labels); outside: all but the one inside the bounding sphere.
CATEGORIES = [("outside", lambda lab: lab != "inside"), ("orbit", lambda lab: lab.startswith("orbit")),
              ("top", lambda lab: lab in ("top-down", "near-top")),
              ("grazing", lambda lab: lab.startswith("grazing")), ("below", lambda lab: lab == "below"),
              ("close", lambda lab: lab in ("close", "close-wide")), ("inside", lambda lab: lab == "inside")]


def _measure(ctx, name, scene, obj, mesh, entry, builds, w, h, labels) -> list[dict]:
    cams = cameras_for(scene.camera, entry["centre"], entry["radius"], w, h)
    ref = reference.MeshReference(mesh, scene.light, obj.material)
    bg = scene.render.background
    refs = [images.encode(ref.render(c), bg) for c in cams]
    renderers = {label: b(ctx) for label, (b, _, _) in builds.items()}
    target = gl.Target(ctx, w, h)
    timer = FrameTimer(ctx, target)
    scores = {k: [] for k in renderers}

    def seen(label, c, _):   # the frame just timed, scored while it is in the target
        frame = target.read()
        scores[label].append({**compare(images.encode(frame, bg), refs[c]),
                              "nonfinite": int((~np.isfinite(frame)).any(-1).sum())})

    try:   # one round of the loop vdmrender prices with: every variant on each camera in turn, after its warm-up
        samples, _ = interleaved.frames(timer, renderers, cams, Budget(), 1, seen=seen)
        rows = []
        for label, r in renderers.items():
            s, sc = samples[label], scores[label]
            row = {"object": name, "resolution": f"{w}x{h}", "label": label, "device": gl.renderer_name(ctx),
                   "median_ms": round(statistics.median(x.gpu_ms for x in s), 2),
                   "median_cpu_ms": round(statistics.median(x.cpu_ms for x in s), 2), **pooled(sc),
                   "nonfinite": sum(x["nonfinite"] for x in sc),
                   **dict(zip(("gpu_bytes", "target_bytes"), gpu_bytes(r))), "bake_s": builds[label][1], **builds[label][2],
                   "cameras": {lab: {**pooled([x]), "nonfinite": x["nonfinite"], "ms": round(t.gpu_ms, 2),
                                     "cpu_ms": round(t.cpu_ms, 2)} for lab, x, t in zip(labels, sc, s)},
                   "categories": {cat: {**pooled([x for lab, x in zip(labels, sc) if pick(lab)]),
                                        "cpu_ms": round(statistics.median(t.cpu_ms for lab, t in zip(labels, s)
                                                                          if pick(lab)), 2)}
                                  for cat, pick in CATEGORIES if any(pick(lab) for lab in labels)}}
            if label.startswith("octahedral"):
                row["shadow_ms"] = round(statistics.median(x.passes["shadow"] for x in s), 2)
                row.update(_costs(ctx, builds[label][0], cams[0], target))
            rows.append(row)
        return rows
    finally:
        target.release()
        for r in renderers.values():
            r.release()


def _costs(ctx, build, cam, target) -> dict:
    """The frame pass's texture fetches and search steps per covered pixel of one frame, instrumented."""
    with counters.counting(ctx):
        r = build(ctx)
    try:
        c = counters.count_frame(ctx, r, cam, target)
    finally:
        r.release()
    frame, px = c["passes"]["frame"], max(c["covered"], 1)
    return {"fetches_per_pixel": round(frame["fetches"] / px, 1), "steps_per_pixel": round(frame["steps"] / px, 1)}


def _markdown(doc: dict) -> str:
    return f"# Octahedral impostors against enhanced billboards ({doc['device']})\n\n" + tables.octahedral(doc)


@click.command()
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"), show_default=True)
@click.option("--quick", is_flag=True, help="Sphere only, 200x150, 4 cameras, 64-texel billboard maps (a smoke run).")
@click.option("--models", default=None, help="Comma-separated subset of: " + ", ".join(m for m, _ in MODELS))
@publish.option("octahedral-bench")
def main(out: Path, quick: bool, models: str | None, publish_dir: Path | None):
    """Run the octahedral benchmark and write OUT/octahedral.json and OUT/octahedral.md."""
    started = publish.Run("bench.octahedral")
    chosen = MODELS[:1] if quick else [m for m in MODELS if models is None or m[0] in models.split(",")]
    rows = []
    for name, source in chosen:
        for r in _model(out, name, source, quick):
            rows.append(r)
            click.echo(f"{name:8} {r['resolution']:8} {r['label']:42} {r['median_ms']:9.1f} ms {r['median_cpu_ms']:9.1f} CPU ms  dLuv {number(r['mean_dluv'], 3)}  "
                       f"IoU {number(r['iou'], 4)}  {r['gpu_bytes'] / 2**20:6.1f} MB", err=True)
    out.mkdir(parents=True, exist_ok=True)
    device = rows[0]["device"]
    doc = {"device": device, "shadow_map": SHADOW_MAP, "categories": [c for c, _ in CATEGORIES], "rows": rows}
    (out / "octahedral.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "octahedral.md").write_text(_markdown(doc))
    click.echo(f"wrote {out / 'octahedral.json'}, {out / 'octahedral.md'}")
    if publish_dir:
        click.echo(f"published {started.publish(publish_dir, 'octahedral-bench', doc)}")


if __name__ == "__main__":
    main()
