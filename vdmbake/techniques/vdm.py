"""Technique `vdm`: view-dependent displacement mapping (Wang et al. 2003). The bake casts the
zero-curvature tables, bends them to the curvature range the base mesh has (the Appendix), adds the
MVM, and compresses [A_VDM, A_MVM] by SVD to the largest k the scene renders (sec. 3.1-3.3);
vdmbake/vdm.py holds the kernels."""
from __future__ import annotations

import time
from dataclasses import dataclass

from .. import parts, texspace, vdm
from ..schema import Choice, Either, Integer, ListOf, Technique, setting


@dataclass(frozen=True)
class Options:
    k: tuple = setting((1, 2, 4, 8), ListOf(Either(Integer(1, 256), Choice("all"))),
                       "eigenfunctions of the SVD reconstructed per pixel; \"all\" keeps every one (the "
                       "uncompressed table, up to float32 rounding)", knob="k")


def bake(job) -> dict:
    m, mesh = job.obj.mesostructure, job.mesh
    lo, hi = texspace.curvature_range(mesh.frame, mesh.normals, m.tiling)
    sampling = vdm.Sampling(m.size, m.phi, m.theta, vdm.curvature_samples(lo, hi, m.curvatures))
    t0 = time.perf_counter()
    table, theta_mvm, rays = vdm.bake_tables(job.maps.heights.astype("f8"), m.depth, sampling)
    t1 = time.perf_counter()
    ks = job.options.k
    k = table.shape[3] * table.shape[4] + table.shape[4] if "all" in ks else max(ks)
    comp = vdm.compress(table, theta_mvm, k, report=[x for x in ks if x != "all"])
    t2 = time.perf_counter()
    tables = parts.VDMTables(W=comp.W.transpose(2, 0, 1, 3), E_vdm=comp.E_vdm.transpose(0, 2, 1),
                             E_mvm=comp.E_mvm)
    k = comp.W.shape[-1]
    entry = {
        "tables": job.write("vdm", parts.VDM, tables), "k": k, "rank": comp.rank,
        "curvatures": list(sampling.curvatures), "rays": rays, "table_bytes": table.nbytes + theta_mvm.nbytes,
        "compressed_bytes": comp.W.nbytes + comp.E_vdm.nbytes + comp.E_mvm.nbytes,
        "errors": {str(kk): {f: round(getattr(e, f), 6) for f in ("energy", "rms_vdm", "rms_mvm", "max_abs_vdm")}
                   for kk, e in comp.errors.items()}}
    job.steps.update(vdm_tables_s=round(t1 - t0, 3), vdm_svd_s=round(t2 - t1, 3))
    job.log(f"VDM {m.size}^2 x {m.phi} phi x {m.theta} theta x {len(sampling.curvatures)} curvatures "
            f"[{lo:.3g}, {hi:.3g}], {rays:,} rays in {t1 - t0:.2f} s; SVD k = {k} (rank {comp.rank}) in "
            f"{t2 - t1:.2f} s, {entry['table_bytes'] / 2**20:.1f} MB -> {entry['compressed_bytes'] / 2**20:.2f} MB")
    return entry


TECHNIQUE = Technique("vdm", "view-dependent displacement mapping, the paper's four steps per pixel over the base "
                      "mesh: silhouette from the MVM, real texture coordinate, self-shadow by a second lookup, "
                      "shading; d and theta_MVM rebuilt from the SVD", ("surface",), Options, mesostructure=True,
                      bake=bake)
