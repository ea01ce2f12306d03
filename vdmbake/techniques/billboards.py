"""Technique `billboards`: enhanced billboards (Vichitvejpaisal 2005). Each variant names a projection
(greedy set cover, sec. 3.2, or the axis baseline, sec. 4.2), a per-pixel march (the thesis's 100 steps
with hit range 0.01 or 0.02, sec. 3.3 and 4.1, or the improved one) and optionally the coarse mesh that
fills holes (sec. 3.4). The bake makes only the projections and the coarse mesh the variants name;
vdmbake/billboards.py holds the kernels."""
from __future__ import annotations

import time
from dataclasses import dataclass

from .. import billboards, coarse, parts
from ..errors import InputError
from ..schema import Integer, ListOf, Number, Parsed, Technique, setting


@dataclass(frozen=True)
class Variant:
    projection: str   # "greedy" (sec. 3.2) or "axis" (sec. 4.2)
    method: str       # "hit0.01" / "hit0.02": the thesis's march with that hit range; "improved"
    coarse: bool      # the coarse mesh fills holes (sec. 3.4)

    def __str__(self) -> str:
        return f"{self.projection}-{self.method}" + ("+coarse" if self.coarse else "")

    @property
    def hit_range(self) -> float | None:
        """The thesis's hit range e (sec. 3.3 step 2.2), None for the improved march."""
        return float(self.method[3:]) if self.method.startswith("hit") else None


VARIANT = Parsed(r"(greedy|axis)-(hit0\.01|hit0\.02|improved)(\+coarse)?",
                 lambda m: Variant(m[1], m[2], m[3] is not None),
                 "PROJECTION-METHOD[+coarse]: 'greedy-' or 'axis-', then 'hit0.01', 'hit0.02' or 'improved', "
                 "optionally '+coarse'")


@dataclass(frozen=True)
class Options:
    variants: tuple[Variant, ...] = setting(
        tuple(VARIANT.parse(v) for v in ("greedy-hit0.01", "greedy-hit0.02", "greedy-improved",
                                         "greedy-hit0.01+coarse", "greedy-improved+coarse")),
        ListOf(VARIANT), "projection, march and hole filling of each variant", knob="variant")
    resolution: int = setting(512, Integer(8, 4096), "map side in texels")
    coarse_ratio: float = setting(0.1, Number(1e-4, 1.0), "faces kept by the coarse mesh that fills holes")


def bake(job) -> dict:
    """Per projection the variants name: the billboards' maps (alpha, depth, world normal) and the greedy
    choice's statistics; the coarse mesh if a variant fills holes with it."""
    opts, out = job.options, {}
    for mode in dict.fromkeys(v.projection for v in opts.variants):
        t0 = time.perf_counter()
        res = billboards.bake(job.mesh, billboards.Settings(mode=mode, resolution=opts.resolution),
                              log=lambda m: job.log(f"{mode} billboards: {m}"))
        job.steps[f"billboards_{mode}_s"] = round(time.perf_counter() - t0, 3)
        if not res.billboards:
            raise InputError(f"object {job.obj.name!r}: the {mode} projection captures no face of the mesh "
                             f"(faces left out: {res.leftover}); billboards have nothing to draw.")
        rel = job.write(f"billboards-{mode}", parts.BILLBOARDS, res.billboards)
        out[mode] = {"maps": rel, "faces": [len(f) for f in res.faces], "leftover": res.leftover,
                     "candidates": res.candidates, "rays": res.rays}
        job.log(f"{mode} billboards: {len(res.billboards)} from {res.candidates} candidate directions, "
                f"{job.writer.parts[rel]['bytes'] / 2**20:.2f} MB; faces left out {res.leftover}")
    if any(v.coarse for v in opts.variants):
        c = coarse.simplify(job.mesh, opts.coarse_ratio)
        out["coarse"] = job.write("billboards-coarse", parts.MESH, c)
        job.log(f"billboards' coarse mesh {len(c.faces)} faces")
    return out


TECHNIQUE = Technique("billboards", "enhanced billboards: per billboard its box, per pixel a march through its "
                      "depth map, exact depth, optional coarse-mesh hole filling", ("surface",), Options, bake=bake)
