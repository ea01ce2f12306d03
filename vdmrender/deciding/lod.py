"""Error-driven LOD chains (issue 22): from a screen-size sweep (vdmrender.views.sweep), per object and per set of
limits (scene.Thresholds), the cheapest variant within the limits at each measured size, merged into bands of
screen sizes (vdmrender.reporting.chains writes them: lod.json, lod.md, lod.png).

The limits bound what a switch changes (issue 39): each variant's frames against the object's full asset drawn the
same way (vdmrender.comparing.change), or, where a chain says limit_on = "reference", the error against the reference. A
variant measured at size s is chosen for the band of sizes from s down to the next smaller measured size
(exclusive): the band is judged at its largest size, where a fixed-resolution impostor's error is largest and a
mesh's cost is about the same, so the choice is conservative within its band. Cheapest is decided on the variants'
interleaved frames where the sweep timed them so (vdmrender.deciding.pricing: every variant within the limits and within
4x of the fastest's median, frame beside frame under the same load; a variant costs the same as the fastest
unless the 95% confidence interval of their paired log-ratios lies wholly above 10%), else on separately timed
medians (the same within their interquartile spreads together or 10% of the cheaper); of levels of detail that
compare (more triangles is finer; the full asset finest of all), a finer one that costs no less than a coarser one
within the limits is not taken; of the variants left that cost the same, the one of least mean change (or error)
is taken, where errors against the reference closer than the reference's noise are ties decided by cost, so that
two runs pick the same chain. A chain never switches to a finer level at a smaller size unless it is cheaper
there, or the level above is over the limits there (the finer one then takes the bands above it too, where it is
within the limits), so a chain of triangle meshes is the order MSFT_lod and engines express. Where no variant is within the limits,
the one of least mean change is taken (the error against the reference cannot rank there: the full asset's own
error is the floor). With pop_dluv, a switch that would pop more is avoided where a variant within the limits pops
less."""
from __future__ import annotations

import math

import numpy as np

from vdmbake.scene import BY_FACES, LIMIT_ON, TRIANGLE_MESHES

from . import pricing
from .baseline import POINT

CHANGE = LIMIT_ON["change"]["mean_dluv"]   # the mean change against the full asset (vdmrender.comparing.change)
MEASURED = ("mean_dluv", "p95_dluv", "flip_mean", "iou", "aliased_mean_dluv", *LIMIT_ON["change"].values(),
            "floor_dluv", "reference_noise_dluv", "median_ms", "spread_ms", "empty_frames")


def meets(row: dict, limits: dict) -> bool:
    """Every limit holds (an IoU at least its limit, the others at most theirs); a value that was not measured
    (every frame empty) holds none."""
    return all(row.get(k) is not None and (row[k] >= v if k.endswith("iou") else row[k] <= v)
               for k, v in limits.items())


def noise(row: dict, error: str) -> float:
    """The noise of a row's `error`: the reference's own sampling noise for the error against it, none for the change
    against the full asset (two GL frames of one device)."""
    return (row.get("reference_noise_dluv") or 0.0) if error == LIMIT_ON["reference"]["mean_dluv"] else 0.0


def tie(a: dict, b: dict, error: str) -> bool:
    """Two rows' `error`s closer than their noises together (noise): no difference the measurement can show."""
    return abs(a[error] - b[error]) <= math.hypot(noise(a, error), noise(b, error))


def least(rows: list[dict], error: str) -> dict:
    """The row of least `error` (unmeasured last), where errors that tie (tie) are decided by cost, then by
    label."""
    measured = [r for r in rows if r.get(error) is not None]
    if not measured:
        return min(rows, key=lambda r: (r["median_ms"], r["label"]))
    best = min(measured, key=lambda r: r[error])
    tied = [r for r in measured if tie(r, best, error)]
    return min(tied, key=lambda r: (r["median_ms"], r["label"]))


def _cost_ties(rows: list[dict]) -> list[dict]:
    """The rows that cost the same as the cheapest: where every row within pricing.NEAR of the fastest median
    carries its interleaved frame times (`interleaved_ms`, aligned), pricing's "same" (or a difference it could not
    show); otherwise those pricing.slower does not find slower by their separately timed medians."""
    best = min(rows, key=lambda r: r["median_ms"])
    near = [r for r in rows if r["median_ms"] <= pricing.NEAR * best["median_ms"]]
    paired = len(near) > 1 and all(r.get("interleaved_ms") for r in near) and len({len(r["interleaved_ms"]) for r in near}) == 1
    if paired:
        verdict = pricing.verdicts({r["label"]: np.array(r["interleaved_ms"]) for r in near})
        return [r for r in near if verdict[r["label"]] != "slower"]
    return [r for r in rows if not pricing.slower(best, r)]


def cheapest(rows: list[dict], error: str = CHANGE) -> dict:
    """The cheapest row: a level of detail finer than another that costs no less is never it (the coarser serves as
    well); of those left that cost the same (_cost_ties), the one of least `error` (least)."""
    rows = [r for r in rows if not any(finer(r, o) and not cheaper(r, o) for o in rows)]
    return least(_cost_ties(rows), error)


def cheaper(a: dict, b: dict) -> bool:
    """Row a costs less than row b: b is slower by pricing's verdict on their interleaved frames, or by their
    separately timed medians (as _cost_ties)."""
    return a["median_ms"] < b["median_ms"] and b not in _cost_ties([a, b])


def detail(row: dict) -> float | None:
    """A row's level of detail where levels compare: the full asset's the finest, a triangle mesh's its triangles;
    None for the others (impostors: no rank among meshes)."""
    if row["label"] == row.get("change_against"):
        return math.inf
    return row.get("faces") if row.get("technique") in BY_FACES else None


def finer(a: dict, b: dict) -> bool:
    da, db = detail(a), detail(b)
    return da is not None and db is not None and da > db


def contenders(rows: list[dict], lod_sets) -> set[str]:
    """The variants (labels) at one screen size that may be some chain's cheapest: for every set of limits
    (scene.Thresholds), those within them and within pricing.NEAR of the fastest of them by their own medians
    (the sweep times these again, interleaved)."""
    out = set()
    for t in lod_sets:
        ok = [r for r in rows if meets(r, t.limits())]
        if ok:
            fastest = min(r["median_ms"] for r in ok)
            out |= {r["label"] for r in ok if r["median_ms"] <= pricing.NEAR * fastest}
    return out


def chain(rows: list[dict], limits: dict, height: int, pop=None, pop_dluv: float | None = None,
          hysteresis: float = 0.0, error: str = CHANGE) -> dict:
    """One object's chain: entries from the largest screen size down, each {variant, band, measured}. `error`: the
    mean the limits are on, which ranks variants of equal cost (cheapest). Monotone in detail: a variant finer than
    the level above is taken at a smaller size only where it is cheaper than that level there, or where that level
    is over the limits there and it is not; then it takes the sizes above, down from the coarser level, too (where it
    is within the limits there). pop(size, a, b): the mean ΔLuv between variants a's and b's frames at that size
    (None: not measured); with pop_dluv, a switch that would pop more is avoided where another variant within the
    limits pops less (the previous one itself pops 0). Each switch records its pop and its hysteresis band
    (switch_px)."""
    sizes = sorted({r["size_px"] for r in rows}, reverse=True)
    at = {(r["size_px"], r["label"]): r for r in rows}
    picks, needed = [], []   # needed: the picks finer than the level above because that one was over the limits
    for s in sizes:
        here = [r for r in rows if r["size_px"] == s]
        above = at.get((s, picks[-1][1]["label"])) if picks else None
        ok = [r for r in here if meets(r, limits)]   # with the level above among them, cheapest keeps finer ones out
        if ok and above is not None and pop is not None and pop_dluv is not None:
            smooth = [r for r in ok if r is above or pop(s, above["label"], r["label"]) <= pop_dluv]
            ok = smooth or ok
        pick = cheapest(ok, error) if ok else least(here, CHANGE)
        picks.append((s, pick, bool(ok)))
        if above is not None and not meets(above, limits) and finer(pick, above):
            needed.append(len(picks) - 1)
    for i in reversed(needed):   # the finer level needed here also takes the coarser bands above it
        for j in range(i - 1, -1, -1):
            s, r, _ = picks[j]
            up = at.get((s, picks[i][1]["label"]))
            if up is None or not finer(up, r) or not meets(up, limits):
                break
            picks[j] = (s, up, True)
    entries = []
    for i, (s, r, ok) in enumerate(picks):
        low = sizes[i + 1] if i + 1 < len(sizes) else 0
        point = {"size_px": s, **{k: r.get(k) for k in MEASURED}, "per_pixel": r.get("per_pixel")}
        if entries and entries[-1]["variant"] == r["label"] and entries[-1]["meets"] == ok:
            entries[-1]["min_px"] = low
            entries[-1]["measured"].append(point)
        else:
            if entries and entries[-1]["variant"] != r["label"]:   # the switch from the finer level above, here
                a = entries[-1]["variant"]
                entries[-1]["switch_px"] = [round(s * (1 - hysteresis), 3), round(s * (1 + hysteresis), 3)]
                point["pop_dluv"] = pop(s, a, r["label"]) if pop is not None else None
            entries.append({"variant": r["label"], "technique": r["technique"], "value": r["value"],
                            "max_px": s, "min_px": low, "meets": ok, "measured": [point]})
    for e in entries:   # MSFT_screencoverage's unit: the share of the frame's height (vdmbake.export)
        e["screen_coverage"] = [round(e["max_px"] / height, 6), round(e["min_px"] / height, 6)]
    pops = [e["measured"][0]["pop_dluv"] for e in entries if "pop_dluv" in e["measured"][0]]
    return {"entries": entries, "unmet_px": [s for s, _, ok in picks if not ok], "above_px": sizes[0],
            "pops_dluv": pops, "pops_meet": None if pop_dluv is None or None in pops else max(pops, default=0) <= pop_dluv}


def floor(rows: list[dict]) -> list[dict]:
    """Per size, from the largest, what no variant of the object can change (vdmrender.comparing.change): the full asset's
    mean and p95 ΔLuv against the reference and the reference's own noise, and of the pairs of variants measured
    there, how many differ in mean ΔLuv against the reference by less than the noise of both (ties by that error)."""
    out = []
    for s in sorted({r["size_px"] for r in rows}, reverse=True):
        here = [r for r in rows if r["size_px"] == s]
        errs = [r for r in here if r["mean_dluv"] is not None]
        pairs = [(a, b) for i, a in enumerate(errs) for b in errs[i + 1:]]
        ties = [1 for a, b in pairs if tie(a, b, "mean_dluv")]
        out.append({"size_px": s, "full_asset": here[0].get("change_against"), "floor_dluv": here[0].get("floor_dluv"),
                    "floor_p95_dluv": here[0].get("floor_p95_dluv"), "floor_iou": here[0].get("floor_iou"),
                    "reference_noise_dluv": here[0].get("reference_noise_dluv"), "pairs": len(pairs), "ties": len(ties)})
    return out


def _object_chains(rows: list[dict], t, height: int, pop=None) -> dict:
    """The chain over every variant, and where the object has triangle-mesh variants, the chain over those
    alone (`meshes_only`: what a glTF with MSFT_lod carries). t: the chain's scene.Thresholds."""
    meshes = [r for r in rows if r["technique"] in TRIANGLE_MESHES]
    error = LIMIT_ON[t.limit_on]["mean_dluv"]
    one = lambda rs: chain(rs, t.limits(), height, pop, t.pop_dluv, t.hysteresis, error)   # noqa: E731
    return {**one(rows), **({"meshes_only": one(meshes)} if meshes else {})}


def object_chains(rows: list[dict], lod_sets, height: int, pop=None) -> dict[str, dict]:
    """One object's chains from its sweep rows, by the name of their set of limits (scene.Thresholds); pop(size, a,
    b): the mean ΔLuv between two variants' frames at that size (vdmrender.render: the sweep's frames compared)."""
    return {t.name: _object_chains(rows, t, height, pop) for t in lod_sets}


def chains(per_object: dict[str, dict], sweep_rows: list[dict], lod_sets, device: str, resolution,
           filtering: dict | None = None) -> dict:
    """lod.json's content: per set of limits, per object, its chain (per_object: {object: object_chains}) as
    measured on the sweep (`sweep_rows`); `filtering`: what the errors judged are against (report.json's: the
    reference's samples per pixel, the frames' anti-aliasing)."""
    filtering = filtering or POINT
    return {"device": device, "resolution": list(resolution), "sizes_px": sorted({r["size_px"] for r in sweep_rows},
                                                                                  reverse=True),
            "error": {"reference_spp": filtering["reference_spp"], "antialias": filtering["antialias"]},
            "band": "an entry is chosen where the object's bounding sphere spans more than min_px and at most "
                    "max_px pixels on screen; screen_coverage: the same as shares of the frame's height; switch_px: "
                    "with hysteresis, switch to the next entry below the first size and back above the second; "
                    "pop_dluv: at the size an entry takes over, the mean ΔLuv between its frames and the previous "
                    "entry's (what a viewer sees change at the switch)",
            "rule": __doc__.split("\n\n", 1)[1].replace("\n", " "),
            "floors": {o: floor([r for r in sweep_rows if r["object"] == o]) for o in per_object},
            "chains": [{"name": t.name, "limit_on": t.limit_on, "limits": t.limits(), "pop_dluv": t.pop_dluv,
                        "hysteresis": t.hysteresis, "objects": {o: by_name[t.name] for o, by_name in per_object.items()}}
                       for t in lod_sets]}


def priced_on_field(lod: dict, rows: list[dict]) -> None:
    """Chains priced where they are used: for an object drawn as many copies, its lod@CHAIN row (every copy by the
    variant its size selects, vdmrender.views.lodmix.mixed) against every single variant drawing the same field. The
    cheapest of those within the chain's limits on the field (cheapest's rule) is what the field ships: where
    that is a single variant, the chain becomes that variant at every size (the sweep's chain kept as
    sweep_entries), so a chain is never slower than one representation meeting the same limits there. Where none
    is within the limits on the field, the one of least change is shipped (as at a chain's size)."""
    for c in lod["chains"]:
        for obj, ch in c["objects"].items():
            field = [r for r in rows if r["object"] == obj and (r["technique"] != "lod" or r["value"] == c["name"])]
            if not any(r["technique"] == "lod" for r in field):
                continue
            ok = [r for r in field if meets(r, c["limits"])]
            best = cheapest(ok, LIMIT_ON[c["limit_on"]]["mean_dluv"]) if ok else least(field, CHANGE)
            ch["field"] = {"how": " ".join(priced_on_field.__doc__.split()), "chosen": best["label"],
                           "candidates": [{"variant": r["label"], "median_ms": r["median_ms"],
                                           "spread_ms": r["spread_ms"], "change_dluv": r.get(CHANGE),
                                           "mean_dluv": r["mean_dluv"], "floor_dluv": r.get("floor_dluv"),
                                           "reference_noise_dluv": r.get("reference_noise_dluv"),
                                           "meets": meets(r, c["limits"])} for r in field]}
            if best["technique"] != "lod":
                point = {"size_px": None, **{k: best.get(k) for k in MEASURED}, "per_pixel": best.get("per_pixel")}
                ch["sweep_entries"] = ch["entries"]
                ch["entries"] = [{"variant": best["label"], "technique": best["technique"], "value": best["value"],
                                  "max_px": ch["above_px"], "min_px": 0, "meets": bool(ok), "measured": [point],
                                  "screen_coverage": [round(ch["above_px"] / lod["resolution"][1], 6), 0.0]}]
