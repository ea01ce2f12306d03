"""Error-driven LOD chains (issue 22): from a screen-size sweep (vdmrender.sweep), per object and per set of
limits (scene.Thresholds), the cheapest variant within the limits at each measured size, merged into bands of
screen sizes; written as lod.json and lod.md.

A variant measured at size s is chosen for the band of sizes from s down to the next smaller measured size
(exclusive): the band is judged at its largest size, where a fixed-resolution impostor's error is largest and a
mesh's cost is about the same, so the choice is conservative within its band. Cheapest is the smallest median
GPU time; variants whose medians differ by less than their interquartile spreads together, or by less than
NOISE of the cheaper, cost the same within the noise, and of those the one with the smaller mean ΔLuv is taken,
so that two runs pick the same chain."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from vdmbake.common import instances

from .composite import Composite

NOISE = 0.1   # a difference in median GPU time below this share is not taken as one in cost (two runs of
              # configs/lod-bunny.toml on the shared 2-core llvmpipe machine moved by 14% in the median, 42% at p90:
              # there, bands below 32 px can flip between runs; README, "What to ship at each screen size")
TRIANGLE_MESHES = ("mesh", "coarse")   # the variants a glTF can carry as they are (vdmbake.export)
MEASURED = ("mean_dluv", "p95_dluv", "flip_mean", "iou", "aliased_mean_dluv", "median_ms", "spread_ms", "empty_frames")


def meets(row: dict, limits: dict) -> bool:
    """Every limit holds (IoU at least its limit, the errors at most theirs); a value that was not measured
    (every frame empty) holds none."""
    return all(row.get(k) is not None and (row[k] >= v if k == "iou" else row[k] <= v) for k, v in limits.items())


def cheapest(rows: list[dict]) -> dict:
    """The cheapest row, ties within the noise broken by the smaller error, then by label."""
    best = min(rows, key=lambda r: r["median_ms"])
    tied = [r for r in rows if r["median_ms"] - best["median_ms"]
            <= max((r["spread_ms"] or 0) + (best["spread_ms"] or 0), NOISE * best["median_ms"])]
    return min(tied, key=lambda r: (r["mean_dluv"] if r["mean_dluv"] is not None else float("inf"), r["label"]))


def chain(rows: list[dict], limits: dict, height: int) -> dict:
    """One object's chain: entries from the largest screen size down, each {variant, band, measured}."""
    sizes = sorted({r["size_px"] for r in rows}, reverse=True)
    picks = []
    for s in sizes:
        here = [r for r in rows if r["size_px"] == s]
        ok = [r for r in here if meets(r, limits)]
        pick = cheapest(ok) if ok else min(here, key=lambda r: (r["mean_dluv"] is None, r["mean_dluv"] or 0, r["label"]))
        picks.append((s, pick, bool(ok)))
    entries = []
    for i, (s, r, ok) in enumerate(picks):
        low = sizes[i + 1] if i + 1 < len(sizes) else 0
        point = {"size_px": s, **{k: r.get(k) for k in MEASURED}, "per_pixel": r.get("per_pixel")}
        if entries and entries[-1]["variant"] == r["label"] and entries[-1]["meets"] == ok:
            entries[-1]["min_px"] = low
            entries[-1]["measured"].append(point)
        else:
            entries.append({"variant": r["label"], "technique": r["technique"], "value": r["value"],
                            "max_px": s, "min_px": low, "meets": ok, "measured": [point]})
    for e in entries:   # MSFT_screencoverage's unit: the share of the frame's height (vdmbake.export)
        e["screen_coverage"] = [round(e["max_px"] / height, 6), round(e["min_px"] / height, 6)]
    return {"entries": entries, "unmet_px": [s for s, _, ok in picks if not ok],
            "above_px": sizes[0]}


def _object_chains(rows: list[dict], limits: dict, height: int) -> dict:
    """The chain over every variant, and where the object has triangle-mesh variants, the chain over those
    alone (`meshes_only`: what a glTF with MSFT_lod carries)."""
    meshes = [r for r in rows if r["technique"] in TRIANGLE_MESHES]
    return {**chain(rows, limits, height), **({"meshes_only": chain(meshes, limits, height)} if meshes else {})}


def chains(sweep_rows: list[dict], lod_sets, device: str, resolution, filtering: dict | None = None) -> dict:
    """lod.json's content: per set of limits, per object, its chain; `filtering`: what the errors judged are
    against (report.json's: the reference's samples per pixel, the frames' anti-aliasing)."""
    objects = list(dict.fromkeys(r["object"] for r in sweep_rows))
    filtering = filtering or {"reference_spp": 1, "antialias": "none"}
    return {"device": device, "resolution": list(resolution), "sizes_px": sorted({r["size_px"] for r in sweep_rows},
                                                                                  reverse=True),
            "error": {"reference_spp": filtering["reference_spp"], "antialias": filtering["antialias"]},
            "band": "an entry is chosen where the object's bounding sphere spans more than min_px and at most "
                    "max_px pixels on screen; screen_coverage: the same as shares of the frame's height",
            "rule": __doc__.split("\n\n", 1)[1].replace("\n", " "),
            "chains": [{"name": t.name, "limits": t.limits(),
                        "objects": {o: _object_chains([r for r in sweep_rows if r["object"] == o], t.limits(),
                                                      resolution[1]) for o in objects}}
                       for t in lod_sets]}


def table(lod: dict) -> str:
    """lod.md: every chain as bands of screen sizes, its variant and what it measured at the band's top."""
    def num(x, digits):
        return "-" if x is None else f"{x:.{digits}f}"

    seen = lod.get("error") or {"reference_spp": 1, "antialias": "none"}
    lines = [f"LOD chains on {lod['device']}, frame {lod['resolution'][0]}x{lod['resolution'][1]}, sizes measured "
             f"{', '.join(map(str, lod['sizes_px']))} px; errors against the reference at {seen['reference_spp']} "
             f"samples per pixel, frames anti-aliased {seen['antialias']}. {lod['rule']}", ""]
    for c in lod["chains"]:
        limits = ", ".join(f"{k} {'>=' if k == 'iou' else '<='} {v:g}" for k, v in c["limits"].items())
        for obj, ch in c["objects"].items():
            lines += [f"## {c['name']} ({limits}): {obj}", "",
                      "| band [px]: over, up to | variant | within limits | mean ΔLuv | p95 ΔLuv | FLIP | IoU | median GPU ms |",
                      "|---|---|---|---:|---:|---:|---:|---:|"]
            for e in ch["entries"]:
                top = e["measured"][0]
                lines.append(f"| ({e['min_px']}, {e['max_px']}] | {e['variant']} | {'yes' if e['meets'] else '**no**'} | "
                             f"{num(top['mean_dluv'], 3)} | {num(top['p95_dluv'], 2)} | {num(top['flip_mean'], 4)} | "
                             f"{num(top['iou'], 4)} | {num(top['median_ms'], 3)} |")
            lines.append("")
            if ch["unmet_px"]:
                lines += [f"No variant is within the limits at {', '.join(map(str, ch['unmet_px']))} px: the chain "
                          "uses the variant of least mean ΔLuv there.", ""]
            lines += [f"Above {ch['above_px']} px nothing was measured.", ""]
    return "\n".join(lines)


def write(folder: Path, lod: dict) -> None:
    (folder / "lod.json").write_text(json.dumps(lod, indent=1, allow_nan=False) + "\n")
    (folder / "lod.md").write_text(table(lod))


def screen_px(camera, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Each sphere's silhouette diameter in pixels as vdmrender.sweep measures it (seen at the image centre: what
    an engine's screen-size test computes), infinite for a sphere around the eye."""
    f = 0.5 * camera.height / math.tan(math.radians(camera.fov_deg) / 2)
    d2 = ((centres - camera.eye) ** 2).sum(1)
    gap = d2 - radii ** 2
    with np.errstate(divide="ignore"):
        return np.where(gap > 0, 2 * f * radii / np.sqrt(np.maximum(gap, 1e-300)), np.inf)


def pick(entries: list[dict], sizes: np.ndarray) -> np.ndarray:
    """Each size's entry index: the band (min_px, max_px] it falls in; above the chain's top, its finest entry."""
    lows = np.array([e["min_px"] for e in entries], float)   # decreasing
    return np.clip((sizes <= lows[:, None]).sum(0), 0, len(entries) - 1)


def chosen(entries: list[dict], camera, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Each copy's variant label under `camera`: the entry whose band its screen size falls in (pick)."""
    return np.array([e["variant"] for e in entries])[pick(entries, screen_px(camera, centres, radii))]


class LodMix(Composite):
    """Per-instance LOD, as an engine does it: per frame every copy of the object is drawn by the variant its
    screen size selects in the chain (`entries`, lod.json's), all in one frame with one depth buffer and one
    shadow map (vdmrender.composite.Composite: each copy casts what its variant casts). renderers: {variant label:
    renderer built with every copy, with `place`}; world: the copies' matrices; sphere: the object's bounding
    sphere (centre, radius); around: the sphere holding every copy."""

    def __init__(self, ctx, renderers: dict, entries: list[dict], world: np.ndarray, sphere, around, light,
                 shadow_size: int):
        super().__init__(ctx, renderers, *around, light, shadow_size)
        self.all, self.entries, self.world = dict(self.renderers), entries, world
        self.centres, self.radii = instances.spheres(world, *sphere)

    def passes(self, camera, target) -> list:
        labels = chosen(self.entries, camera, self.centres, self.radii)
        self.renderers = {}
        for label, r in self.all.items():   # a variant may hold several bands: all its copies at once
            mine = self.world[labels == label]
            if len(mine):
                r.place(mine)
                self.renderers[label] = r
        return super().passes(camera, target)

    def release(self) -> None:
        self.renderers = self.all
        super().release()
