"""The memory one job may use, and the guard that holds every documented size to it: one rule for the bake, the
render and the benches.

The tools are sized for a machine with 24 GiB of memory: a job (one bake step, or one render) may reach BUDGET at
its peak, the rest left to the system, and never more than the memory available when it starts (on a smaller or
busier machine). Each piece of work whose documented sizes can reach the budget estimates its peak from its
settings alone, from peaks measured with ru_maxrss, VmHWM or tracemalloc and rounded up: the bake steps one
function per kind, `kernels.octahedral.bake_bytes` (atlases), `assets.teapot.bake_bytes` (segments),
`kernels.vdm.bake_bytes` (tables), `techniques.billboards.bake_bytes` (maps and their pyramids, per billboard: how
many a projection makes is known only as they are made, so their bake is held to the count that fits),
`DISPLACE_BYTES_PER_FACE` (the `displaced` technique's levels); a render, `render_parts`: everything it holds at
once, summed (the reference at its size, samples and threads with the frames it keeps, the displaced reference of
a mesostructure, the objects' geometry, the render targets with their samples), which `check_render` holds to
the budget once, before the render starts, and the benches that trace references ask too. `check` refuses an
estimate over the budget, with it in the message, before anything is allocated. A setting's documented maximum
is what the guard allows, or the refusal says why not.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from ..errors import InputError

BUDGET = 20 << 30   # bytes: a 24 GiB machine less 4 GiB for the system, the interpreter and what else runs


def available() -> int:
    """The memory the system reports available now (bytes)."""
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def allowed(free: int | None = None) -> int:
    """What one job may reach: BUDGET, or the available memory (`free`, measured now if None) where that is less."""
    return min(BUDGET, available() if free is None else free)


def fits(need: int, free: int | None = None) -> bool:
    return need <= allowed(free)


def check(need: int, what: str, fix: str, free: int | None = None) -> None:
    """Refuse `what` when its estimated peak `need` (bytes) is over allowed(`free`); `fix` says what to lower."""
    limit = allowed(free)
    if need > limit:
        which = ("the budget (vdmbake.bundle.budget.BUDGET, for a 24 GiB machine)" if limit == BUDGET
                 else f"the memory available now (the budget is {BUDGET / 2**30:.3g} GiB)")
        raise InputError(f"{what} needs about {need / 2**30:.1f} GiB of memory, more than the {limit / 2**30:.3g} "
                         f"GiB of {which}; {fix}.")


# What a render holds at its peak, per unit, measured as the growth of peak RSS (VmHWM, so Embree's and llvmpipe's
# own allocations count) and rounded up about 2x; tests/test_memory.py measures each kind again and holds these
# to it. Reference, per pixel of the frame: tracing at 1 spp, 255 bytes (a whole frame's rays at once); filtered
# at more spp (reference.filtered: its sums, the samples' agreement, a frame in flight per thread), 830 bytes on
# one thread and 310-440 more per further thread (256^2, 16 and 64 spp, 1, 2 and 4 threads).
POINT_BYTES_PER_PIXEL = 512
FILTERED_BYTES_PER_PIXEL = 1536
FILTERED_BYTES_PER_THREAD_PIXEL = 768
# Frames a run keeps per camera and pixel until its object's rows are scored: the references (filtered, its halves,
# the pixel classes, the point-sampled one, their sRGB encodings: 53 bytes measured for the filtered one and its
# halves) and one variant's frames (as shipped, point-sampled, the full asset's for the change: 16 bytes each).
HELD_BYTES_PER_CAMERA_PIXEL = 128
# Geometry, per face of every mesh part of an object (its reference's Embree scene, 136 bytes measured over
# 40k -> 160k faces, and the variants' buffers, which llvmpipe keeps in RAM: 150 bytes a face of peak RSS over
# 200k -> 800k mesh faces at 48^2), and per sphere or cylinder (the quadric reference's grid and boxes: 2.6-2.8 kB
# over 20k -> 80k spheres; 2.15 kB a sphere of peak RSS over 80k -> 200k inline spheres with the impostor's).
BYTES_PER_FACE = 600
BYTES_PER_QUADRIC = 8192
# Displacing, per face made (geometry.displaced: subdivision's edge tables and the per-vertex frames, float64):
# 240-245 bytes of peak RSS over 590k -> 2.4M faces.
DISPLACE_BYTES_PER_FACE = 512
# The displaced reference of a mesostructure, per face: its mesh and Embree scene (192 bytes held), and the same
# surface built again and uploaded as the full asset the variants' change is measured against
# (vdmrender.comparing.change): 374-392 bytes a face of peak RSS over 590k -> 2.4M faces.
DISPLACED_BYTES_PER_FACE = 768
# Render targets, per pixel of the frame: a single-sample target (RGBA32F colour, float depth) with its read-back
# (the bytes and the array), 36 bytes over 512^2 -> 1024^2 and 62 at 512^2 with llvmpipe's first frame; per sample
# of an anti-aliased one (msaaN: N, ssaaK: K^2, beside its resolved target), 20-25 bytes (512^2 and 768^2).
TARGET_BYTES_PER_PIXEL = 96
BYTES_PER_SAMPLE = 48


@dataclass(frozen=True)
class Geometry:
    """What one object gives a render to hold: its mesh faces (every mesh part of the object), spheres and
    cylinders, and the faces of its displaced reference (a mesostructure's), each with every copy counted (the
    reference merges them)."""
    name: str
    faces: int = 0
    quadrics: int = 0
    displaced: int = 0

    def bytes(self) -> tuple[int, int]:
        """(geometry, displaced reference) bytes."""
        return (self.faces * BYTES_PER_FACE + self.quadrics * BYTES_PER_QUADRIC,
                self.displaced * DISPLACED_BYTES_PER_FACE)


@dataclass(frozen=True)
class Render:
    """A render's settings as far as its memory goes: the frame, how many cameras' frames it keeps, the reference's
    samples per pixel and threads, the variants' anti-aliasing (a mode's (kind, N) of vdmbake.scene.ANTIALIAS), the
    objects, and whether their references are held at once (composite frames trace every object together) or one
    after the other."""
    width: int
    height: int
    cameras: int
    spp: int = 1
    threads: int = 1
    antialias: tuple[str, int] = ("none", 1)
    objects: tuple[Geometry, ...] = ()
    together: bool = False


def samples(antialias: tuple[str, int]) -> int:
    """The samples per pixel of an anti-aliased target (msaaN: N; ssaaK: K^2); 0 without one."""
    kind, n = antialias
    return {"none": 0, "msaa": n, "ssaa": n * n}[kind]


def render_parts(r: Render) -> dict[str, tuple[int, str, str]]:
    """What the render holds at its peak, by part: bytes, what they are, and the setting that lowers them. The
    objects' geometry and displaced references are those of the largest object, or of all of them held together."""
    pixels = r.width * r.height
    tracing = (POINT_BYTES_PER_PIXEL if r.spp == 1
               else FILTERED_BYTES_PER_PIXEL + FILTERED_BYTES_PER_THREAD_PIXEL * (r.threads - 1))
    if r.together:
        o = Geometry("all", *(sum(getattr(g, k) for g in r.objects) for k in ("faces", "quadrics", "displaced")))
        whose = "every object, traced together"
    else:
        o = max(r.objects, key=lambda g: sum(g.bytes()), default=Geometry("none"))
        whose = f"object {o.name!r}"
    geometry, displaced = o.bytes()
    aa = samples(r.antialias)
    return {
        "reference": (pixels * (tracing + r.cameras * HELD_BYTES_PER_CAMERA_PIXEL),
                      f"{r.width}x{r.height} at {r.spp} spp on {r.threads} thread{'s' * (r.threads > 1)}, "
                      f"{r.cameras} cameras' frames", "render.resolution (--resolution), render.reference_spp "
                      "(--reference-spp) or the cameras (camera.orbit.count, camera.poses)"),
        "displaced reference": (displaced, f"{whose}: {o.displaced:,} faces",
                                "the object's mesostructure.tiling or size"),
        "geometry": (geometry, f"{whose}: {o.faces:,} mesh faces, {o.quadrics:,} spheres and cylinders",
                     "fewer or simpler objects, or fewer instances"),
        "targets": (pixels * (TARGET_BYTES_PER_PIXEL * (2 if aa else 1) + BYTES_PER_SAMPLE * aa),
                    f"{r.antialias[0]}{r.antialias[1]}, {aa} samples a pixel" if aa else "none",
                    "render.antialias (--antialias) or render.resolution (--resolution)")}


def render_bytes(r: Render) -> int:
    """The render's estimated peak: the sum of its parts."""
    return sum(b for b, _, _ in render_parts(r).values())


def check_render(r: Render, free: int | None = None) -> None:
    """The render's one memory guard, before any work: refuse it when the sum of its parts is over allowed(`free`),
    naming each part and the setting that lowers the largest."""
    parts = render_parts(r)
    largest = max(parts, key=lambda k: parts[k][0])
    check(render_bytes(r), "the render (" + "; ".join(f"{k} {b / 2**30:.3g} GiB: {what}"
                                                      for k, (b, what, _) in parts.items() if b) + ")",
          f"lower the {largest}: {parts[largest][2]}", free)
