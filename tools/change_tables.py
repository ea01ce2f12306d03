"""docs/results/change.json from render folders (issue 39): what each variant changes against its full asset and its
error against the reference per size, the chains before and after, the forest's field and the reference's noise.

    python tools/change_tables.py --after lod-bunny=DIR lod-villin=DIR forest=DIR --before lod-bunny=DIR ... \
        --noise16 DIR --noise64 DIR --device "..." --measured-by "..." -o docs/results/change.json

Every cell is formatted here once from the folders' report.json and lod.json, so the published strings are the runs'
own; `make docs` renders them (tools/make_docs.py)."""
from __future__ import annotations

import argparse
import json
from datetime import date
from pathlib import Path

SIZES = (512, 128, 32, 16)


def num(x, digits=2) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def load(folder: Path) -> tuple[dict, dict | None]:
    report = json.loads((folder / "report.json").read_text())
    lod = folder / "lod.json"
    return report, json.loads(lod.read_text()) if lod.is_file() else None


def variants(runs: dict[str, Path]) -> dict:
    """Per object and variant, at each size: change against the full asset / error against the reference; and the
    floor (the full asset's error) with the reference's noise."""
    rows = []
    for config in ("lod-bunny", "lod-villin"):
        report, _ = load(runs[config])
        sweep = report["sweep"]["rows"]
        for obj in dict.fromkeys(r["object"] for r in sweep):
            mine = {(r["label"], r["size_px"]): r for r in sweep if r["object"] == obj}
            labels = list(dict.fromkeys(label for label, _ in mine))
            first = mine[labels[0], SIZES[0]]
            rows.append([obj, f"floor: {first['change_against']} / noise",
                         *(f"{num(mine[labels[0], s]['floor_dluv'])} / {num(mine[labels[0], s]['reference_noise_dluv'])}"
                           for s in SIZES)])
            rows += [["", label, *(f"{num(mine[label, s]['change_dluv'])} / {num(mine[label, s]['mean_dluv'])}"
                                   for s in SIZES)] for label in labels]
    return {"header": ["object", "variant", *(f"{s} px" for s in SIZES)], "align": ["---", "---", *["---:"] * 4],
            "rows": rows}


def bands(entries: list[dict]) -> str:
    return ", ".join(f"{e['variant']} ({e['min_px']}, {e['max_px']}]{'' if e['meets'] else chr(92) + '*'}"
                     + (f" pop {e['measured'][0]['pop_dluv']:.2f}" if e["measured"][0].get("pop_dluv") is not None else "")
                     for e in entries)


def chains(before: dict[str, Path], after: dict[str, Path]) -> dict:
    rows = []
    for config in ("lod-bunny", "lod-villin", "forest"):
        if config not in after:
            continue
        _, old = load(before[config])
        _, new = load(after[config])
        for c_new in new["chains"]:
            c_old = next(c for c in old["chains"] if c["name"] == c_new["name"])
            for obj, ch in c_new["objects"].items():
                was = c_old["objects"][obj]
                rows.append([config, c_new["name"], obj, bands(was.get("sweep_entries", was["entries"])),
                             bands(ch.get("sweep_entries", ch["entries"])),
                             bands(ch["entries"]) if "field" in ch else "-"])
    return {"header": ["scene", "chain", "object", "before (error against the reference)",
                       "after (change against the full asset)", "shipped on the field"],
            "align": ["---"] * 6, "rows": rows}


def field(folder: Path) -> dict:
    _, lod = load(folder)
    rows = []
    for c in lod["chains"]:
        for obj, ch in c["objects"].items():
            f = ch["field"]
            rows += [[c["name"], f"**{k['variant']}**" if k["variant"] == f["chosen"] else k["variant"],
                      num(k["median_ms"], 1), num(k["change_dluv"]), num(k["mean_dluv"]), num(k["floor_dluv"]),
                      "yes" if k["meets"] else "no"] for k in f["candidates"]]
    return {"header": ["chain", "on the field", "median GPU ms", "change ΔLuv", "ΔLuv against the reference",
                       "floor ΔLuv", "within the limit"], "align": ["---", "---", "---:", "---:", "---:", "---:", "---"],
            "rows": rows}


def noise(by_spp: dict[int, Path]) -> dict:
    rows = []
    floors = {spp: load(folder)[1]["floors"] for spp, folder in by_spp.items()}
    first = next(iter(floors.values()))
    for obj in first:
        for s in SIZES:
            cells = []
            for spp in by_spp:
                f = next((f for f in floors[spp][obj] if f["size_px"] == s), None)
                cells += ["-", "-"] if f is None else [num(f["reference_noise_dluv"], 3), f"{f['ties']} of {f['pairs']}"]
            rows.append([obj, str(s), *cells])
    header = ["object", "size [px]"]
    for spp in by_spp:
        header += [f"noise ΔLuv, {spp} spp", f"variant pairs within it, {spp} spp"]
    return {"header": header, "align": ["---", "---:", *["---:"] * (2 * len(by_spp))], "rows": rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    pairs = lambda xs: {k: Path(v) for k, v in (x.split("=", 1) for x in xs)}  # noqa: E731
    ap.add_argument("--after", nargs="+", required=True)
    ap.add_argument("--before", nargs="+", required=True)
    ap.add_argument("--noise16", type=Path, required=True)
    ap.add_argument("--noise64", type=Path, required=True)
    ap.add_argument("--device", required=True)
    ap.add_argument("--measured-by", required=True)
    ap.add_argument("-o", type=Path, required=True)
    a = ap.parse_args()
    after, before = pairs(a.after), pairs(a.before)
    doc = {"about": "issue 39: decisions on the change against the full asset (tools/change_tables.py)",
           "measured_by": a.measured_by, "device": a.device, "when": date.today().isoformat(),
           "tables": {"variants": variants(after), "chains": chains(before, after), "field": field(after["forest"]),
                      "noise": noise({16: a.noise16, 64: a.noise64})}}
    a.o.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")


if __name__ == "__main__":
    main()
