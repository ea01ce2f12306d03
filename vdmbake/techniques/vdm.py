"""Technique `vdm`: view-dependent displacement mapping (Wang et al. 2003). The bake casts the
zero-curvature tables, bends them to the curvature range the base mesh has (Wang2003 Appendix), adds the
MVM, compresses [A_VDM, A_MVM] by SVD to the largest k the scene renders (Wang2003 §3.1-3.3), and stores
the weights in the smallest format whose rounding the truncation hides (vdmbake/kernels/vdm_storage.py);
vdmbake/kernels/vdm.py holds the kernels. Each variant is a k and a refine setting: refine 0 is the paper's
per-pixel algorithm, R > 0 finishes the view ray's hit and the self-shadow on the height field."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

from ..bundle import budget, parts
from ..common import texspace
from ..kernels import vdm, vdm_storage
from ..schema import Choice, Either, Integer, ListOf, Technique, setting


@dataclass(frozen=True)
class Variant:
    k: int | str      # eigenfunctions reconstructed, or "all"
    refine: int       # 0: the paper's algorithm; R: R + 1 height samples around the lookup's hit, R toward the light

    def __str__(self) -> str:
        return f"{self.k}" if self.refine == 0 else f"{self.k}r{self.refine}"

    def plain(self):
        """The report's value: k alone for the paper's algorithm (as before refinement), else the label's."""
        return self.k if self.refine == 0 else str(self)


@dataclass(frozen=True)
class Options:
    k: tuple = setting((1, 2, 4, 8), ListOf(Either(Integer(1, 256), Choice("all"))),
                       "eigenfunctions of the SVD reconstructed per pixel; \"all\" keeps every one (the "
                       "uncompressed table, up to the weights' storage)", knob="k")
    refine: tuple[int, ...] = setting((0,), ListOf(Integer(0, 64)),
                                      "0: the paper's algorithm; R: the hit finished with R + 1 samples of the height "
                                      "field around the lookup's, the self-shadow with R samples toward the light "
                                      "(each value with each k: variants vdm@K and vdm@KrR)")


def variants(options: Options) -> list[Variant]:
    return [Variant(k, r) for r in options.refine for k in options.k]


def check_memory(m, origin: str, free: int | None = None, k: int | str = "all") -> None:
    """Refuse, before the bake starts, VDM tables whose bake (k eigenfunctions) would not fit the memory budget
    (vdmbake.bundle.budget; `free`: the available memory, measured if None)."""
    table = m.size ** 2 * m.phi * m.theta * m.curvatures * 4
    budget.check(vdm.bake_bytes(m.size, m.phi, m.theta, m.curvatures, k),
                 f"{origin}: the VDM table of mesostructure size {m.size}, phi {m.phi}, theta {m.theta}, curvatures "
                 f"{m.curvatures} ({table / 2**30:.1f} GiB, k = {k})",
                 "lower mesostructure.size, phi, theta or curvatures, or k", free)


def bake(job) -> dict:
    m, mesh, ks = job.obj.mesostructure, job.mesh, job.options.k
    check_memory(m, f"object {job.obj.name!r}", k="all" if "all" in ks else max(ks))
    lo, hi = texspace.curvature_range(mesh.frame, mesh.normals, m.tiling)
    sampling = vdm.Sampling(m.size, m.phi, m.theta, vdm.curvature_samples(lo, hi, m.curvatures))
    t0 = time.perf_counter()
    table, theta_mvm, rays = vdm.bake_tables(job.maps.heights.astype("f8"), m.depth, sampling)
    t1 = time.perf_counter()
    k = table.shape[3] * table.shape[4] + table.shape[4] if "all" in ks else max(ks)
    comp = vdm.compress(table, theta_mvm, k, report=[x for x in ks if x != "all"])
    t2 = time.perf_counter()
    k = comp.W.shape[-1]
    errors = vdm_storage.storage_errors(comp.W, comp.E_vdm, comp.E_mvm)
    storage = vdm_storage.choose(errors, comp.errors[k].rms_vdm, comp.errors[k].rms_mvm)
    stored, scale, offset = vdm_storage.quantise(comp.W, storage)
    t3 = time.perf_counter()
    tables = parts.VDMTables(W=stored.transpose(2, 0, 1, 3), E_vdm=comp.E_vdm.transpose(0, 2, 1), E_mvm=comp.E_mvm,
                             scale=scale, offset=offset)
    entry = {
        "tables": job.write("vdm", parts.VDM, tables), "k": k, "rank": comp.rank,
        "curvatures": list(sampling.curvatures), "rays": rays, "table_bytes": table.nbytes + theta_mvm.nbytes,
        "compressed_bytes": stored.nbytes + comp.E_vdm.nbytes + comp.E_mvm.nbytes, "storage": storage,
        "storage_errors": {f: {q: round(v, 7) for q, v in e.items()} for f, e in errors.items()},
        "errors": {str(kk): {f: round(getattr(e, f), 6) for f in ("energy", "rms_vdm", "rms_mvm", "max_abs_vdm")}
                   for kk, e in comp.errors.items()}}
    job.steps.update(vdm_tables_s=round(t1 - t0, 3), vdm_svd_s=round(t2 - t1, 3), vdm_storage_s=round(t3 - t2, 3))
    job.log(f"VDM {m.size}^2 x {m.phi} phi x {m.theta} theta x {len(sampling.curvatures)} curvatures "
            f"[{lo:.3g}, {hi:.3g}], {rays:,} rays in {t1 - t0:.2f} s; SVD k = {k} (rank {comp.rank}) in "
            f"{t2 - t1:.2f} s, {entry['table_bytes'] / 2**20:.1f} MB -> {entry['compressed_bytes'] / 2**20:.2f} MB "
            f"(W as {storage})")
    return entry


def reads(entry: dict, variant: Variant, obj) -> dict:
    """The tables; k, and the curvature samples (increasing finite numbers) the renderer's axis is made of."""
    k, cs = entry["k"], entry["curvatures"]
    if isinstance(k, bool) or not isinstance(k, int) or k < 1 or not cs or not all(
            isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in cs) or any(
            b <= a for a, b in zip(cs, cs[1:])):
        raise ValueError("k or curvatures")
    return {entry["tables"]: parts.VDM}


TECHNIQUE = Technique("vdm", "view-dependent displacement mapping, the paper's four steps per pixel over the base "
                      "mesh: silhouette from the MVM, real texture coordinate, self-shadow by a second lookup, "
                      "shading; d and theta_MVM rebuilt from the SVD; refined on the height field as an option",
                      ("surface",), Options, mesostructure=True, bake=bake, combine=variants,
                      reads=reads)
