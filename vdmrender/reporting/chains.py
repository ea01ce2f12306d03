"""An object's LOD chains written for people: lod.json as vdmrender.deciding.lod decided them, lod.md (the floor
and every chain's bands as tables) and lod.png (each chain through its variants' change against screen size)."""
from __future__ import annotations

import json
from pathlib import Path

from vdmbake.scene import LIMIT_ON

from ..common import markdown
from ..common.markdown import cell, number
from ..common.plots import ERROR_LABEL
from ..deciding.baseline import POINT
from ..deciding.lod import CHANGE


def table(lod: dict) -> str:
    """lod.md: per object the floor (what no variant changes: the full asset's error against the reference and the
    reference's noise, per size); every chain as bands of screen sizes, its variant, its change against the full
    asset and its error against the reference at the band's top, the pop where it takes over and the hysteresis of
    the switch; for a field of copies, how the chain was priced there."""
    seen = lod.get("error") or POINT
    lines = [f"LOD chains on {cell(lod['device'])}, frame {lod['resolution'][0]}x{lod['resolution'][1]}, sizes measured "
             f"{', '.join(map(str, lod['sizes_px']))} px; frames anti-aliased {seen['antialias']}, the reference at "
             f"{seen['reference_spp']} samples per pixel. {lod['rule']}", ""]
    for obj, rows in lod.get("floors", {}).items():
        lines += [f"## The floor of {obj}: its full asset against the reference", "",
                  "The full asset's own error against the reference, drawn the same way as every variant, is what "
                  "the pipeline costs (a shading sample per pixel, the anti-aliasing), not the representation; no "
                  "difference below the reference's noise can be told from noise. Where the full asset's IoU falls "
                  "(ray-cast quadrics miss atoms smaller than a pixel), what the chains decide on is drawn wrong too.", "",
                  markdown.table(["size [px]", "full asset", "mean ΔLuv", "p95 ΔLuv", "IoU", "reference noise ΔLuv",
                         "variant pairs within noise"], "rlrrrrr",
                        [[str(f["size_px"]), cell(f["full_asset"]), number(f["floor_dluv"], 3),
                          number(f["floor_p95_dluv"], 2), number(f.get("floor_iou"), 4),
                          number(f["reference_noise_dluv"], 3), f"{f['ties']} of {f['pairs']}"] for f in rows]), ""]
    for c in lod["chains"]:
        limits = ", ".join(f"{k} {'>=' if k.endswith('iou') else '<='} {v:g}" for k, v in c["limits"].items())
        limits += f", pop <= {c['pop_dluv']:g}" if c.get("pop_dluv") is not None else ""
        for obj, ch in c["objects"].items():
            rows = []
            for e in ch["entries"]:
                top, switch = e["measured"][0], e.get("switch_px")
                rows.append([f"({e['min_px']}, {e['max_px']}]", cell(e["variant"]), "yes" if e["meets"] else "**no**",
                             number(top.get(CHANGE), 3), number(top.get("change_p95_dluv"), 2),
                             number(top.get("change_iou"), 4), number(top["mean_dluv"], 3),
                             number(top.get("floor_dluv"), 3), number(top["median_ms"], 3),
                             number(top.get("pop_dluv"), 2), f"{switch[0]:g}, {switch[1]:g}" if switch else "-"])
            lines += [f"## {c['name']} ({limits}): {obj}", "",
                      markdown.table(["band [px]: over, up to", "variant", "within limits", "change ΔLuv", "change p95",
                             "IoU with the full asset", "ΔLuv against the reference", "floor ΔLuv", "median GPU ms",
                             "pop ΔLuv taking over", "switch down, up [px]"], "lllrrrrrrrl", rows), ""]
            if ch["unmet_px"]:
                lines += [f"**No variant is within the limits at {', '.join(map(str, ch['unmet_px']))} px**: the chain "
                          "takes the variant of least mean change against the full asset there.", ""]
            if ch.get("pops_meet") is False:
                lines += [f"A switch pops more than {c['pop_dluv']:g} ΔLuv where no variant within the limits pops "
                          "less.", ""]
            if "field" in ch:
                f = ch["field"]
                lines += [f"Priced on the field of copies: {f['how']}", "",
                          markdown.table(["on the field", "median GPU ms", "spread ms", "change ΔLuv",
                                 "ΔLuv against the reference", "floor ΔLuv", "within limits"], "lrrrrrl",
                                [[f"**{cell(r['variant'])}**" if r["variant"] == f["chosen"] else cell(r["variant"]),
                                  number(r["median_ms"], 2), number(r["spread_ms"], 2),
                                  number(r.get("change_dluv"), 3), number(r["mean_dluv"], 3),
                                  number(r.get("floor_dluv"), 3), "yes" if r["meets"] else "no"]
                                 for r in f["candidates"]]), ""]
            lines += [f"Above {ch['above_px']} px nothing was measured.", ""]
    return "\n".join(lines)


def write(folder: Path, lod: dict, sweep_rows: list[dict]) -> None:
    (folder / "lod.json").write_text(json.dumps(lod, indent=1, allow_nan=False) + "\n")
    (folder / "lod.md").write_text(table(lod))
    plot(folder / "lod.png", lod, sweep_rows)


def plot(path: Path, lod: dict, sweep_rows: list[dict]) -> None:
    import matplotlib.pyplot as plt

    fig = figure(lod, sweep_rows)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure(lod: dict, sweep_rows: list[dict]):
    """lod.png, one panel per chain and object: every variant's mean change (or error, as the chain's limit_on)
    against screen size (thin), the chain's bands shaded and named (hatched: over the limits), its value through
    them (thick), the limit (dashed), the floor (the full asset against the reference, dotted) and the pop at each
    switch (a red bar as tall as the pop, at the switch size)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    panels = [(c, obj, ch) for c in lod["chains"] for obj, ch in c["objects"].items()]
    fig, axes = plt.subplots(len(panels), 1, figsize=(10, 3.6 * len(panels)), squeeze=False)
    shades = plt.get_cmap("tab10")
    for ax, (c, obj, ch) in zip(axes[:, 0], panels):
        error = LIMIT_ON[c.get("limit_on", "reference")]["mean_dluv"]
        mine = [r for r in sweep_rows if r["object"] == obj and r.get(error) is not None]
        labels = list(dict.fromkeys(r["label"] for r in mine))
        for label in labels:
            pts = sorted((r["size_px"], r[error]) for r in mine if r["label"] == label)
            ax.plot(*zip(*pts), "-", color=shades(labels.index(label) % 10), linewidth=0.8, alpha=0.6, label=label)
        path_pts = []
        for e in ch["entries"]:
            colour = shades(labels.index(e["variant"]) % 10) if e["variant"] in labels else "grey"
            lo = max(e["min_px"], min(lod["sizes_px"]) / 2)
            ax.axvspan(lo, e["max_px"], color=colour, alpha=0.12, hatch=None if e["meets"] else "//")
            ax.text((lo * e["max_px"]) ** 0.5, 0.97, e["variant"] + ("" if e["meets"] else " (over)"),
                    transform=ax.get_xaxis_transform(), ha="center",
                    va="top", fontsize=7, rotation=90 if len(ch["entries"]) > 2 else 0)
            path_pts += [(m["size_px"], m.get(error)) for m in e["measured"]
                         if m["size_px"] is not None and m.get(error) is not None]
            top = e["measured"][0]
            if top.get("pop_dluv") is not None:
                ax.bar(top["size_px"], top["pop_dluv"], width=0.08 * top["size_px"], color="red", alpha=0.8,
                       label="pop at the switch" if e is ch["entries"][1] else None)
        if path_pts:
            ax.plot(*zip(*sorted(path_pts)), "o-", color="black", linewidth=2, markersize=4, label="the chain")
        if error in c["limits"]:
            ax.axhline(c["limits"][error], color="black", linestyle="--", linewidth=0.8, label="limit")
        base = [(f["size_px"], f["floor_dluv"]) for f in lod.get("floors", {}).get(obj, []) if f["floor_dluv"] is not None]
        if base:
            ax.plot(*zip(*sorted(base)), ":", color="grey", linewidth=1.5,
                    label="floor: full asset against the reference")
        ax.set_xscale("log", base=2)
        ax.set_xticks(lod["sizes_px"], [str(s) for s in lod["sizes_px"]])
        ax.minorticks_off()
        ax.set_xlim(min(lod["sizes_px"]) / 2, max(lod["sizes_px"]) * 1.3)
        ax.set_xlabel("bounding sphere on screen [px] (log)")
        ax.set_ylabel(ERROR_LABEL if error != CHANGE else "mean colour difference per pixel\nagainst the full asset "
                      "(CIE ΔE*uv)")
        priced = f", priced on the field: {ch['field']['chosen']}" if "field" in ch else ""
        ax.set_title(f"{obj}: chain {c['name']}{priced}", fontsize=9)
        ax.grid(True, alpha=0.3)
        handles, _ = ax.get_legend_handles_labels()
        handles.append(Patch(facecolor="grey", alpha=0.25, label="shaded: a band of the chain,\nnamed at its top"))
        if not all(e["meets"] for e in ch["entries"]):
            handles.append(Patch(facecolor="none", edgecolor="grey", hatch="//",
                                 label="hatched: over the limits\n(the least change taken)"))
        ax.legend(handles=handles, fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    seen = lod.get("error") or POINT
    fig.suptitle(f"LOD chains on {lod['device']}\nreference {seen['reference_spp']} spp, frames AA {seen['antialias']}",
                 fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.4 / fig.get_figheight()))   # room for the two-line title above
    return fig
