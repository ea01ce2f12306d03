"""Technique `billboards`: enhanced billboards (Vichitvejpaisal2005). Each variant names a projection
(greedy set cover, Vichitvejpaisal2005 §3.2, or the axis baseline, §4.2), a per-pixel march (the thesis's 100 steps
with hit range 0.01 (Vichitvejpaisal2005 §4.1) or 0.02 (§3.4); the improved one; or hier, the exact hierarchical trace
through a min/max pyramid of each depth map, beyond the thesis) and optionally the coarse mesh that
fills holes (Vichitvejpaisal2005 §3.4). The bake makes only the projections, pyramids and coarse mesh the variants
need; vdmbake/kernels/billboards.py and vdmbake/kernels/billboard_maps.py hold the kernels."""
from __future__ import annotations

import os
import time
from dataclasses import dataclass

from ..kernels import billboard_maps, billboards
from ..bundle import budget, parts
from ..common import texture
from ..errors import InputError
from ..schema import Integer, ListOf, Number, Parsed, Technique, setting
from .coarse import simplified


@dataclass(frozen=True)
class Variant:
    projection: str   # "greedy" (Vichitvejpaisal2005 §3.2) or "axis" (§4.2)
    method: str       # "hit0.01" / "hit0.02": the thesis's march with that hit range; "improved"; "hier"
    coarse: bool      # the coarse mesh fills holes (Vichitvejpaisal2005 §3.4)

    def __str__(self) -> str:
        return f"{self.projection}-{self.method}" + ("+coarse" if self.coarse else "")

    @property
    def hit_range(self) -> float | None:
        """The thesis's hit range e (Vichitvejpaisal2005 §3.3 step 2.2), None for the improved march."""
        return float(self.method[3:]) if self.method.startswith("hit") else None


VARIANT = Parsed(r"(greedy|axis)-(hit0\.01|hit0\.02|improved|hier)(\+coarse)?",
                 lambda m: Variant(m[1], m[2], m[3] is not None),
                 "PROJECTION-METHOD[+coarse]: 'greedy-' or 'axis-', then 'hit0.01', 'hit0.02', 'improved' or "
                 "'hier', optionally '+coarse'")


@dataclass(frozen=True)
class Options:
    variants: tuple[Variant, ...] = setting(
        tuple(VARIANT.parse(v) for v in ("greedy-hit0.01", "greedy-hit0.02", "greedy-improved",
                                         "greedy-hit0.01+coarse", "greedy-improved+coarse")),
        ListOf(VARIANT), "projection, march and hole filling of each variant", knob="variant")
    resolution: int = setting(512, Integer(8, 4096), "map side in texels")
    coarse_ratio: float = setting(0.1, Number(1e-4, 1.0), "faces kept by the coarse mesh that fills holes")


# Peak bytes per texel of a billboard: its maps, bordered maps and pyramid as baked and read back (measured with
# pyramids: 177 on 6 maps of 1024^2, 160 on 8, 129 on 6 of 2048^2; colour maps add 40, estimated from their
# channels); while the maps are traced, 24 per texel of each billboard made and 180 of each traced at once, one per
# CPU (measured: 22 and 172).
BOARD_BYTES, COLOUR_BYTES, KEPT_BYTES, TRACE_BYTES = 200, 40, 24, 180


def bake_bytes(resolution: int, boards: int, coloured: bool = False) -> int:
    """The peak memory of a projection's bake that makes `boards` billboards of resolution^2 texels, estimated
    (vdmbake.bundle.budget): the larger of the parts' phase and the tracing's."""
    return resolution ** 2 * max(boards * (BOARD_BYTES + COLOUR_BYTES * coloured),
                                 boards * KEPT_BYTES + min(boards, os.cpu_count() or 1) * TRACE_BYTES)


def max_boards(job, coloured: bool) -> int:
    """The most billboards (up to the kernel's max_billboards) a projection's bake may make within the memory
    budget: the kernel is held to it, so the bake never outgrows the budget; refused if not one billboard fits. The
    count is chosen against the fixed BUDGET, so the bundle does not depend on the machine's load."""
    r = job.options.resolution
    boards = next((n for n in range(billboards.Settings.max_billboards, 0, -1)
                   if bake_bytes(r, n, coloured) <= budget.BUDGET), 0)
    budget.check(bake_bytes(r, max(boards, 1), coloured), f"object {job.obj.name!r}: a billboard of {r}^2 texels"
                 + (" with its colour map" if coloured else ""), "lower techniques.billboards.resolution")
    return boards


def bake(job) -> dict:
    """Per projection the variants name: the billboards' maps (alpha, depth, world normal, and colour for an
    asset with its own colours), the greedy
    choice's statistics, the bordered maps the renderers sample and, for hier, the pyramids; the coarse
    mesh if a variant fills holes with it or hier casts its shadows with it."""
    opts, out = job.options, {}
    coloured = texture.has_albedo(job.mesh)
    boards = max_boards(job, coloured)
    for mode in dict.fromkeys(v.projection for v in opts.variants):
        t0 = time.perf_counter()
        settings = billboards.Settings(mode=mode, resolution=opts.resolution, max_billboards=boards)
        res = billboards.bake(job.mesh, settings, log=lambda m: job.log(f"{mode} billboards: {m}"))
        job.steps[f"billboards_{mode}_s"] = round(time.perf_counter() - t0, 3)
        if boards < billboards.Settings.max_billboards and res.leftover["over_budget"]:
            raise InputError(f"object {job.obj.name!r}: the {mode} projection needs more billboards of "
                             f"{opts.resolution}^2 texels than the {boards} whose bake fits the memory budget (about "
                             f"{bake_bytes(opts.resolution, boards, coloured) / 2**30:.1f} GiB, vdmbake.bundle.budget"
                             "); lower techniques.billboards.resolution.")
        if not res.billboards:
            raise InputError(f"object {job.obj.name!r}: the {mode} projection captures no face of the mesh "
                             f"(faces left out: {res.leftover}); billboards have nothing to draw.")
        rel = job.write(f"billboards-{mode}", parts.BILLBOARDS, res.billboards)
        out[mode] = {"maps": rel, "faces": [len(f) for f in res.faces], "leftover": res.leftover,
                     "candidates": res.candidates, "rays": res.rays}
        job.log(f"{mode} billboards: {len(res.billboards)} from {res.candidates} candidate directions"
                + (" with colour maps" if res.billboards[0].albedo is not None else "") + ", "
                f"{job.writer.parts[rel]['bytes'] / 2**20:.2f} MB; faces left out {res.leftover}")
        traced = any(v.projection == mode and v.method == "hier" for v in opts.variants)
        t0 = time.perf_counter()
        maps = [billboard_maps.bordered(b, traced) for b in res.billboards]   # float32 maps: as stored
        job.steps[f"billboards_{mode}_bordered_s"] = round(time.perf_counter() - t0, 3)
        out[mode]["bordered"] = rel = job.write(f"billboards-{mode}-bordered", parts.BORDERED, maps)
        if traced:
            out[mode]["pyramid_bytes"] = sum(m.pyramid.nbytes for m in maps)
        job.log(f"{mode} billboards: bordered maps" + (" and pyramids" if traced else "")
                + f" {job.writer.parts[rel]['bytes'] / 2**20:.2f} MB in {job.steps[f'billboards_{mode}_bordered_s']:.2f} s")
    if any(v.coarse or v.method == "hier" for v in opts.variants):
        c = simplified(job, opts.coarse_ratio, "techniques.billboards.coarse_ratio")
        out["coarse"] = job.write("billboards-coarse", parts.MESH, c)
        job.log(f"billboards' coarse mesh {len(c.faces)} faces")
    return out


def reads(entry: dict, variant: Variant, obj) -> dict:
    p = entry[variant.projection]
    out = {p["maps"]: parts.BILLBOARDS, p["bordered"]: parts.BORDERED}
    if variant.coarse or variant.method == "hier":
        out[entry["coarse"]] = parts.MESH
    return out


TECHNIQUE = Technique("billboards", "enhanced billboards: per pixel a march (or, hier, an exact hierarchical "
                      "trace) through each billboard's depth map, exact depth, optional coarse-mesh hole filling",
                      ("surface",), Options, bake=bake, reads=reads)
