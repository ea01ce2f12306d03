"""The real peak memory of one small case of each kind a render holds, beside what vdmbake.bundle.budget estimates
for it: run as `python tests/memory_peaks.py KIND ARGS...`, alone in its process, it prints {"measured": bytes,
"estimate": bytes} as JSON. Measured as the growth of the process's peak resident set (VmHWM, reset through
/proc/self/clear_refs once the inputs are made), so what Embree and llvmpipe allocate outside Python counts too.

* mesh SEGMENTS SIZE SPP THREADS CAMERAS: a torus uploaded as the `mesh` variant draws it, and its reference
  traced as a run traces it (reference.filtered), every camera's frame kept; estimated: the reference and
  geometry parts.
* displaced SIZE: a torus under a `bricks` mesostructure of SIZE texels, tiling 2 x 2: the displaced reference
  (mesh and Embree scene), and the same surface built again and uploaded, as the change's full asset is
  (vdmrender.comparing.change); estimated: the displaced reference part.
* quadrics COUNT SIZE: COUNT random spheres' reference, one frame; estimated: the reference and geometry parts.
* targets SIZE MODE: the harness's targets under anti-aliasing MODE, cleared, resolved and read back;
  estimated: the targets part.
"""
from __future__ import annotations

import json
import sys

import numpy as np


def _status(key: str) -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith(key + ":"))


def _reset() -> int:
    """Reset the peak to the resident set now, and return it."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    return _status("VmRSS")


def _camera(size: int):
    from vdmrender.common.camera import Camera
    return Camera(np.array([0.0, -4.0, 1.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]), 40.0, size, size, 0.1, 20.0)


def _parts(render, *names) -> int:
    from vdmbake.bundle import budget
    parts = budget.render_parts(render)
    return sum(parts[n][0] for n in names)


def mesh(segments: int, size: int, spp: int, threads: int, cameras: int) -> dict:
    from vdmbake.assets.primitives import torus
    from vdmbake.bundle import budget
    from vdmbake.scene import Light, Material
    from vdmrender.gpu import gl
    from vdmrender.tracing import reference
    from vdmrender.passes.raster import RasterMesh

    ctx = gl.create_context()
    m, cam = torus(1.0, 0.3, segments, segments // 2), _camera(size)
    before = _reset()
    drawn = RasterMesh(ctx, m, Light(), Material(), 256)
    ctx.finish()
    ref = reference.MeshReference(m, Light(), Material())
    kept = [reference.filtered(ref.render, cam, spp, threads) for _ in range(cameras)]
    measured = _status("VmHWM") - before
    drawn.release()
    del kept
    need = budget.Render(size, size, cameras, spp, threads, objects=(budget.Geometry("torus", len(m.faces)),))
    return {"measured": measured, "estimate": _parts(need, "reference", "geometry")}


def displaced(size: int) -> dict:
    from vdmbake.assets import heightfields
    from vdmbake.assets.primitives import torus
    from vdmbake.bundle import budget
    from vdmbake.common import geometry
    from vdmbake.kernels import vdm
    from vdmbake.scene import Light, Material
    from vdmrender.gpu import gl
    from vdmrender.tracing import reference
    from vdmrender.passes.raster import RasterMesh

    ctx = gl.create_context()
    base = torus(1.0, 0.3, 24, 12)
    heights = heightfields.from_spec("bricks", size, None).astype(np.float64)
    normals = vdm.height_normals(heights, 0.06)
    levels = geometry.reference_levels(base, size, (2, 2))
    before = _reset()
    surface = geometry.displaced(base, heights, normals, 0.06, (2, 2), levels)
    ref = reference.MeshReference(surface, Light(), Material())
    full = RasterMesh(ctx, geometry.displaced(base, heights, normals, 0.06, (2, 2), levels), Light(), Material(), 256)
    ctx.finish()
    measured = _status("VmHWM") - before
    full.release()
    need = budget.Render(8, 8, 1, objects=(budget.Geometry("torus", displaced=len(ref.mesh.faces)),))
    return {"measured": measured, "estimate": _parts(need, "displaced reference")}


def quadrics(count: int, size: int) -> dict:
    from vdmbake.bundle import budget
    from vdmbake.kernels.quadrics import inline
    from vdmbake.scene import Light, Material
    from vdmrender.tracing import reference

    rng = np.random.default_rng(1)
    q, cam = inline(np.c_[rng.uniform(-1, 1, (count, 3)), np.full(count, 0.02)], [], (0.5, 0.5, 0.5)), _camera(size)
    before = _reset()
    ref = reference.QuadricReference(q, Light(), Material())
    frame = reference.filtered(ref.render, cam, 1)
    measured = _status("VmHWM") - before
    del frame
    need = budget.Render(size, size, 1, objects=(budget.Geometry("spheres", quadrics=count),))
    return {"measured": measured, "estimate": _parts(need, "reference", "geometry")}


def targets(size: int, mode: str) -> dict:
    from vdmbake.bundle import budget
    from vdmbake.scene import ANTIALIAS
    from vdmrender.gpu import gl
    from vdmrender.measuring import antialias

    ctx = gl.create_context()
    before = _reset()
    plain = gl.Target(ctx, size, size)            # as measure.Harness: the frame's target, and the shipped one
    plain.clear()
    frames = [plain.read()]
    if mode != "none":
        shipped = antialias.target(ctx, size, size, mode)
        shipped.clear()
        shipped.resolve()
        frames.append(shipped.read())
    ctx.finish()
    measured = _status("VmHWM") - before
    del frames
    need = budget.Render(size, size, 1, antialias=ANTIALIAS[mode])
    return {"measured": measured, "estimate": _parts(need, "targets")}


KINDS = {"mesh": mesh, "displaced": displaced, "quadrics": quadrics, "targets": targets}

if __name__ == "__main__":
    kind, *args = sys.argv[1:]
    print(json.dumps(KINDS[kind](*(int(a) if a.isdigit() else a for a in args))))
