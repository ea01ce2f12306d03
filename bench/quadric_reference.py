"""The quadric reference's cost against the number of quadrics: real molecules of 22k and 165k atoms
and the 165k one tiled 3x2 (991k atoms), space-filling, one orbit camera at 3 bounding radii.

Two tracers, interleaved (vdmrender's loop: old, new, then new, old, ...), median of 3 rounds, each round building
its tracer afresh (vdmrender's reference log times the build with the frames):
  box-walk  the original, kept here so the gain stays visible: one box a quadric, Embree float32
            alone deciding which boxes a ray meets;
  grouped   vdmrender.tracing.reference.QuadricTracer: a box a grid cell's group, each its own orientation,
            faces stepped over found in float64.
Per variant: build s, first frame s (Embree builds its BVH on the first query), steady frame s, and
rays/s (primary rays plus their shadow rays, as QuadricReference.render casts them). Exactness: the
pixels whose hit (t, quadric) differ between the two, each checked against every quadric.

    python -m bench.quadric_reference -o out/bench [--size 256] [--quick]
"""
from __future__ import annotations

import json
import os
import platform
import statistics
import time
from pathlib import Path
from unittest import mock

import click
import numpy as np

from vdmbake.assets.meshes import resolve_path
from vdmbake.assets.molecules import load_molecule
from vdmbake.bundle import budget
from vdmbake.common.geometry import onb
from vdmbake.errors import InputError
from vdmbake.kernels.quadrics import QuadricSet
from vdmbake.scene import Cameras, Light, Material, Orbit

from vdmrender.measuring import interleaved
from vdmrender.tracing import quadric_math, reference
from vdmrender.common.camera import cameras_for

from .quadrics import MOLECULES, _available

CASES = [("4jsv", 1), ("6zu5", 1), ("6zu5", 6)]   # (molecule, copies: 6 = tiled 3x2)


class BoxWalk(reference.QuadricTracer):
    """The original tracer: one box a quadric (12 triangles; oriented along a cylinder's axis), each
    face met tests its quadric alone, nothing checks the faces stepped over."""

    def __init__(self, q):
        self.q = q
        self.n_s = len(q.spheres)
        s, c = q.spheres, q.cylinders
        axis = c[:, 3:6] - c[:, :3]
        half = 0.5 * np.linalg.norm(axis, axis=1)
        w = axis / (2 * half)[:, None]
        u, v = onb(w)
        box = reference._BOX
        grow = 1.0 + 1e-5
        corners = np.concatenate([
            s[:, None, :3] + grow * s[:, None, 3:4] * box[None],
            0.5 * (c[:, None, :3] + c[:, None, 3:6]) + grow * (
                u[:, None] * c[:, None, 6:7] * box[None, :, :1] + v[:, None] * c[:, None, 6:7] * box[None, :, 1:2]
                + w[:, None] * half[:, None, None] * box[None, :, 2:3])])
        faces = (np.arange(len(corners))[:, None, None] * 8 + reference._BOX_FACES[None]).reshape(-1, 3)
        self.scene = reference.RayScene(corners.reshape(-1, 3), faces)
        self.reach = float(np.linalg.norm(corners.max(1) - corners.min(1), axis=1).max())
        self.step = 1e-6 * q.bounding_sphere()[1]
        self.members = np.arange(len(corners))[:, None]   # a group a quadric

    def _met(self, o, d, face_t, group):
        return np.arange(len(o)), group

    def _nearest(self, o, d, ray, group, tmin):
        t, n = self._test(o, d, group, tmin)                # a ray's one group is its one quadric
        return t, n, group


VARIANTS = {"box-walk": BoxWalk, "grouped": reference.QuadricTracer}


def tiled(q: QuadricSet, copies: int) -> QuadricSet:
    """`copies` (1 or 6) of q side by side, 3 x 2 in x and y, each shifted by its box's size."""
    if copies == 1:
        return q
    size = np.ptp(q.spheres[:, :3], 0) + 2 * q.spheres[:, 3].max()
    shifts = [np.array([i * size[0], j * size[1], 0.0]) for i in range(3) for j in range(2)]
    return QuadricSet(np.concatenate([q.spheres + np.r_[s, 0.0] for s in shifts]),
                      np.concatenate([q.sphere_rgb] * 6),
                      np.concatenate([q.cylinders + np.r_[s, s, 0.0] for s in shifts]),
                      np.concatenate([q.cylinder_rgb] * 6))


def device() -> str:
    model = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                  if line.startswith("model name")), platform.processor() or "unknown CPU")
    return f"{model}, {len(os.sched_getaffinity(0))} cores available to this process ({os.cpu_count()} online)"


def brute_force(q: QuadricSet, o, d, tmin, tmax):
    """Nearest hit (t, quadric index) of each ray with every quadric: the judge where the tracers differ."""
    out_t, out_i = np.full(len(o), np.inf), np.full(len(o), -1)
    s, c = q.spheres, q.cylinders
    for k in range(len(o)):
        os_, ds = np.broadcast_to(o[k], (len(s), 3)), np.broadcast_to(d[k], (len(s), 3))
        oc, dc = np.broadcast_to(o[k], (len(c), 3)), np.broadcast_to(d[k], (len(c), 3))
        t = np.concatenate([quadric_math.ray_spheres(os_, ds, s[:, :3], s[:, 3], np.full(len(s), tmin[k])),
                            quadric_math.ray_capped_cylinders(oc, dc, c[:, :3], c[:, 3:6], c[:, 6],
                                                              np.full(len(c), tmin[k]))[0]])
        t = np.where(t <= tmax[k], t, np.inf)
        if np.isfinite(t.min()):
            out_t[k], out_i[k] = t.min(), t.argmin()
    return out_t, out_i


def one_round(name, q, cam, light, material) -> tuple[dict, tuple]:
    """Build the variant's reference, render the frame twice: timings, rays and the primary hits."""
    with mock.patch.object(reference, "QuadricTracer", VARIANTS[name]):
        t0 = time.perf_counter()
        ref = reference.QuadricReference(q, light, material)
        build = time.perf_counter() - t0
    t0 = time.perf_counter()
    ref.render(cam)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    frame = ref.render(cam)
    steady = time.perf_counter() - t0
    eye, d = cam.pixel_rays()
    scale = np.linalg.norm(d, axis=1)
    hits = ref.tracer.first_hit(np.ascontiguousarray(eye), d / scale[:, None], cam.near * scale, cam.far * scale)
    rays = cam.width * cam.height + int((frame[..., 3] > 0).sum())
    return {"build_s": build, "first_frame_s": first, "frame_s": steady, "rays": rays,
            "boxes": len(ref.tracer.members)}, hits


def measure(q, cam, rounds: int) -> tuple[dict, dict]:
    """Both tracers through vdmrender's one interleaved loop (vdmrender.measuring.interleaved.rounds: each round
    one_round of each in turn, the order rotated by round): medians over the rounds, and each one's last hits."""
    light, material = Light(), Material()
    hits = {}

    def step(name, _):
        r, hits[name] = one_round(name, q, cam, light, material)
        return r

    runs = interleaved.rounds(VARIANTS, step, rounds)
    out = {}
    for name, rs in runs.items():
        med = {k: statistics.median(r[k] for r in rs) for k in ("build_s", "first_frame_s", "frame_s")}
        rays = rs[0]["rays"]
        out[name] = {**{k: round(v, 3) for k, v in med.items()}, "rays": rays, "boxes": rs[0]["boxes"],
                     "rays_per_s_frame": round(rays / med["frame_s"]),
                     "rays_per_s_with_build": round(rays / (med["build_s"] + med["first_frame_s"]))}
    return out, hits


def exactness(q, cam, hits) -> dict:
    (ta, _, ia), (tb, _, ib) = hits["box-walk"], hits["grouped"]
    differ = np.flatnonzero((ta != tb) | (ia != ib))
    eye, d = cam.pixel_rays()
    scale = np.linalg.norm(d, axis=1)
    bt, bi = brute_force(q, eye[differ], (d / scale[:, None])[differ], (cam.near * scale)[differ],
                         (cam.far * scale)[differ])
    return {"pixels": int(len(ta)), "pixels_differing": int(len(differ)),
            "box_walk_wrong": int((ta[differ] != bt).sum()), "grouped_wrong": int((tb[differ] != bt).sum()),
            "max_rel_t_difference": float(np.max(np.abs(ta[differ] - tb[differ]) / bt, initial=0.0,
                                                 where=np.isfinite(bt)))}


def _markdown(summary: dict) -> str:
    lines = [f"# Quadric reference: cost against atoms ({summary['device']})", "",
             f"{summary['size']}x{summary['size']}, one camera at 3 bounding radii, spacefill; "
             f"median of {summary['rounds']} interleaved rounds; rays = primary + shadow.", "",
             "| molecule | atoms | variant | boxes | build s | first frame s | frame s | rays/s (frame) | "
             "rays/s (build + first frame) |", "|---|---:|---|---:|---:|---:|---:|---:|---:|"]
    for row in summary["rows"]:
        for name in VARIANTS:
            v = row[name]
            lines.append(f"| {row['molecule']} | {row['atoms']} | {name} | {v['boxes']} | {v['build_s']:.2f} | "
                         f"{v['first_frame_s']:.2f} | {v['frame_s']:.3f} | {v['rays_per_s_frame']} | "
                         f"{v['rays_per_s_with_build']} |")
    lines += ["", "| molecule | pixels | differing | box-walk wrong | grouped wrong |", "|---|---:|---:|---:|---:|"]
    for row in summary["rows"]:
        e = row["exactness"]
        lines.append(f"| {row['molecule']} | {e['pixels']} | {e['pixels_differing']} | {e['box_walk_wrong']} | "
                     f"{e['grouped_wrong']} |")
    return "\n".join(lines) + "\n"


@click.command()
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"), show_default=True)
@click.option("--size", default=256, show_default=True, help="frame width and height")
@click.option("--quick", is_flag=True, help="the 22k-atom molecule only, 64x64, one round (a smoke run).")
def main(out: Path, size: int, quick: bool):
    """Measure both tracers and write OUT/quadric_reference.json and OUT/quadric_reference.md."""
    paths = {name: path for name, path, _ in MOLECULES}
    cases = [c for c in CASES if _available(paths[c[0]])][:1 if quick else None]
    size, rounds = (64, 1) if quick else (size, 3)
    scene_camera = Cameras(orbit=Orbit(count=1, distance=3.0, fov_deg=45.0))
    rows = []
    for name, copies in cases:
        q = tiled(load_molecule(resolve_path(paths[name], Path(".")), "spacefill"), copies)
        label = name if copies == 1 else f"{name} x{copies}"
        cam = cameras_for(scene_camera, *q.bounding_sphere(), size, size)[0]
        try:   # the render's memory rule, for one reference frame of these quadrics
            budget.check_render(budget.Render(size, size, 1, objects=(
                budget.Geometry(label, quadrics=len(q.spheres) + len(q.cylinders)),)))
        except InputError as e:
            raise click.BadParameter(str(e), param_hint="--size") from None
        timings, hits = measure(q, cam, rounds)
        rows.append({"molecule": label, "atoms": len(q.spheres), **timings, "exactness": exactness(q, cam, hits)})
        click.echo(f"{label}: " + ", ".join(f"{k} {v['rays_per_s_frame']} rays/s (frame), "
                                            f"{v['rays_per_s_with_build']} with the build" for k, v in timings.items()),
                   err=True)
    summary = {"device": device(), "size": size, "rounds": rounds, "rows": rows}
    out.mkdir(parents=True, exist_ok=True)
    (out / "quadric_reference.json").write_text(json.dumps(summary, indent=1) + "\n")
    (out / "quadric_reference.md").write_text(_markdown(summary))
    click.echo(f"wrote {out / 'quadric_reference.json'}, {out / 'quadric_reference.md'}")


if __name__ == "__main__":
    main()
