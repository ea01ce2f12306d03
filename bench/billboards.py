"""make bench, enhanced-billboards part: the thesis's appendix A comparison, written to JSON and
markdown, never asserted.

Models comparable to tables A-1/A-2 (sphere, torus, cone, cylinder) and a real scanned bunny, each
at 800x600, 400x300 and 200x150: the full mesh, the coarse mesh alone, the thesis's billboards
(100-step march, hit range 0.01 and 0.02) and the hierarchical ones (`hier`), each with and without the
coarse mesh, and the improved ones with it, greedy projection; plus the axis projection (hier+coarse),
its billboard count and storage for comparison.

Then, on the bunny, in one process (issue 9's closing measurements):
  * interleaved timing: full mesh, coarse mesh, hit0.01+coarse, improved+coarse, hier, hier+coarse,
    ROUNDS rounds of one frame each per resolution (vdmrender's interleaved loop), every pass timed by its own
    timer query: the median frame and its shadow pass share; the ratio to the full mesh, paired frame by frame
    (vdmrender.deciding.pricing: the median ratio and its 95% interval);
  * march cost, instrumented (vdmrender/measuring/counters.py): fragments, texture fetches, march steps (cell visits
    for hier) and searches per covered pixel, improved against hier, at 800x600.

    python -m bench.billboards -o out/bench [--quick]
"""
from __future__ import annotations

import itertools
import json
import statistics
from pathlib import Path

import click

from bench import publish, tables
from bench.quadrics import measure_scene
from vdmrender.common import progress

MODELS = [("sphere", 'primitive = "sphere"'), ("torus", 'primitive = "torus"'), ("cone", 'primitive = "cone"'),
          ("cylinder", 'primitive = "cylinder"'), ("bunny", 'mesh = "pkg:pymeshfix/examples/StanfordBunny.ply"')]
RESOLUTIONS = [(800, 600), (400, 300), (200, 150)]
# Thesis appendix A-2 (hit range 0.01; with coarse mesh), for the models we have.
THESIS = {"sphere": (25.81, 6.56), "torus": (58.09, 51.80), "cone": (5.56, 3.33), "cylinder": (39.45, 31.85)}
# The improved march alone (20-60 s a frame at 800x600 on llvmpipe) is left out: improved+coarse stands for it.
VARIANTS = ["greedy-hit0.01", "greedy-hit0.02", "greedy-hier", "greedy-hit0.01+coarse", "greedy-hit0.02+coarse",
            "greedy-improved+coarse", "greedy-hier+coarse", "axis-hier+coarse"]
# The bunny's interleaved profile: these labels, ROUNDS frames each per resolution.
PROFILE = ["mesh", "coarse@0.1", "billboards@greedy-hit0.01+coarse", "billboards@greedy-improved+coarse",
           "billboards@greedy-hier", "billboards@greedy-hier+coarse"]
ROUNDS = 5

SCENE = """
[render]
resolution = [{w}, {h}]
repeats = 1
warmup = 1
shadow_map = {shadow_map}
[camera]
orbit = {{ count = 1, elevation_deg = 25, azimuth_deg = 30, distance = 2.6, fov_deg = 40 }}
[[objects]]
name = "{name}"
{source}
techniques = {{ mesh = {{}}, coarse = {{ ratios = [0.1] }}, billboards = {{ variants = {variants}, resolution = {res} }} }}
"""


def _builders(bundle_path: Path, width: int, height: int):
    """(camera, {label: build}, (bundle, scene, object, entry)) for the bench scene's object, as vdmrender
    builds them, at width x height."""
    from bench.interleave import scene_of
    from vdmrender.common.camera import cameras_for
    from vdmrender.techniques import variants

    bundle, scene, obj, entry, _ = scene_of(bundle_path)
    cam = cameras_for(scene.camera, entry["centre"], entry["radius"], width, height)[0]
    return cam, {v.label: v.build for v in variants(obj, entry, bundle, scene)}, (bundle, scene, obj, entry)


def profile(bundle_path: Path, labels: list[str], rounds: int, resolutions) -> list[dict]:
    """Interleaved timing in one GL context through vdmrender's one loop (vdmrender.measuring.interleaved.frames:
    each label warmed up as vdmrender warms up a row, then per resolution `rounds` rounds of one frame of each, the
    order rotated by round), every pass in its own timer query (vdmrender/measuring/timing.py: GPU time, as
    vdmrender reports it), and the frame's process CPU time (llvmpipe's threads are the process's own: the work
    done, much less disturbed by other processes on a shared machine than wall time). The ratio to the full mesh is
    the timing statistic's (vdmrender.deciding.pricing.ratio: the median of the paired frames' ratios, and its 95%
    interval)."""
    from vdmrender.deciding import pricing
    from vdmrender.gpu import gl
    from vdmrender.measuring import interleaved
    from vdmrender.measuring.timing import Budget, FrameTimer

    ctx = gl.create_context()
    rows = []
    try:
        for w, h in resolutions:
            cam, builds, _ = _builders(bundle_path, w, h)
            target = gl.Target(ctx, w, h)
            timer = FrameTimer(ctx, target)
            renderers = {k: builds[k](ctx) for k in labels}
            samples, _ = interleaved.frames(timer, renderers, [cam], Budget(), rounds)
            for k, r in renderers.items():
                r.release()
            target.release()
            mesh = samples["mesh"]
            for k in labels:
                s = samples[k]
                total = [x.gpu_ms for x in s]
                gpu, cpu = (pricing.ratio([getattr(x, a) for x in s], [getattr(m, a) for m in mesh])
                            for a in ("gpu_ms", "cpu_ms"))
                rows.append({"label": k, "resolution": f"{w}x{h}", "median_ms": round(statistics.median(total), 2),
                             "ratio_to_mesh": gpu["ratio"], "ratio_to_mesh_95": [gpu["low"], gpu["high"]],
                             "median_cpu_ms": round(statistics.median(x.cpu_ms for x in s), 2),
                             "cpu_ratio_to_mesh": cpu["ratio"], "cpu_ratio_to_mesh_95": [cpu["low"], cpu["high"]],
                             "shadow_share": round(statistics.median(x.passes["shadow"] / t
                                                                     for x, t in zip(s, total)), 3),
                             "passes_ms": {n: round(statistics.median(x.passes[n] for x in s), 2)
                                           for n in s[0].passes}})
    finally:
        ctx.release()
    return rows


def march_cost(bundle_path: Path, width: int, height: int) -> dict:
    """improved+coarse and hier+coarse on the bench camera, instrumented (vdmrender/measuring/counters.py): per covered
    pixel, over the frame's passes (all but the shadow map's), the fragments the stages ran (improved: every
    box fragment and the coarse mesh's; hier: its pre-passes', the screen pass's and the coarse mesh's),
    texture fetches, march steps (improved: its samples and bisections; hier: cell visits, a pyramid fetch
    each) and searches (a billboard marched or traced); steps per search is a march's mean length."""
    from vdmrender.measuring import counters
    from vdmrender.gpu import gl
    from vdmrender.measuring.measure import is_light_pass

    cam, builds, _ = _builders(bundle_path, width, height)
    ctx = gl.create_context()
    out = {}
    try:
        for name in ("improved", "hier"):
            with counters.counting(ctx):
                r = builds[f"billboards@greedy-{name}+coarse"](ctx)
            target = gl.Target(ctx, width, height)
            try:
                c = counters.count_frame(ctx, r, cam, target)
            finally:
                target.release()
                r.release()
            frame = {k: sum(p[k] for n, p in c["passes"].items() if not is_light_pass(n)) for k in counters.COUNTERS}
            px = max(c["covered"], 1)
            out[name] = {"covered_pixels": c["covered"], **{f"{k}_per_pixel": round(v / px, 2) for k, v in frame.items()},
                         "steps_per_search": round(frame["steps"] / max(frame["searches"], 1), 2)}
    finally:
        ctx.release()
    return out


def _markdown(doc: dict) -> str:
    return f"# Enhanced billboards benchmark ({doc['device']})\n\n" + tables.billboards(doc)


@click.command()
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"), show_default=True)
@click.option("--quick", is_flag=True, help="Sphere only, 200x150, 64-texel maps (a smoke run).")
@publish.option("billboards-bench")
def main(out: Path, quick: bool, publish_dir: Path | None):
    """Run the billboard benchmark and write OUT/billboards.json and OUT/billboards.md."""
    started = publish.Run("bench.billboards")
    models = MODELS[:1] if quick else MODELS
    resolutions = RESOLUTIONS[-1:] if quick else RESOLUTIONS
    res, shadow_map = (64, 512) if quick else (512, 1024)
    rows, bakes = [], {}
    for (name, source), (w, h) in progress.bar(list(itertools.product(models, resolutions)), "bench-billboards",
                                               unit="scene"):
        tag = f"billboards-{name}-{w}x{h}"
        for r in measure_scene(out, tag, SCENE.format(w=w, h=h, name=name, source=source, res=res,
                                                      shadow_map=shadow_map, variants=json.dumps(VARIANTS))):
            rows.append({**r, "resolution": f"{w}x{h}"})
            click.echo(f"{name:8} {w}x{h} {r['label']:36} {r['median_ms']:9.1f} ms  dLuv {r['mean_dluv']:.3f}  "
                       f"IoU {r['iou']:.4f}", err=True)
        if name not in bakes:
            bundle = out / "bundles" / f"{tag}.bundle"
            m = json.loads((bundle / "manifest.json").read_text())
            bb = m["objects"][name]["techniques"]["billboards"]
            timing = json.loads((bundle / "timing.json").read_text())["steps_s"].get(name, {})
            bakes[name] = {"greedy": len(bb["greedy"]["faces"]), "axis": len(bb["axis"]["faces"]),
                           "leftover": bb["greedy"]["leftover"],
                           "greedy_mb": m["parts"][bb["greedy"]["maps"]]["bytes"] / 2**20,
                           "axis_mb": m["parts"][bb["axis"]["maps"]]["bytes"] / 2**20,
                           "bake_s": timing.get("billboards_greedy_s", 0.0),
                           "pyramid_mb": bb["greedy"]["pyramid_bytes"] / 2**20,
                           "hier_bake_s": timing.get("billboards_greedy_bordered_s", 0.0)}
    # the closing measurements on the last model (the bunny), from its first resolution's bundle
    first = out / "bundles" / f"billboards-{models[-1][0]}-{resolutions[0][0]}x{resolutions[0][1]}.bundle"
    rounds = 1 if quick else ROUNDS
    prof = profile(first, PROFILE, rounds, resolutions)
    for p in prof:
        click.echo(f"profile {p['resolution']} {p['label']:36} {p['median_ms']:9.1f} ms  x{p['ratio_to_mesh']:.2f} "
                   f"shadow {p['shadow_share']:.0%}", err=True)
    cost = march_cost(first, *resolutions[0])
    out.mkdir(parents=True, exist_ok=True)
    device = rows[0]["device"]
    doc = {"device": device, "map_resolution": res, "shadow_map": shadow_map, "thesis": THESIS, "bakes": bakes,
           "rows": rows, "profiled_model": models[-1][0], "rounds": rounds, "profile": prof,
           "cost_resolution": "x".join(map(str, resolutions[0])), "march_cost": cost}
    (out / "billboards.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "billboards.md").write_text(_markdown(doc))
    click.echo(f"wrote {out / 'billboards.json'}, {out / 'billboards.md'}")
    if publish_dir:
        click.echo(f"published {started.publish(publish_dir, 'billboards-bench', doc)}")


if __name__ == "__main__":
    main()
