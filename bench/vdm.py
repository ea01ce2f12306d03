"""make bench, VDM part: the measurements too slow for the tests, written to JSON and markdown, never asserted.

1. The bake of the paper's configuration (Wang et al. 2003, sec. 4: 128^2 texels, 32 x 8 views,
   16 curvatures in [-2, 3]): seconds per step, and the table bake's rays per second against raw
   Embree on the same rays in the same run; sizes raw and compressed, and the error each k adds.
2. Error against time on a torus and a vase with brick and gravel heights at 512^2: VDM at several
   k, each at refine 0 (the paper's algorithm), 1, 2 and 4, POM at several step counts, relief mapping
   (exact hierarchical tracing) at several iteration caps, bump mapping, displacement mapping at several
   subdivision levels, and the plain base mesh, against the displaced geometry traced by Embree; then,
   interleaved in one process, the first implementation's VDM lookup against today's, 8-bit against
   float32 weights, the refine settings against POM, relief and displacement, and the frame pass's costs
   per covered pixel (vdmrender/measuring/counters.py: fragments, texture fetches, search steps, searches).

    python -m bench.vdm -o out/bench [--quick]
"""
from __future__ import annotations

import itertools
import json
import time
from pathlib import Path

import click
import numpy as np

from vdmbake.assets import heightfields
from vdmbake.kernels import vdm, vdm_storage

from bench import interleave, publish, tables
from bench.quadrics import measure_scene
from vdmrender.gpu import gl
from vdmrender.common import progress
from vdmrender.reporting import report
from vdmrender.common.source import Source
from vdmrender.techniques import variants
from vdmrender.techniques.vdm import VDMPass

# (name, primitive, params, tiling): tilings keep a tile about as long as it is wide
SURFACES = [("torus", "torus", "{ segments = 256, rings = 64 }", (16, 4)),
            ("vase", "vase", "{ segments = 128, rings = 128 }", (8, 6))]
HEIGHTS = [("bricks", "bricks"), ("gravel", "skimage:gravel")]

SCENE = """
[render]
resolution = [{w}, {h}]
repeats = 3
warmup = 1
[camera]
orbit = {{ count = 2, elevation_deg = 30, azimuth_deg = 30, distance = 2.4, fov_deg = 40 }}
[[objects]]
name = "{name}"
primitive = "{primitive}"
params = {params}
mesostructure = {{ height = "{height}", size = {size}, depth = 0.06, tiling = [{tu}, {tv}], phi = {phi}, theta = 8, curvatures = {n_c} }}
techniques = {{ vdm = {{ k = [2, 4, 8], refine = [0, 1, 2, 4] }}, pom = {{ steps = [16, 32] }}, relief = {{ iterations = [8, 16, 32] }}, bump = {{}}, displaced = {{ levels = {levels} }}, mesh = {{}} }}
"""
# k up to 8 (the paper's): the bake chooses the weights' storage for the largest k a scene renders.
# Measured again interleaved in one process (wall and CPU time, interleave.py): the first implementation's
# lookup against today's, the weights' 8-bit storage against float32, the refine settings against POM,
# relief and displacement (the goals compare with pom@16 and displaced@2).
EXTRA = {"vdm@8 original lookup": dict(original=True), "vdm@8 float weights": dict(as_float=True)}
INTERLEAVED = ("vdm@8", "vdm@8r1", "vdm@8r2", "vdm@8r4", "vdm@4r2", "vdm@4r4", "pom@16", "pom@32", "relief@16",
               "relief@32", "displaced@1", "displaced@2")
COUNTED = ("vdm@8 original lookup", "vdm@8", "vdm@8r2", "vdm@8r4", "pom@16", "pom@32", "relief@32")


def paper_bake(size: int, n_phi: int, n_c: int) -> dict:
    """The paper's configuration on the bricks pattern; raw Embree timed on the same rays."""
    h = heightfields.pattern("bricks", size)
    depth = 0.06
    s = vdm.Sampling(size, n_phi, 8, vdm.curvature_samples(-2.0, 3.0, n_c))
    t0 = time.perf_counter()
    flat, rays, scene = vdm.vdm_flat(h, depth, s)
    t1 = time.perf_counter()
    o, d = vdm.flat_rays(s, 1e-4 * depth)
    o, d = np.ascontiguousarray(o), np.ascontiguousarray(d)
    t2 = time.perf_counter()
    scene.distances(o, d)                       # raw Embree: the same rays, nothing else
    t3 = time.perf_counter()
    t4 = time.perf_counter()
    table, theta_mvm, _ = vdm.bake_tables(h, depth, s)
    t5 = time.perf_counter()
    comp8 = vdm.compress(table, theta_mvm, 8)   # what a bake for k = 8 does (the paper's default)
    t6 = time.perf_counter()
    added = vdm_storage.storage_errors(comp8.W, comp8.E_vdm, comp8.E_mvm)
    e_bytes = comp8.E_vdm.nbytes + comp8.E_mvm.nbytes
    storage = {f: {"bytes": comp8.W.size * vdm_storage.BYTES[f] + e_bytes, **added[f]} for f in vdm_storage.FORMATS}
    chosen = vdm_storage.choose(added, comp8.errors[8].rms_vdm, comp8.errors[8].rms_mvm)
    ks = (1, 2, 4, 8, 16)
    comp = vdm.compress(table, theta_mvm, 10_000, report=ks)   # every k's error, for the table (not timed)
    n_cols = s.n_theta * n_c
    per_k = {}
    for k, e in comp.errors.items():
        weights = size * size * n_phi * k * 4
        per_k[str(k) if k in ks else "all"] = {"k": k, "bytes": weights + (n_cols + n_c) * k * 4, **e.__dict__}
    return {"size": size, "n_phi": n_phi, "n_theta": 8, "curvatures": n_c, "depth": depth, "rays": rays,
            "flat_s": round(t1 - t0, 3), "raw_embree_s": round(t3 - t2, 3),
            "flat_mrays_per_s": round(rays / (t1 - t0) / 1e6, 3), "raw_mrays_per_s": round(rays / (t3 - t2) / 1e6, 3),
            "throughput_ratio": round((t3 - t2) / (t1 - t0), 3),
            "tables_s": round(t5 - t4, 3), "svd_s": round(t6 - t5, 3), "bake_s": round(t6 - t4, 3),
            "rank": comp.rank, "raw_bytes": table.nbytes + theta_mvm.nbytes, "compressed": per_k,
            "storage_k8": storage, "storage_chosen": chosen, "storage_tolerance": vdm_storage.TOLERANCE}


def _scene_rows(out: Path, name, primitive, params, tiling, hname, height, w, h, size, n_phi, n_c, levels) -> list[dict]:
    tag = f"{name}-{hname}"
    rows = measure_scene(out, f"vdm-{tag}", SCENE.format(
        w=w, h=h, name=tag, primitive=primitive, params=params, height=height, size=size, tu=tiling[0],
        tv=tiling[1], phi=n_phi, n_c=n_c, levels=list(levels)))
    meso = json.loads((out / "bundles" / f"vdm-{tag}.bundle" / "manifest.json").read_text())["objects"][tag]
    c = meso["techniques"]["vdm"]["curvatures"]
    return [{**r, "surface": name, "height": hname, "curvature_range": [c[0], c[-1]]} for r in rows]


def _interleaved(out: Path, tag: str, rounds: int) -> dict:
    """INTERLEAVED (the scene's own variants) and EXTRA measured on the scene's bundle against its reference;
    the costs of COUNTED (interleave.costs: counts summed over the cameras)."""
    bundle, scene, obj, entry, cams = interleave.scene_of(out / "bundles" / f"vdm-{tag}.bundle")
    ref8 = interleave.reference8(out / "renders" / f"vdm-{tag}", obj.name, len(cams), scene.render.background)
    src = Source(obj, entry, entry["techniques"]["vdm"], bundle, scene, obj.techniques["vdm"])
    scene_builds = {v.label: v.build for v in variants(obj, entry, bundle, scene)}
    extra = {k: (lambda ctx, o=o: VDMPass(ctx, src, 8, **o)) for k, o in EXTRA.items()}
    builds = {**{k: scene_builds[k] for k in INTERLEAVED if k in scene_builds}, **extra}

    ctx = gl.create_context()
    try:
        rows = interleave.measure(ctx, builds, cams, ref8, scene.render.background, rounds)
        costs = {k: interleave.costs(ctx, {**scene_builds, **extra}[k], cams) for k in COUNTED}
    finally:
        ctx.release()
    return {"rows": rows, "costs": costs}


def _markdown(doc: dict) -> str:
    return f"# VDM benchmark ({doc['device']})\n\n" + tables.vdm(doc)


def _series(rows: list[dict]) -> list[dict]:
    """Rows for the plot: each refine setting of vdm its own line (vdm@8r2 is on "vdm r2")."""
    def series(r):
        v = r["value"]
        return f"vdm r{v.split('r')[1]}" if r["technique"] == "vdm" and isinstance(v, str) and "r" in v else r["technique"]
    return [{**r, "technique": series(r)} for r in rows]


@click.command()
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"), show_default=True)
@click.option("--quick", is_flag=True, help="Small tables, 96x96 frames, bricks on the torus only (a smoke run).")
@publish.option("vdm-bench")
def main(out: Path, quick: bool, publish_dir: Path | None):
    """Run the VDM benchmark and write OUT/vdm.json, OUT/vdm.md and OUT/vdm.png."""
    started = publish.Run("bench.vdm")
    size, n_phi, n_c, (w, h) = (32, 8, 4, (96, 96)) if quick else (128, 32, 16, (512, 512))
    paper = paper_bake(size, n_phi, n_c)
    click.echo(f"paper configuration: {paper['bake_s']:.2f} s, {paper['flat_mrays_per_s']:.2f} Mrays/s "
               f"(raw Embree {paper['raw_mrays_per_s']:.2f})", err=True)
    rows, inter = [], {}
    runs = list(itertools.product(SURFACES[:1] if quick else SURFACES, HEIGHTS[:1] if quick else HEIGHTS))
    for (name, primitive, params, tiling), (hname, height) in progress.bar(runs, "bench-vdm", unit="scene"):
        for r in _scene_rows(out, name, primitive, params, tiling, hname, height, w, h, size, n_phi, n_c,
                             (0, 1) if quick else (1, 2)):
            rows.append(r)
            click.echo(f"{name:5} {hname:6} {r['label']:13} {r['median_ms']:9.1f} ms  dLuv {r['mean_dluv']:.3f}  "
                       f"IoU {r['iou']:.4f}", err=True)
        tag = f"{name}-{hname}"
        inter[tag] = _interleaved(out, tag, 2 if quick else 5)
        for k, r in inter[tag]["rows"].items():
            click.echo(f"{tag} interleaved {k:22} {r['median_ms']:8.1f} ms  CPU {r['median_cpu_ms']:8.1f} ms  "
                       f"dLuv {r['mean_dluv']:.3f}", err=True)
    out.mkdir(parents=True, exist_ok=True)
    device = rows[0]["device"]
    doc = {"device": device, "resolution": [w, h], "paper_bake": paper, "rows": rows, "interleaved": inter}
    (out / "vdm.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "vdm.md").write_text(_markdown(doc))
    report.plot(out / "vdm.png", {"rows": _series(rows), "resolution": [w, h], "device": device})
    click.echo(f"wrote {out / 'vdm.json'}, {out / 'vdm.md'}, {out / 'vdm.png'}")
    if publish_dir:
        click.echo(f"published {started.publish(publish_dir, 'vdm-bench', doc)}")


if __name__ == "__main__":
    main()
