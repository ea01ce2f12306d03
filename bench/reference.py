"""make bench-reference: the filtered reference beside Mitsuba 3 (issue 40), in one process, interleaved.

The scanned Stanford bunny (pymeshfix's, 100k faces), one directional light, Lambert only (no ambient, no highlight,
so that Mitsuba's `direct` integrator with one emitter sample renders the same picture from the same rays: a primary
ray and, where it hits, one shadow ray), two orbit cameras, square frames. Variants:
  before     the reference's sampling as it was (main at 62f9cd8), kept here so the gain stays visible: N x N
             jittered strata, one thread (on today's tracer: its per-ray gains count for it too);
  uniform    vdmrender.tracing.reference.filtered with every sample for every pixel (adaptive=False: correlated
             multi-jittered, every core), as it was before adaptive sampling;
  ours-1     vdmrender.tracing.reference.filtered on one thread (adaptive: N samples first, the rest where they disagree;
             spp is the budget of the hardest pixels, `mean_spp` what it traced);
  ours       the same on every core;
  mitsuba-1  Mitsuba 3 `scalar_rgb`, `direct` integrator (1 emitter sample, no BSDF sample), `multijitter` sampler,
             box filter, one thread;
  mitsuba    the same on every core.
Timing: at 480 x 480 and 16 and 64 spp, each round every variant in turn (vdmrender's interleaved loop, the order
rotating by round), wall and CPU seconds (the process's, every thread), medians over the rounds. Error: at 400, 96, 48 and 24 px across, mean
ΔLuv of each at 4, 16 and 64 spp (ours also at a budget of 256, against Mitsuba's only: where it traces every
sample they are the truth's) against each renderer's own 256-spp frame (ours: uniform's) and against Mitsuba's (the renderers agree within their noise), and the seconds each needs to reach
Mitsuba's 16-spp error, and ours to reach uniform's 64-spp error (log-log interpolation of error against wall time,
on every core). Profile: where a 16-spp frame's time goes on one thread.

    python -m bench.reference -o out/bench [--quick] [--rounds 3]

Writes out/bench/reference.json and .md, and with --docs docs/results/reference.json (the tables of
docs/reference.md, `make docs`).
"""
from __future__ import annotations

import datetime
import json
import math
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from vdmbake.assets.meshes import load_mesh_file, resolve_path
from vdmbake.scene import Light, Material
from vdmrender.common import images
from vdmrender.comparing import metrics
from vdmrender.measuring import interleaved as loop
from vdmrender.tracing import reference
from vdmrender.common.camera import Camera, clip_planes
from vdmrender.common.markdown import number
from tools.make_docs import markdown

MESH = "pkg:pymeshfix/examples/StanfordBunny.ply"
TIMING_PX, TIMING_SPP = 480, (16, 64)
ERROR_PX, ERROR_SPP, TRUTH_SPP = (400, 96, 48, 24), (4, 16, 64), 256
OURS_SPP = (*ERROR_SPP, TRUTH_SPP)   # adaptive: a budget of 256 costs less than uniform's 64 where few pixels need it
BACKGROUND = np.array([0.1, 0.1, 0.1])


def light() -> Light:
    d = np.array([0.4, -0.5, 0.77])
    return Light(direction=tuple(d / np.linalg.norm(d)), color=(1.0, 1.0, 1.0), ambient=(0.0, 0.0, 0.0))


MATERIAL = Material(albedo=(0.8, 0.65, 0.5), diffuse=1.0, specular=0.0)


def cameras(mesh, size: int) -> list[Camera]:
    """Two orbit cameras, 30 degrees apart in azimuth, 20 degrees up, at 2.6 bounding radii, 40 degree field."""
    centre, radius = mesh.bounding_sphere()
    centre = np.asarray(centre, float)
    out = []
    for az in (30.0, 60.0):
        a, e = math.radians(az), math.radians(20.0)
        eye = centre + 2.6 * radius * np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
        out.append(Camera(eye, centre, np.array([0.0, 0.0, 1.0]), 40.0, size, size,
                          *clip_planes(eye, centre, centre, radius)))
    return out


def before(render, camera, spp: int):
    """reference.filtered as it was at 62f9cd8: jittered strata, each seeded by its index, on one thread."""
    n = math.isqrt(spp)
    total = np.zeros((camera.height, camera.width, 4))
    for k in range(spp):
        offset = None if n == 1 else (np.array([k % n, k // n])
                                      + np.random.default_rng(k).random((camera.height, camera.width, 2))) / n
        f = render(camera, offset=offset).astype(np.float64)
        f[..., :3] *= f[..., 3:]
        total += f
    return (total / spp).astype(np.float32)


class Mitsuba:
    """The same scene in Mitsuba 3 (scalar_rgb): the mesh with its vertex normals, a diffuse BSDF of the albedo, a
    directional emitter whose irradiance pi x colour makes its radiance albedo x colour x cos, as ours."""

    def __init__(self, mesh, light: Light, material: Material):
        import drjit as dr
        import mitsuba as mi

        mi.set_variant("scalar_rgb")
        self.mi, self.dr = mi, dr
        m = mi.Mesh("bunny", len(mesh.vertices), len(mesh.faces), has_vertex_normals=True)
        p = mi.traverse(m)
        p["vertex_positions"] = mesh.vertices.astype(np.float32).ravel()
        p["faces"] = mesh.faces.astype(np.uint32).ravel()
        p["vertex_normals"] = mesh.normals.astype(np.float32).ravel()
        p.update()
        self.dir = tempfile.TemporaryDirectory()
        ply = os.path.join(self.dir.name, "bunny.ply")
        m.write_ply(ply)
        self.shape = {"type": "ply", "filename": ply, "face_normals": False,
                      "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(material.albedo)}}}
        self.emitter = {"type": "directional", "direction": [-c for c in light.direction],
                        "irradiance": {"type": "rgb", "value": [math.pi * c * material.diffuse for c in light.color]}}
        self.scenes = {}

    def _scene(self, camera: Camera, spp: int, seed: int):
        key = (camera.width, camera.height, tuple(camera.eye), spp, seed)
        if key not in self.scenes:
            mi = self.mi
            self.scenes[key] = mi.load_dict({
                "type": "scene", "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
                "bunny": self.shape, "sun": self.emitter,
                "camera": {"type": "perspective", "fov": camera.fov_deg, "fov_axis": "y",
                           "near_clip": camera.near, "far_clip": camera.far,
                           "to_world": mi.ScalarTransform4f().look_at(origin=camera.eye.tolist(),
                                                                      target=camera.target.tolist(),
                                                                      up=camera.up.tolist()),
                           "sampler": {"type": "multijitter", "sample_count": spp, "seed": seed},
                           "film": {"type": "hdrfilm", "width": camera.width, "height": camera.height,
                                    "pixel_format": "rgba", "rfilter": {"type": "box"}}}})
        return self.scenes[key]

    def render(self, camera: Camera, spp: int, threads: int, seed: int = 0) -> np.ndarray:
        """(H, W, 4) premultiplied linear RGB and coverage, row 0 at the top, as reference.filtered."""
        self.dr.set_thread_count(threads)
        scene = self._scene(camera, spp, seed)
        return np.array(self.mi.render(scene, spp=spp, seed=seed), dtype=np.float32)


def device() -> str:
    model = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                  if line.startswith("model name")), platform.processor() or "unknown CPU")
    return f"{model}, {len(os.sched_getaffinity(0))} cores available to this process ({os.cpu_count()} online)"


def timed(fn):
    """(result, wall s, CPU s of the process: every thread)."""
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def variants(ref, mitsuba, cores: int) -> dict:
    """name -> frame(camera, spp) -> (premultiplied frame, samples traced per pixel or None)."""
    def ours(threads, adaptive=True):
        def frame(c, spp):
            f, halves = reference.filtered(ref.render, c, spp, threads, adaptive)
            return f, None if halves is None else halves.traced
        return frame

    return {"before": lambda c, spp: (before(ref.render, c, spp), None),
            "uniform": ours(cores, adaptive=False), "ours-1": ours(1), "ours": ours(cores),
            "mitsuba-1": lambda c, spp: (mitsuba.render(c, spp, 1), None),
            "mitsuba": lambda c, spp: (mitsuba.render(c, spp, cores), None)}


def interleaved(fns: dict, cams, spps: dict, rounds: int, ref) -> tuple[dict, dict]:
    """Every variant at each of its samples per pixel (spps: name -> spp list) over every camera, through vdmrender's
    one interleaved loop (vdmrender.measuring.interleaved.rounds: each round all of them in turn, the order rotated
    by round): {(name, spp): {wall_s, cpu_s, rays, mean_spp}} (medians over the rounds; rays of ours; mean_spp, the
    samples per pixel ours traced), and the first round's frames {(name, spp): [frame]}."""
    traced, frames = {}, {}

    def step(key, _):
        name, spp = key
        rays0 = ref.scene.rays_cast
        out, wall, cpu = timed(lambda: [fns[name](c, spp) for c in cams])
        frames.setdefault(key, [f for f, _ in out])
        if out[0][1] is not None:
            traced[key] = round(float(np.mean([n.mean() for _, n in out])), 3)
        click.echo(f"  {name} {spp} spp: {wall:.2f} s wall, {cpu:.2f} s CPU", err=True)
        return wall, cpu, ref.scene.rays_cast - rays0

    times = loop.rounds([(n, spp) for n in fns for spp in spps[n]], step, rounds)
    return ({k: {"wall_s": round(statistics.median(t[0] for t in v), 3),
                 "cpu_s": round(statistics.median(t[1] for t in v), 3), "rays": v[0][2],
                 "mean_spp": traced.get(k, k[1]), "wall_runs_s": [round(t[0], 3) for t in v]}
             for k, v in times.items()}, frames)


def error(frames, truths) -> float | None:
    """Mean ΔLuv of the cameras' frames, each encoded over the background against its truth, pooled as vdmrender's
    rows pool it (metrics.pooled: over every scored pixel of every frame)."""
    return metrics.pooled([metrics.compare(images.encode(f, BACKGROUND), images.encode(t, BACKGROUND))
                           for f, t in zip(frames, truths)])["mean_dluv"]


def seconds_to(target: float, points: list[tuple[float, float]]) -> float | None:
    """Wall seconds to reach error `target`, log-log interpolated (or extrapolated from the nearest two) over
    (seconds, error) points."""
    pts = sorted(points)
    if len(pts) < 2 or any(e <= 0 for _, e in pts):
        return None
    x, y = np.log([s for s, _ in pts]), np.log([e for _, e in pts])
    i = int(np.clip(np.searchsorted(-y, -math.log(target)), 1, len(pts) - 1))
    slope = (y[i] - y[i - 1]) / (x[i] - x[i - 1])
    return round(float(math.exp(x[i - 1] + (math.log(target) - y[i - 1]) / slope)), 3) if slope < 0 else None


def profile(ref, frame, cam, spp: int) -> dict:
    """Where frame(camera, spp) spends its time (on one thread): Embree's own ray loops against the rest (Python
    and numpy); the samples (primary rays) and rays (with the shadow rays) it traced per second."""
    scene, spent = ref.scene._scene, {"intersect": 0.0, "occluded": 0.0}

    class Clocked:
        def run(self, *a, **k):
            t = time.perf_counter()
            try:
                return scene.run(*a, **k)
            finally:
                spent["occluded" if k.get("query") == "OCCLUDED" else "intersect"] += time.perf_counter() - t

    rays0 = ref.scene.rays_cast
    ref.scene._scene = Clocked()
    try:
        (_, traced), wall, cpu = timed(lambda: frame(cam, spp))
    finally:
        ref.scene._scene = scene
    rays = ref.scene.rays_cast - rays0
    samples = spp * cam.width * cam.height if traced is None else int(traced.sum())
    embree = spent["intersect"] + spent["occluded"]
    return {"size": cam.width, "spp": spp, "wall_s": round(wall, 3), "cpu_s": round(cpu, 3), "rays": rays,
            "samples": samples, "embree_intersect_s": round(spent["intersect"], 3),
            "embree_occluded_s": round(spent["occluded"], 3), "rest_s": round(wall - embree, 3),
            "samples_per_cpu_s": round(samples / cpu), "rays_per_cpu_s": round(rays / cpu),
            "embree_rays_per_s": round(rays / embree)}


def tables(doc: dict) -> dict:
    def t(header, rows):
        return {"header": header, "align": ["---"] + ["---:"] * (len(header) - 1), "rows": rows}

    tm = doc["timing"]
    rows = []
    for name in ("before", "uniform", "ours-1", "ours", "mitsuba-1", "mitsuba"):
        cells = [name]
        for spp in TIMING_SPP:
            r, m = tm[f"{name}@{spp}"], tm[f"mitsuba@{spp}"]
            cells += [f"{r['wall_s']:.2f}", f"{r['cpu_s']:.2f}", f"{r['mean_spp']:.1f}", f"{r['wall_s'] / m['wall_s']:.2f}"]
        rows.append(cells)
    timing = t(["variant", *(f"{h} {spp} spp" for spp in TIMING_SPP
                             for h in ("wall s", "CPU s", "samples traced", "wall / mitsuba"))], rows)
    err = doc["error"]
    rows = []
    for name in ("before", "uniform", "ours", "mitsuba"):
        for spp in (OURS_SPP if name == "ours" else ERROR_SPP):
            e = [err[str(px)][name][str(spp)] for px in doc["error_px"]]
            rows.append([f"{name} {spp} spp", *(number(x["own"], 3) + f" · {x['mitsuba']:.3f}"
                                                + (f" ({x['mean_spp']:.1f})" if name == "ours" else "") for x in e)])
    errors = t(["variant", *(f"{px} px" for px in doc["error_px"])], rows)
    rows, goal = [], []
    for px in doc["error_px"]:
        e = doc["equal_error"][str(px)]
        rows.append([f"{px} px", f"{e['target']:.3f}", *(number(e[n], 2) for n in ("before", "uniform", "ours", "mitsuba")),
                     "-" if e["ours"] is None else f"{e['ours'] / e['mitsuba']:.2f}"])
        g = doc["goal"][str(px)]
        goal.append([f"{px} px", f"{g['uniform_16_s']:.2f}", f"{g['target']:.3f}", number(g["ours_s"], 2),
                     "-" if g["ours_s"] is None else f"{g['ours_s'] / g['uniform_16_s']:.2f}"])
    equal = t(["size", "Mitsuba's 16-spp error", "before s", "uniform s", "ours s", "mitsuba s", "ours / mitsuba"], rows)
    goal = t(["size", "uniform 16 spp s", "uniform 64-spp error", "ours s to it", "ours / uniform 16"], goal)
    p = doc["profile"]
    rows = [[name, f"{r['wall_s']:.2f}", f"{r['cpu_s']:.2f}", f"{r['embree_intersect_s']:.2f}",
             f"{r['embree_occluded_s']:.2f}", f"{r['rest_s']:.2f}", f"{r['samples'] / 1e6:.2f}",
             f"{r['samples_per_cpu_s'] / 1e6:.2f}", f"{r['rays_per_cpu_s'] / 1e6:.2f}", f"{r['embree_rays_per_s'] / 1e6:.2f}"]
            for name, r in p.items()]
    prof = t(["variant (one thread)", "wall s", "CPU s", "Embree intersect s", "Embree occluded s", "the rest s",
              "M samples", "M samples / CPU s", "M rays / CPU s", "Embree alone M rays/s"], rows)
    return {"timing": timing, "error": errors, "equal-error": equal, "goal": goal, "profile": prof}


@click.command()
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"))
@click.option("--rounds", default=3, show_default=True)
@click.option("--quick", is_flag=True, help="96 px timing, 48 and 24 px errors, one round (a smoke run).")
@click.option("--docs", is_flag=True, help="Also write docs/results/reference.json (make docs renders its tables).")
def main(out: Path, rounds: int, quick: bool, docs: bool):
    import mitsuba

    out.mkdir(parents=True, exist_ok=True)
    load_before = os.getloadavg()[0]
    mesh = load_mesh_file(resolve_path(MESH, Path(".")))
    lit = light()
    ref = reference.MeshReference(mesh, lit, MATERIAL)
    mi = Mitsuba(mesh, lit, MATERIAL)
    cores = reference.workers()
    timing_px, error_px, rounds = (96, (48, 24), 1) if quick else (TIMING_PX, ERROR_PX, rounds)
    fns = variants(ref, mi, cores)
    click.echo(f"timing at {timing_px} px", err=True)
    times, _ = interleaved(fns, cameras(mesh, timing_px), {n: TIMING_SPP for n in fns}, rounds, ref)
    errors, equal, goal = {}, {}, {}
    for px in error_px:
        cams = cameras(mesh, px)
        click.echo(f"error at {px} px", err=True)
        own = {"uniform": [reference.filtered(ref.render, c, TRUTH_SPP, adaptive=False)[0] for c in cams],
               "mitsuba": [mi.render(c, TRUTH_SPP, cores, seed=1) for c in cams]}
        own["before"] = own["ours"] = own["uniform"]
        sub = {n: fns[n] for n in ("before", "uniform", "ours", "mitsuba")}
        t, frames = interleaved(sub, cams, {n: OURS_SPP if n == "ours" else ERROR_SPP for n in sub}, rounds, ref)
        # ours at 256 shares the truth's samples where it traced them all: only Mitsuba's truth is independent of it
        errors[str(px)] = {n: {str(spp): {"own": None if (n, spp) == ("ours", TRUTH_SPP) else error(frames[n, spp], own[n]),
                                         "mitsuba": error(frames[n, spp], own["mitsuba"]),
                                         "wall_s": t[n, spp]["wall_s"], "cpu_s": t[n, spp]["cpu_s"],
                                         "mean_spp": t[n, spp]["mean_spp"]}
                                  for spp in (OURS_SPP if n == "ours" else ERROR_SPP)} for n in sub}
        errors[str(px)]["truths_agree"] = error(own["uniform"], own["mitsuba"])
        e = errors[str(px)]
        curve = {n: [(x["wall_s"], x["own"]) for x in e[n].values() if x["own"] is not None] for n in sub}
        target = e["mitsuba"]["16"]["own"]
        equal[str(px)] = {"target": target, **{n: seconds_to(target, curve[n]) for n in sub}}
        goal[str(px)] = {"uniform_16_s": e["uniform"]["16"]["wall_s"], "target": e["uniform"]["64"]["own"],
                         "ours_s": seconds_to(e["uniform"]["64"]["own"], curve["ours"])}
    prof = {n: profile(ref, fns[n], cameras(mesh, timing_px)[0], 16) for n in ("before", "ours-1")}
    prof["uniform-1"] = profile(ref, lambda c, spp: (reference.filtered(ref.render, c, spp, 1, adaptive=False)[0], None),
                                cameras(mesh, timing_px)[0], 16)
    doc = {"about": "make bench-reference (bench/reference.py): the filtered reference beside Mitsuba 3, interleaved",
           "measured_by": "python -m bench.reference -o out/bench" + (" --quick" if quick else "") + f" --rounds {rounds}",
           "when": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
           "device": device(), "load_before": load_before, "load_after": os.getloadavg()[0],
           "mitsuba": mitsuba.__version__, "cores": cores,
           "timing_px": timing_px, "error_px": list(error_px), "rounds": rounds,
           "timing": {f"{n}@{spp}": v for (n, spp), v in times.items()}, "error": errors, "equal_error": equal,
           "goal": goal, "profile": prof}
    doc["tables"] = tables(doc)
    (out / "reference.json").write_text(json.dumps(doc, indent=1) + "\n")
    md = [f"# The reference beside Mitsuba 3 ({doc['device']}, {doc['when']})", ""]
    for key, tbl in doc["tables"].items():
        md += [f"## {key}", "", markdown(tbl["header"], tbl["align"], tbl["rows"])]
    (out / "reference.md").write_text("\n".join(md))
    if docs:
        Path("docs/results/reference.json").write_text(json.dumps(doc, indent=1) + "\n")
    click.echo(f"{out / 'reference.md'}  {out / 'reference.json'}", err=True)


if __name__ == "__main__":
    main()
