"""The benches' tables, formatted from their JSON: each bench writes its .md with these, and tools/make_docs.py
renders the published JSON (docs/results) with the same functions, so the docs show a figure as the bench
printed it. The standard library only: make_docs runs on the system Python without the packages."""
from __future__ import annotations


def number(v, digits: int) -> str:
    """A figure with `digits` decimals, or "-" where there is none (as vdmrender.common.markdown.number)."""
    return "-" if v is None else f"{v:.{digits}f}"


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
                           number(r["mean_dluv"], 3), number(r["p95_dluv"], 2), number(r["iou"], 4)]
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
        ious = sorted(number(r["iou"], 4) for r in rs)
        rows.append([tag.replace("-", ", "), " / ".join(variants), " / ".join(f"{r['median_cpu_ms']:.1f}" for r in rs),
                     " / ".join(f"{r['median_cpu_ms'] / base:.2f}" for r in rs),
                     " / ".join(number(r["mean_dluv"], 3) for r in rs),
                     ious[0] if ious[0] == ious[-1] else f"{ious[0]}-{ious[-1]}"])
    return markdown(["surface, height", "variant", "CPU ms/frame", "x pom@16", "mean ΔLuv", "IoU"],
                    ["---", "---", "---:", "---:", "---:", "---:"], rows)


def _ratio(p: dict, key: str) -> str:
    """A ratio with its 95% interval (KEY_95)."""
    return f"{p[key]:.2f} ({p[key + '_95'][0]:.2f}-{p[key + '_95'][1]:.2f})"


def billboards(doc: dict) -> str:
    """bench.billboards: each model's bake, every variant at every resolution (with the thesis's figure, appendix
    A-2, beside its own march), and on the profiled model the interleaved passes and the march's costs."""
    out = [markdown(["model", "billboards greedy / axis", "faces left out (greedy)", "maps MB greedy / axis", "bake s",
                     "hier: pyramids MB (float32) / bake s"], ["---", "---:", "---", "---:", "---:", "---:"],
                    [[name, f"{b['greedy']} / {b['axis']}", str(b["leftover"]),
                      f"{b['greedy_mb']:.2f} / {b['axis_mb']:.2f}", f"{b['bake_s']:.1f}",
                      f"{b['pyramid_mb']:.2f} / {b['hier_bake_s']:.2f}"] for name, b in doc["bakes"].items()])]
    rows = []
    for r in doc["rows"]:
        thesis, ref = doc["thesis"].get(r["object"]), ""
        if thesis and r["resolution"] == "800x600" and r["label"].endswith("hit0.01"):
            ref = f"{thesis[0]:.2f}"
        elif thesis and r["resolution"] == "800x600" and r["label"].endswith("hit0.01+coarse"):
            ref = f"{thesis[1]:.2f}"
        rows.append([r["object"], r["resolution"], r["label"], f"{r['median_ms']:.1f}", f"{r['mean_dluv']:.3f}", ref,
                     f"{r['p95_dluv']:.2f}", f"{r['iou']:.4f}"])
    out.append(markdown(["model", "resolution", "variant", "median ms", "mean ΔLuv", "thesis (A-2)", "p95", "IoU"],
                        ["---", "---", "---", "---:", "---:", "---:", "---:", "---:"], rows))
    prof, model = doc["profile"], doc["profiled_model"]
    if prof:
        out += [f"## {model}, interleaved ({doc['rounds']} rounds, every pass timed)", "",
                markdown(["variant", "resolution", "median GPU ms", "x full mesh (95%)", "median CPU ms",
                          "x full mesh, CPU (95%)", "shadow pass share", "passes (median GPU ms)"],
                         ["---", "---", "---:", "---:", "---:", "---:", "---:", "---"],
                         [[p["label"], p["resolution"], f"{p['median_ms']:.1f}", _ratio(p, "ratio_to_mesh"),
                           f"{p['median_cpu_ms']:.1f}", _ratio(p, "cpu_ratio_to_mesh"), f"{p['shadow_share']:.0%}",
                           ", ".join(f"{k} {v:.1f}" for k, v in p["passes_ms"].items())] for p in prof]),
                "Time per halving of the resolution (median CPU ms of one over the next):", ""]
        rows = []
        for label in dict.fromkeys(p["label"] for p in prof):
            t = {p["resolution"]: p["median_cpu_ms"] for p in prof if p["label"] == label}
            if len(t) == 3:
                rows.append([label, f"{t['800x600'] / t['400x300']:.2f}", f"{t['400x300'] / t['200x150']:.2f}"])
        out.append(markdown(["variant", "800x600 / 400x300", "400x300 / 200x150"], ["---", "---:", "---:"], rows))
    if doc["march_cost"]:
        out += [f"## March cost, {model} {doc['cost_resolution']} (instrumented, vdmrender/measuring/counters.py)", "",
                "Per covered pixel, over the frame's passes but the shadow map's; hier's steps are cell visits.", "",
                markdown(["march (+coarse)", "covered pixels", "fragments / px", "fetches / px", "steps / px",
                          "searches / px", "steps / search"], ["---", "---:", "---:", "---:", "---:", "---:", "---:"],
                         [[name, str(c["covered_pixels"]), f"{c['fragments_per_pixel']:.1f}",
                           f"{c['fetches_per_pixel']:.1f}", f"{c['steps_per_pixel']:.1f}",
                           f"{c['searches_per_pixel']:.1f}", f"{c['steps_per_search']:.1f}"]
                          for name, c in doc["march_cost"].items()])]
    return "\n".join(out)


def _category(c: dict | None) -> str:
    """A camera category's cell: mean ΔLuv / IoU / median CPU ms ("" where the model has no such camera)."""
    return "" if not c else f"{number(c['mean_dluv'], 2)} / {number(c['iou'], 3)} / {c['cpu_ms']:,.0f}"


def octahedral(doc: dict) -> str:
    """bench.octahedral: every model, resolution and variant, over all cameras and per camera category."""
    def blank(x):
        return "" if x is None else str(x)
    cats = doc["categories"]
    return "\n".join([
        "Mean and p95 ΔLuv pooled over every scored pixel of every camera (the union of coverage masks; "
        "vdmrender.comparing.metrics.pooled, as vdmrender's rows), IoU averaged over the frames that are not empty, "
        "'-' where no frame had a pixel to score; median GPU ms (timer queries) and CPU ms per frame (shadow pass "
        "included; CPU: the process's time over all its threads, llvmpipe's included, which other processes on the "
        "machine barely inflate); shadow ms: the octahedral shadow pass alone (GPU); asset MB: the textures and "
        "buffers a variant uploads (maps, pyramid atlases, coverage, coarse mesh, occupancy boxes, the octahedral "
        "atlas); target MB: what it renders into every frame besides the frame and its shadow map (the billboards' "
        "depth pre-pass and occupancy targets); bake seconds.", "",
        markdown(["model", "resolution", "variant", "asset MB", "target MB", "bake s", "GPU ms", "CPU ms", "shadow ms",
                  "fetches/px", "steps/px", "mean ΔLuv", "p95", "IoU"], ["---"] * 3 + ["---:"] * 11,
                 [[r["object"], r["resolution"], r["label"], f"{r['gpu_bytes'] / 2**20:.2f}",
                   f"{r['target_bytes'] / 2**20:.2f}", f"{r['bake_s']:.1f}", f"{r['median_ms']:.0f}",
                   f"{r['median_cpu_ms']:.0f}", blank(r.get("shadow_ms")), blank(r.get("fetches_per_pixel")),
                   blank(r.get("steps_per_pixel")), number(r["mean_dluv"], 3), number(r["p95_dluv"], 2),
                   number(r["iou"], 4)] for r in doc["rows"]]),
        "Per camera category: mean ΔLuv / IoU (pooled as above) / median CPU ms over the cameras of that kind.", "",
        markdown(["model", "resolution", "variant", *cats], ["---"] * (3 + len(cats)),
                 [[r["object"], r["resolution"], r["label"],
                   *(_category(r["categories"].get(k)) for k in cats)] for r in doc["rows"]]),
        "outside: the cameras outside the bounding sphere (all but inside). orbit: 8 at 25 degrees; top: top-down and "
        "80 degrees; grazing: 0 and 5 degrees; below: -30 degrees; close: 1.4 and 1.2 radii (fov 50 and 90); inside: "
        "0.95 radii, inside the bounding sphere.\n"])


# docs/impostors.md's digests of bench.octahedral: one model's rows at one resolution, its camera categories,
# its two resolutions side by side, and the primitives outside and inside their bounding spheres
def _octahedral_rows(doc: dict, model: str, resolution: str) -> list[dict]:
    return [r for r in doc["rows"] if r["object"] == model and r["resolution"] == resolution]


def octahedral_model(doc: dict, model: str = "bunny", resolution: str = "800x600") -> str:
    rows = _octahedral_rows(doc, model, resolution)
    mesh = next(r for r in rows if r["label"] == "mesh")

    def blank(x):
        return "" if x is None else f"{x:,.1f}"
    return markdown(["variant", "asset MB", "frame targets MB", "bake s", "GPU ms", "CPU ms", "x mesh (CPU)",
                     "fetches / px", "steps / px", "mean ΔLuv", "p95", "IoU"], ["---"] + ["---:"] * 11,
                    [[r["label"], f"{r['gpu_bytes'] / 2**20:.1f}", f"{r['target_bytes'] / 2**20:.1f}",
                      f"{r['bake_s']:.1f}", f"{r['median_ms']:,.0f}", f"{r['median_cpu_ms']:,.0f}",
                      f"{r['median_cpu_ms'] / mesh['median_cpu_ms']:.2f}", blank(r.get("fetches_per_pixel")),
                      blank(r.get("steps_per_pixel")), number(r["mean_dluv"], 3), number(r["p95_dluv"], 2),
                      number(r["iou"], 4)] for r in rows])


def octahedral_categories(doc: dict, model: str = "bunny", resolution: str = "800x600") -> str:
    rows = _octahedral_rows(doc, model, resolution)
    cats = [c for c in doc["categories"] if c != "outside" and any(c in r["categories"] for r in rows)]
    return markdown(["variant", *cats], ["---"] * (1 + len(cats)),
                    [[r["label"], *(_category(r["categories"][k]) for k in cats)] for r in rows])


def octahedral_resolutions(doc: dict, model: str = "bunny") -> str:
    sizes = list(dict.fromkeys(r["resolution"] for r in doc["rows"] if r["object"] == model))
    at = {(r["label"], r["resolution"]): r for r in doc["rows"] if r["object"] == model}
    labels = list(dict.fromkeys(label for label, _ in at))
    return markdown(["variant", *(f"{s}: CPU ms" for s in sizes), *(f"{s}: mean ΔLuv" for s in sizes)],
                    ["---"] + ["---:"] * (2 * len(sizes)),
                    [[label, *(f"{at[label, s]['median_cpu_ms']:,.0f}" for s in sizes),
                      *(number(at[label, s]["mean_dluv"], 3) for s in sizes)] for label in labels])


def octahedral_primitives(doc: dict, resolution: str = "800x600") -> str:
    return markdown(["model", "variant", "outside", "inside"], ["---"] * 4,
                    [[r["object"], r["label"], _category(r["categories"].get("outside")),
                      _category(r["categories"].get("inside"))]
                     for r in doc["rows"] if r["resolution"] == resolution and r["object"] != "bunny"])


# docs/results.md's digests of bench.billboards: mean ΔLuv at 800x600 per model (the thesis's, appendix A-2, in
# brackets), and the profiled model's interleaved times at each resolution
BILLBOARDS_SELECTED = [("full mesh", "mesh"), ("coarse mesh (10%)", "coarse@0.1"),
                       ("thesis march, hit 0.01", "billboards@greedy-hit0.01"),
                       ("+ coarse mesh", "billboards@greedy-hit0.01+coarse"),
                       ("improved + coarse", "billboards@greedy-improved+coarse"), ("hier", "billboards@greedy-hier"),
                       ("hier + coarse", "billboards@greedy-hier+coarse")]


def billboards_models(doc: dict) -> str:
    by = {(r["object"], r["label"]): r for r in doc["rows"] if r["resolution"] == "800x600"}
    rows = []
    for model in doc["bakes"]:
        thesis = doc["thesis"].get(model)
        cells = []
        for _, label in BILLBOARDS_SELECTED:
            r = by.get((model, label))
            cell = "" if r is None else f"{r['mean_dluv']:.3f}"
            if r is not None and thesis and label.endswith("hit0.01"):
                cell += f" ({thesis[0]:.2f})"
            elif r is not None and thesis and label.endswith("hit0.01+coarse"):
                cell += f" ({thesis[1]:.2f})"
            cells.append(cell)
        faces = by.get((model, "mesh"), {}).get("faces")
        rows.append([f"{model} ({faces:,} faces)" if model not in doc["thesis"] and faces else model, *cells])
    return markdown(["model", *(h for h, _ in BILLBOARDS_SELECTED)], ["---"] + ["---:"] * len(BILLBOARDS_SELECTED), rows)


def billboards_interleaved(doc: dict) -> str:
    prof = doc["profile"]
    at = {(p["label"], p["resolution"]): p for p in prof}
    sizes = list(dict.fromkeys(p["resolution"] for p in prof))
    rows = [[label, *(f"{at[label, s]['median_cpu_ms']:,.0f} ({at[label, s]['cpu_ratio_to_mesh']:.2f})"
                      if (label, s) in at else "" for s in sizes),
             f"{at[label, sizes[0]]['median_ms']:,.0f} ({at[label, sizes[0]]['ratio_to_mesh']:.2f})",
             f"{at[label, sizes[0]]['shadow_share']:.0%}"]
            for label in dict.fromkeys(p["label"] for p in prof)]
    return markdown(["variant", *(f"{s}: CPU ms (x mesh)" for s in sizes), f"{sizes[0]}: GPU ms (x mesh)",
                     f"shadow pass share at {sizes[0]}"], ["---"] + ["---:"] * (len(sizes) + 2), rows)


def _minutes(s: float) -> str:
    return f"{int(s // 60)}:{s % 60:04.1f}"


def suite(doc: dict) -> str:
    """bench.suite: the run's outcome, CPU seconds and wall time."""
    r = doc["run"]
    workers = "one process" if r["workers"] == "0" else f"`-n {r['workers']}`"
    row = [f"{r['commit'][:9]}, {workers}", str(r["tests"]), str(r["passed"]),
           ", ".join(f"{r[k]} {k}" for k in ("failed", "skipped", "xfailed", "xpassed", "errors") if r[k]) or "-",
           f"{r['cpu_s']:.1f} ({r['user_s']:.1f} + {r['sys_s']:.1f})", f"{r['tests_cpu_s']:.1f}",
           f"{r['slow_cpu_s']:.1f} ({r['slow_tests']} tests)", _minutes(r["wall_s"]),
           f"{100 * r['cpu_s'] / r['wall_s']:.0f}%" if r["wall_s"] else "-"]
    failed = r.get("failed_tests") or []
    return markdown(["suite", "tests", "passed", "else", "CPU s (user + sys)", "tests' own CPU s", "slow tests' CPU s",
                     "wall", "CPU / wall"], ["---", "---:", "---:", "---", "---:", "---:", "---:", "---:", "---:"], [row]) + (
        "\nFailed: " + ", ".join(f"`{t}`" for t in failed) + "\n" if failed else "")


def suite_subsets(doc: dict) -> str:
    """bench.suite --ids-of: the tests another commit had, their CPU seconds now, and the tests added since."""
    rows = [[s["commit"][:9], str(s["tests_then"]), str(s["here"]), f"{s['cpu_s']:.1f}", str(len(s["gone"])),
             str(s["added"]), f"{s['added_cpu_s']:.1f}",
             ", ".join(f"{f['file'].removeprefix('tests/')} {f['cpu_s']:.1f}" for f in s["added_by_file"][:4])]
            for s in doc["subsets"]]
    return markdown(["tests of", "then", "here now", "their CPU s now", "gone or renamed", "added since",
                     "their CPU s", "costliest added files (CPU s)"],
                    ["---", "---:", "---:", "---:", "---:", "---:", "---:", "---"], rows)


def suite_files(doc: dict, n: int = 15) -> str:
    """bench.suite: the costliest test files."""
    rows = [[f"`{f['file']}`", str(f["tests"]), f"{f['cpu_s']:.1f}", number(f["slow_cpu_s"] or None, 1)]
            for f in doc["files"][:n]]
    return markdown(["file", "tests", "CPU s", "of which slow tests"], ["---", "---:", "---:", "---:"], rows)


def suite_tests(doc: dict, n: int = 15) -> str:
    """bench.suite: the costliest tests."""
    rows = [[f"`{t['id']}`", f"{t['cpu_s']:.1f}", f"{t['wall_s']:.1f}", "slow" if t["slow"] else ""]
            for t in doc["tests"][:n]]
    return markdown(["test", "CPU s", "wall s", "marker"], ["---", "---:", "---:", "---"], rows)


def _instances_ms(ms: float) -> str:
    return f"{ms:.0f}" if ms >= 1000 else f"{ms:.1f}"


def instances_fields(doc: dict) -> str:
    """bench.instances' digest: per asset and count, each variant's median GPU ms / mean ΔLuv against the merged
    reference ("-": not measured; "not run": the frame would have been over the bench's frame budget; blank: no such
    variant for that asset)."""
    labels = list(dict.fromkeys(r["label"] for r in doc["rows"]))
    rows = []
    for asset in dict.fromkeys(r["asset"] for r in doc["rows"]):
        mine = {(r["copies"], r["label"]): r for r in doc["rows"] if r["asset"] == asset}
        has = {label for _, label in mine}
        faces = next(iter(mine.values()))["faces"]
        for i, n in enumerate(doc["counts"]):
            cells = ["" if label not in has else "not run" if (n, label) not in mine else
                     f"{_instances_ms(mine[n, label]['median_ms'])} / {number(mine[n, label]['mean_dluv'], 2)}"
                     for label in labels]
            rows.append([f"{asset} ({faces:,} faces)" if i == 0 else "", str(n), *cells])
    return markdown(["asset", "copies", *labels], ["---", "---:"] + ["---"] * len(labels), rows)


def instances(doc: dict) -> str:
    """bench.instances: every row, the crossover with the full mesh, the per-copy LOD chains and the bakes."""
    w, h = doc["resolution"]
    rows = [[r["asset"], str(r["copies"]), r["label"], f"{r['median_ms']:.2f}", number(r.get("mean_dluv"), 3),
             "-" if r.get("p95_dluv") is None else str(r["p95_dluv"]), "-" if r.get("iou") is None else str(r["iou"]),
             f"{r['gpu_bytes'] / 2**20:.1f}", str(r["primitives"])] for r in doc["rows"]]
    lines = [markdown(["asset", "copies", "variant", "median GPU ms", "mean ΔLuv", "p95 ΔLuv", "IoU", "GPU MB",
                       "primitives"], ["---", "---:", "---", "---:", "---:", "---:", "---:", "---:", "---:"], rows),
             "Crossover (smallest count at which the variant is faster than the full mesh):", ""]
    for asset, c in doc["crossover"].items():
        lines.append(f"* {asset}: " + ", ".join(f"{k}: {v if v is not None else 'never (up to the largest count run)'}"
                                                 for k, v in c.items()))
    lines += ["", f"Per-copy LOD chains (one copy at {', '.join(map(str, doc['sizes']))} px across, the cheapest "
              f"variant within mean ΔLuv {doc['limit']:g} per band):", ""]
    lines += [f"* {a}: " + ", ".join(f"({e['min_px']}, {e['max_px']}] px {e['variant']}" + ("" if e["meets"] else
                                     " (over the limit)") for e in b["chain"]) for a, b in doc["bakes"].items()]
    lines += ["", "Bake: " + "; ".join(f"{a} {b['bake_s']} s ({', '.join(f'{k} {v}' for k, v in b['steps_s'].items())})"
                                       for a, b in doc["bakes"].items())]
    return (f"Instances on {doc['device']} at {w}x{h}. {doc['how']}".replace("\n", " ") + "\n\n"
            + "Median GPU ms / mean ΔLuv per asset, count and variant:\n\n" + instances_fields(doc) + "\n"
            + "\n".join(lines) + "\n")


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def cluster_runs(doc: dict) -> str:
    """bench.cluster: each set of bundles rendered on one machine and on a local cluster of two workers."""
    rows = []
    for r in doc["runs"]:
        serial = r["scheduler"] is None
        rows.append([f"{r['bundles']} (`{' '.join(r['options'])}`)" if r["options"] else r["bundles"],
                     "one machine" if serial else f"`--scheduler {r['scheduler']}`", f"{r['wall_s']:.1f} s",
                     f"{r['load_end']:.1f}", str(r["rows"]),
                     f"- ({r['traced_s']:.1f} s of it tracing references)" if serial else
                     f"{r['reference_tasks']} reference tasks",
                     "-" if serial else "all" if not r["changed"] else f"NO: {', '.join(r['changed'][:5])}",
                     "-" if serial else f"{len(r['differ'])} of {r['files']}"
                     + (f" ({', '.join(r['differ'][:5])})" if r["differ"] else "")])
    return markdown(["bundles", "run", "wall", "load average (1 min) at its end", "rows", "references",
                     "reports (rows, sweep, chains) the same apart from times",
                     f"files that differ (apart from {', '.join(doc['timing_files'])})"],
                    ["---", "---", "---:", "---:", "---:", "---", "---", "---"], rows)


def cluster_faults(doc: dict) -> str:
    """bench.cluster: each cluster fault as the user meets it."""
    rows = []
    for f in doc["faults"]:
        wall = f"{f['wall_s']:.1f} s" if "wall_s" in f else \
            f"{f['exit_after_kill_s']:.1f} s to exit after the kill (the worker: {f['worker_exit_after_kill_s']:.1f} s)"
        said = (_cell(" / ".join(f["said"])) if "said" in f else
                f"{f['rendered']} of {f['bundles']} bundles rendered, {f['hidden_left']} hidden files left")
        rows.append([f["fault"], f"`{f['command']}`" + (f", {f['then']}" if f.get("then") else ""), str(f["exit"]),
                     wall, said])
    return markdown(["fault", "command", "exit", "wall", "what it prints (the lines that say)"],
                    ["---", "---", "---:", "---", "---"], rows)


def cluster(doc: dict) -> str:
    """bench.cluster's page: how it measured, then its two tables."""
    return (doc["how"].replace("\n", " ") + f" On {doc['device']}; the small bundles ({', '.join(doc['configs'])}) "
            f"baked in {doc['bake_s']:.0f} s, {doc['large']} in {doc['large_bake_s']:.0f} s.\n\n"
            + cluster_runs(doc) + "\n" + cluster_faults(doc))
