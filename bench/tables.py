"""The benches' tables, formatted from their JSON: each bench writes its .md with these, and tools/make_docs.py
renders the published JSON (docs/results) with the same functions, so the docs show a figure as the bench
printed it. The standard library only: make_docs runs on the system Python without the packages."""
from __future__ import annotations


def markdown(header: list[str], align: list[str], rows: list[list[str]]) -> str:
    def line(cells):
        return "|" + "|".join(f" {c} " if c else " " for c in cells) + "|\n"
    return line(header) + "|" + "|".join(align) + "|\n" + "".join(line(r) for r in rows)


def quadrics(doc: dict) -> str:
    """bench.quadrics: every molecule, distance and variant."""
    rows = [[r["object"], str(r["atoms"]), f"{r['distance']:g}", r["label"], f"{r['median_ms']:.1f}",
             f"{r['mean_dluv']:.3f}", f"{r['p95_dluv']:.2f}", f"{r['iou']:.4f}", f"{r['coverage']:.3f}"]
            for r in doc["rows"]]
    return markdown(["molecule", "atoms", "distance", "variant", "median ms", "mean ΔLuv", "p95", "IoU", "coverage"],
                    ["---", "---:", "---:", "---", "---:", "---:", "---:", "---:", "---:"], rows)


# docs/results.md's digest of bench.quadrics: (label, molecule, distance, variants shown side by side)
QUADRICS_SELECTED = [("1VII (villin)", "1vii", 3, ("impostor@direct",)),
                     ("4JSV", "4jsv", 1, ("impostor@direct", "impostor@deferred")),
                     ("DOPC membrane", "dopc", 1, ("impostor@direct", "impostor@deferred")),
                     ("4V8R", "4v8r", 1, ("impostor@direct", "impostor@deferred")),
                     ("6ZU5 (ribosome)", "6zu5", 3, ("impostor@direct", "impostor@deferred")),
                     ("6ZU5", "6zu5", 3, ("tessellated@1", "tessellated@2", "tessellated@3"))]


def _side_by_side(labels: tuple[str, ...]) -> str:
    """("impostor@direct", "impostor@deferred") -> "impostor@direct / deferred"."""
    head = labels[0].split("@")[0]
    return " / ".join([labels[0], *(lb.split("@", 1)[1] if lb.startswith(head + "@") else lb for lb in labels[1:])])


def _joined(values: list[str]) -> str:
    return values[0] if len(set(values)) == 1 else " / ".join(values)


def quadrics_selected(doc: dict) -> str:
    by = {(r["object"], r["distance"], r["label"]): r for r in doc["rows"]}
    rows = []
    for label, mol, distance, variants in QUADRICS_SELECTED:
        rs = [by[(mol, distance, v)] for v in variants if (mol, distance, v) in by]
        if not rs:
            continue
        rows.append([label, f"{rs[0]['atoms']:,}", f"{distance:g}", _side_by_side(tuple(r["label"] for r in rs)),
                     " / ".join(f"{r['median_ms']:.0f}" for r in rs), " / ".join(f"{r['mean_dluv']:.3f}" for r in rs),
                     _joined([f"{r['iou']:.4f}" for r in rs])])
    return markdown(["molecule", "atoms", "distance", "variant", "median ms/frame", "mean ΔLuv", "IoU"],
                    ["---", "---:", "---:", "---", "---:", "---:", "---:"], rows)


def vdm(doc: dict) -> str:
    """bench.vdm: the paper's bake, error against time on every scene, and each scene interleaved (with the
    frame pass's costs)."""
    p = doc["paper_bake"]
    out = [f"## Bake, the paper's configuration ({p['size']}^2, {p['n_phi']} x {p['n_theta']} views, "
           f"{p['curvatures']} curvatures in [-2, 3], bricks)", "",
           f"- total {p['bake_s']:.2f} s: tables {p['tables_s']:.2f} s, SVD to k = 8 {p['svd_s']:.2f} s",
           f"- zero-curvature ray cast: {p['rays']:,} rays in {p['flat_s']:.2f} s = {p['flat_mrays_per_s']:.2f} Mrays/s; "
           f"raw Embree on the same rays {p['raw_mrays_per_s']:.2f} Mrays/s (ratio {p['throughput_ratio']:.2f})",
           f"- raw tables (VDM + MVM, float32): {p['raw_bytes'] / 2**20:.1f} MB; rank {p['rank']}", "",
           markdown(["k", "size MB", "energy kept", "RMS d (texture units)", "max abs d", "RMS theta_MVM (rad)"],
                    ["---", "---:", "---:", "---:", "---:", "---:"],
                    [[f"{key} ({c['k']})", f"{c['bytes'] / 2**20:.2f}", f"{c['energy']:.5f}", f"{c['rms_vdm']:.4f}",
                      f"{c['max_abs_vdm']:.3f}", f"{c['rms_mvm']:.4f}"] for key, c in p["compressed"].items()]),
           f"Weights' storage at k = 8 (the bake keeps {p['storage_chosen']}: the smallest adding at most "
           f"{p['storage_tolerance']:.0%} to the truncation's RMS in quadrature; RMS over every table entry):", "",
           markdown(["W storage", "size MB (W + E)", "added RMS d", "added RMS theta_MVM"], ["---", "---:", "---:", "---:"],
                    [[f, f"{e['bytes'] / 2**20:.3f}", f"{e['rms_vdm']:.5f}", f"{e['rms_mvm']:.5f}"]
                     for f, e in p["storage_k8"].items()]),
           "## Error against time (mean ΔLuv against the displaced geometry traced by Embree)", "",
           markdown(["surface", "height", "variant", "faces", "median ms", "ratio to mesh", "mean ΔLuv", "p95", "IoU"],
                    ["---", "---", "---", "---:", "---:", "---:", "---:", "---:", "---:"],
                    [[r["surface"], r["height"], r["label"], str(r["faces"] or ""), f"{r['median_ms']:.1f}",
                      f"{r.get('ratio_to_baseline', 1.0):.2f}", f"{r['mean_dluv']:.3f}", f"{r['p95_dluv']:.2f}",
                      f"{r['iou']:.4f}"] for r in doc["rows"]])]
    for tag, m in doc["interleaved"].items():
        base = m["rows"]["pom@16"]["median_cpu_ms"]
        out += [f"## {tag}: interleaved in one process (wall and CPU ms per frame, medians)", "",
                markdown(["variant", "median ms", "CPU ms", "CPU ratio to pom@16", "mean ΔLuv", "p95", "IoU"],
                         ["---", "---:", "---:", "---:", "---:", "---:", "---:"],
                         [[k, f"{r['median_ms']:.1f}", f"{r['median_cpu_ms']:.1f}", f"{r['median_cpu_ms'] / base:.2f}",
                           f"{r['mean_dluv']:.3f}", f"{r['p95_dluv']:.2f}", f"{r['iou']:.4f}"]
                          for k, r in m["rows"].items()]),
                "The frame pass's costs per covered pixel (instrumented builds, vdmrender/measuring/counters.py; "
                "fragments: every one the stage ran, discarded ones too), and its fetches per fragment:", ""]
        rows = []
        for k, c in m["costs"].items():
            f, n = c["passes"]["frame"], c["covered"]
            rows.append([k, f"{f['fragments'] / n:.2f}", f"{f['fetches'] / n:.2f}", f"{f['steps'] / n:.2f}",
                         f"{f['searches'] / n:.2f}", f"{f['fetches'] / f['fragments']:.2f}"])
        out.append(markdown(["variant", "fragments", "texture fetches", "search steps", "searches",
                             "fetches / fragment"], ["---", "---:", "---:", "---:", "---:", "---:"], rows))
    return "\n".join(out)


# docs/results.md's digest of bench.vdm's interleaved section: (scene, variants shown side by side)
VDM_SELECTED = [("torus-bricks", ("vdm@8", "vdm@8r2", "vdm@8r4")), ("torus-bricks", ("vdm@4r4",)),
                ("torus-bricks", ("pom@16", "pom@32")), ("torus-bricks", ("relief@16", "relief@32")),
                ("torus-bricks", ("displaced@1", "displaced@2")), ("vase-bricks", ("vdm@8", "vdm@4r4", "vdm@8r4")),
                ("vase-bricks", ("pom@16", "relief@32", "displaced@2")),
                ("torus-gravel", ("vdm@4r4", "pom@16", "relief@32", "displaced@2")),
                ("vase-gravel", ("vdm@4r4", "pom@16", "relief@32", "displaced@2"))]


def vdm_interleaved_cpu(doc: dict) -> str:
    rows = []
    for tag, variants in VDM_SELECTED:
        m = doc["interleaved"].get(tag)
        if m is None:
            continue
        base = m["rows"]["pom@16"]["median_cpu_ms"]
        variants = [v for v in variants if v in m["rows"]]
        rs = [m["rows"][v] for v in variants]
        ious = sorted(f"{r['iou']:.4f}" for r in rs)
        rows.append([tag.replace("-", ", "), " / ".join(variants), " / ".join(f"{r['median_cpu_ms']:.1f}" for r in rs),
                     " / ".join(f"{r['median_cpu_ms'] / base:.2f}" for r in rs),
                     " / ".join(f"{r['mean_dluv']:.3f}" for r in rs),
                     ious[0] if ious[0] == ious[-1] else f"{ious[0]}-{ious[-1]}"])
    return markdown(["surface, height", "variant", "CPU ms/frame", "x pom@16", "mean ΔLuv", "IoU"],
                    ["---", "---", "---:", "---:", "---:", "---:"], rows)
