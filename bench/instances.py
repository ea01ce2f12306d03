"""make bench-instances: many copies of one object (issue 23), the case impostors exist for. Per asset, one bake
(the full mesh, coarse meshes, hierarchical billboards with the coarse mesh filling holes and casting the
shadows, octahedral impostors), then fields of N copies (N = 1, 10, 100, 1000, 10000) at a
constant density (one copy per (SPACING r)^2 of ground, r the bounding radius, seeded turns and scales 0.8-1.2),
seen by two cameras standing at the field's edge and looking across it (copies from near to far, as in a real
scene). Every variant is timed interleaved (bench.interleave: GPU timer queries after a warm-up, medians), with its
GPU bytes and per-pixel work (vdmrender.measuring.counters), and scored against the reference that traces every copy merged
while that fits the memory budget (vdmbake.bundle.budget.render_bytes, the render's own rule); beyond it the
error is not measured, and said so. A variant whose frame would take longer than FRAME_BUDGET_S at the next
N (its time growing with N) is not run there. Per-copy LOD (row lod@dluvLIMIT): one copy measured at SIZES pixels
across (vdmrender.views.sweep's cameras, the same interleaved timing, its own reference) gives the chain of the cheapest
variant within mean ΔLuv LIMIT per band of screen sizes (vdmrender.deciding.lod.chain); in every field each copy is then
drawn per frame by the variant its screen size selects (vdmrender.views.lodmix.LodMix), as an engine would. The crossover:
the smallest N at which each impostor's median time is below the full mesh's.

    python -m bench.instances -o out/bench [--quick] [--publish docs/results]
"""
from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import click
import numpy as np

from vdmbake.bake import bake
from vdmbake.bundle import budget
from vdmbake.bundle.directory import Bundle
from vdmbake.common import instances
from vdmbake.scene import Instances, Scatter

from vdmrender.gpu import gl
from vdmrender.common import images
from vdmrender.deciding import lod
from vdmrender.views import lodmix, sweep
from vdmrender.tracing import refcache
from vdmrender.common.camera import Camera, cameras_for, clip_planes
from vdmrender.techniques import variants

from . import publish, tables
from .interleave import costs, measure

ASSETS = {"scan": ('mesh = "pkg:pymeshfix/examples/StanfordBunny.ply"', 'coarse = { ratios = [0.1, 0.01] }'),
          "bunny": ('mesh = "pkg:pymeshlab/tests/sample_meshes/bunny10k_textured.obj"\n'
                    'transform = { rotate_deg = [90, 0, 0] }', 'coarse = { ratios = [0.1] }')}
COUNTS = (1, 10, 100, 1000, 10000)
SPACING = 3.0                       # ground per copy: (SPACING r)^2
FRAME_BUDGET_S = 20.0               # wall time per frame a variant may be expected to take at the next N
RESOLUTION = (960, 540)
SIZES = (256, 64, 16)               # screen sizes of the one-copy sweep that picks the LOD chain, pixels across
LIMIT = 3.0                         # the chain's limit on mean ΔLuv

SCENE = """
[render]
resolution = [{w}, {h}]
shadow_map = 2048
[[objects]]
name = "{name}"
{source}
[objects.techniques]
mesh = {{}}
{coarse}
billboards = {{ variants = ["greedy-hier+coarse"], resolution = {boards}, coarse_ratio = 0.1 }}
octahedral = {{ variants = ["full-9x128-march", "full-9x64-virtual"] }}
"""


def field(n: int, radius: float) -> Instances:
    side = SPACING * radius * np.sqrt(n)
    return Instances(scatter=Scatter(count=n, area=(side, side), scale=(0.8, 1.2), seed=n))


def cameras(centre, radius: float, n: int, w: int, h: int) -> list[Camera]:
    """Two eyes at the field's edge, a little above it, looking across it towards its far corner and side."""
    half = 0.5 * SPACING * radius * np.sqrt(n)
    up = np.array([0.0, 0.0, 1.0])
    cams = []
    for corner in ((-1.0, -1.0), (1.0, -1.0)):
        eye = centre + np.array([corner[0] * (half + 2.5 * radius), corner[1] * (half + 2.5 * radius),
                                 1.2 * radius + 0.15 * half])
        target = centre - np.array([corner[0], corner[1], 0.0]) * 0.3 * half
        reach = np.linalg.norm(eye - centre) + 1.5 * half * 1.5 + 2 * radius
        near, far = clip_planes(eye, target, centre, reach)
        cams.append(Camera(eye, target, up, 60.0, w, h, max(near, 0.05 * radius), far))
    return cams


def run(out: Path, quick: bool, log) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    w, h = (160, 90) if quick else RESOLUTION
    counts, sizes = ((1, 4), (16,)) if quick else (COUNTS, SIZES)
    assets = {"sphere": ('primitive = "sphere"', 'coarse = { ratios = [0.1] }')} if quick else ASSETS
    ctx = gl.create_context()
    device = gl.renderer_name(ctx)
    rows, bakes = [], {}
    try:
        for name, (source, coarse) in assets.items():
            scene_path, bundle_path = out / f"instances-{name}.toml", out / f"instances-{name}.bundle"
            scene_path.write_text(SCENE.format(w=w, h=h, name=name, source=source, coarse=coarse,
                                               boards=32 if quick else 256))
            t0 = time.perf_counter()
            bake(scene_path, bundle_path, force=True)
            bundle = Bundle(bundle_path)
            timing = json.loads((bundle_path / "timing.json").read_text())
            bakes[name] = {"bake_s": round(time.perf_counter() - t0, 2), "steps_s": timing["steps_s"].get(name, {})}
            obj, entry = bundle.scene.objects[0], bundle.manifest["objects"][name]
            faces = bundle.manifest["parts"][entry["mesh"]]["faces"]
            entries = chain(ctx, bundle, obj, entry, sizes, quick, log)
            bakes[name]["chain"] = [{k: e[k] for k in ("variant", "min_px", "max_px", "meets")} for e in entries]
            chain_name = f"dluv{LIMIT:g}"
            mixed = f"lod@{chain_name}"
            too_slow: set[str] = set()
            for n in counts:
                copies = dataclasses.replace(obj, instances=field(n, entry["radius"]))
                cams = cameras(np.asarray(entry["centre"]), entry["radius"], n, w, h)
                chosen = [v for v in variants(copies, entry, bundle, bundle.scene) if v.label not in too_slow]
                ref8, traced = None, None
                need = budget.Render(w, h, len(cams), objects=(budget.Geometry(name, faces * n),))   # 1 spp
                if budget.fits(budget.render_bytes(need)):
                    t0 = time.perf_counter()
                    ref, _ = refcache.object_reference(copies, entry, bundle, bundle.scene)
                    ref8 = [images.encode(ref.render(c), bundle.scene.render.background) for c in cams]
                    traced = round(time.perf_counter() - t0, 2)
                builds = {v.label: v.build for v in chosen}
                if mixed not in too_slow:   # as vdmrender draws the row lod@CHAIN
                    world = instances.matrices(copies.instances, bundle.scene.camera.up, entry["centre"])
                    builds[mixed] = lodmix.mixed(copies, entry, bundle, bundle.scene, chain_name, entries, world).build
                measured = measure(ctx, builds, cams, ref8 or [None] * len(cams), bundle.scene.render.background,
                                   rounds=1 if quick else 3, score=ref8 is not None)
                for label, build in builds.items():
                    m = measured[label]
                    c = costs(ctx, build, cams[:1])
                    rows.append({"asset": name, "faces": faces, "copies": n, "label": label,
                                 "technique": label.split("@")[0],
                                 **m, "gpu_bytes": c["bytes"], "primitives": c["total"]["primitives"],
                                 "fragments_px": round(c["total"]["fragments"] / max(c["covered"], 1), 2),
                                 "reference_s": traced,
                                 "error": "measured" if ref8 is not None else
                                 f"not measured: {n} x {faces} faces merged exceed the memory budget"})
                    log(f"{name} x{n}: {label:>32} {m['median_ms']:10.2f} ms  "
                        + (f"mean dLuv {m['mean_dluv']:.3f}" if m.get("mean_dluv") is not None else "(no reference)"))
                    grow = counts[counts.index(n) + 1] / n if n != counts[-1] else 1
                    if m["median_wall_ms"] * grow > FRAME_BUDGET_S * 1e3:   # its next frame would be over the budget
                        too_slow.add(label)
    finally:
        ctx.release()
    result = {"device": device, "resolution": [w, h], "counts": list(counts), "sizes": list(sizes),
              "limit": LIMIT, "bakes": bakes, "rows": rows, "crossover": crossover(rows),
              "how": __doc__.split("\n\n")[0]}
    (out / "instances.json").write_text(json.dumps(result, indent=1) + "\n")
    (out / "instances.md").write_text(tables.instances(result))
    plot(out / "instances.png", result)
    return result


def chain(ctx, bundle, obj, entry, sizes, quick: bool, log) -> list[dict]:
    """The LOD chain of one copy: every variant timed interleaved and scored against the copy's reference at each
    screen size (vdmrender.views.sweep's cameras around the bench scene's own views), the cheapest within LIMIT per
    band (vdmrender.deciding.lod.chain, costs compared on the paired frames as vdmrender's chains): lod.json's
    entries."""
    one = dataclasses.replace(obj, instances=None)
    scene = bundle.scene
    w, h = scene.render.resolution
    centre, radius = np.asarray(entry["centre"]), entry["radius"]
    views = cameras_for(scene.camera, centre, radius, w, h)
    ref, _ = refcache.object_reference(one, entry, bundle, scene)
    chosen = variants(one, entry, bundle, scene)
    rows = []
    for size in sizes:
        cams = sweep.sized(views, centre, radius, size)
        ref8 = [images.encode(ref.render(c), scene.render.background) for c in cams]
        measured = measure(ctx, {v.label: v.build for v in chosen}, cams, ref8, scene.render.background,
                           rounds=1 if quick else 3)
        rows += [{"size_px": size, "label": v.label, "technique": v.technique, "value": v.value, "spread_ms": None,
                  **measured[v.label]} for v in chosen]
    entries = lod.chain(rows, {"mean_dluv": LIMIT}, h)["entries"]
    log(f"{obj.name}: chain within mean dLuv {LIMIT:g}: "
        + ", ".join(f"({e['min_px']}, {e['max_px']}] {e['variant']}" for e in entries))
    return entries


def crossover(rows) -> dict:
    """Per asset and impostor-like variant: the smallest count at which it is faster than the full mesh."""
    out = {}
    for asset in dict.fromkeys(r["asset"] for r in rows):
        mine = [r for r in rows if r["asset"] == asset]
        mesh = {r["copies"]: r["median_ms"] for r in mine if r["technique"] == "mesh"}
        for label in dict.fromkeys(r["label"] for r in mine if r["technique"] != "mesh"):
            faster = [r["copies"] for r in mine if r["label"] == label and r["copies"] in mesh
                      and r["median_ms"] < mesh[r["copies"]]]
            out.setdefault(asset, {})[label] = min(faster) if faster else None
    return out


def plot(path: Path, result) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    assets = list(dict.fromkeys(r["asset"] for r in result["rows"]))
    labels = list(dict.fromkeys(r["label"] for r in result["rows"]))   # one colour per variant in every panel
    colour = {label: plt.get_cmap("tab10")(i % 10) for i, label in enumerate(labels)}
    fig, axes = plt.subplots(2, len(assets), figsize=(6 * len(assets), 8), squeeze=False)
    for k, asset in enumerate(assets):
        mine = [r for r in result["rows"] if r["asset"] == asset]
        for label in dict.fromkeys(r["label"] for r in mine):
            pts = [r for r in mine if r["label"] == label]
            style = dict(color=colour[label], label=label, linestyle="--" if label.startswith("lod@") else "-")
            axes[0, k].plot([r["copies"] for r in pts], [r["median_ms"] for r in pts], "o", **style)
            err = [r for r in pts if r.get("mean_dluv") is not None]
            axes[1, k].plot([r["copies"] for r in err], [r["mean_dluv"] for r in err], "o", **style)
        for ax, what in ((axes[0, k], "median GPU time per frame [ms]"), (axes[1, k], "mean ΔL*u*v* (merged reference)")):
            ax.set_xscale("log")
            ax.set_xlabel("copies")
            ax.set_ylabel(what)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
        axes[0, k].set_yscale("log")
        axes[0, k].set_title(f"{asset}, {result['resolution'][0]}x{result['resolution'][1]}", fontsize=10)
    fig.suptitle(f"copies of one object on {result['device']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


@click.command()
@click.option("-o", "--out", type=click.Path(path_type=Path), default=Path("out/bench"), show_default=True)
@click.option("--quick", is_flag=True, help="a sphere, 1 and 4 copies, 160x90 (a smoke test)")
@publish.option("instances")
def main(out: Path, quick: bool, publish_dir: Path | None):
    """Run the instances benchmark and write OUT/instances.json, OUT/instances.md and OUT/instances.png."""
    started = publish.Run("bench.instances")
    result = run(out, quick, lambda m: click.echo(m, err=True))
    click.echo(f"wrote {out / 'instances.json'}, {out / 'instances.md'}, {out / 'instances.png'}")
    if publish_dir:
        click.echo(f"published {started.publish(publish_dir, 'instances', result)}")


if __name__ == "__main__":
    main()
