"""docs/results/demo.json from a `make demo` run's own output (`python tools/demo_results.py out/default`): every
variant's row at the orbit views and every LOD chain's bands, as report.json and lod.json give them, with the device
and the date. `make docs` renders its tables (tools/make_docs.py, view `demo`) in README.md and docs/results.md.

A run of configs/composite.toml (`python tools/demo_results.py out/composite`, a report with composite sets) gives
docs/results/composite.json the same way: each set's row and each object's own rows (view `composite`)."""
from __future__ import annotations

import datetime
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DRAWS = {"billboards": "coarse", "vdm": "base", "pom": "base", "relief": "base", "bump": "base"}   # what `faces` counts


def extract(out: Path) -> dict:
    report = json.loads((out / "report.json").read_text())
    lod = json.loads((out / "lod.json").read_text())
    rows = [{"object": r["object"], "variant": r["label"], "faces": r.get("faces"), "faces_of": DRAWS.get(r["technique"]),
             "median_ms": r["median_ms"], "ratio": r["ratio_to_baseline"],
             "fetches_px": r["per_pixel"]["fetches"], "steps_px": r["per_pixel"]["steps"],
             "mean_dluv": r["mean_dluv"], "p95_dluv": r["p95_dluv"], "iou": r["iou"], "flip": r["flip_mean"]}
            for r in report["rows"]]
    chains = []
    for chain in lod["chains"]:
        for obj, c in chain["objects"].items():
            for e in c["entries"]:
                m = e["measured"][0]   # the band's largest size, where it is judged
                chains.append({"chain": chain["name"], "limits": chain["limits"], "object": obj, "min_px": e["min_px"],
                               "max_px": e["max_px"], "variant": e["variant"], "meets": e["meets"],
                               "change_dluv": m["change_dluv"], "mean_dluv": m["mean_dluv"], "floor_dluv": m["floor_dluv"],
                               "median_ms": m["median_ms"]})
    return {"about": "the default scene (make demo): every variant at the orbit views, and the LOD chains from its sweep",
            "measured_by": f"make demo, then python tools/demo_results.py {out}",
            "when": datetime.date.today().isoformat(), "device": report["device"],
            "resolution": report["resolution"], "sizes_px": lod["sizes_px"], "rows": rows, "chains": chains}


def _row(r: dict, **more) -> dict:
    return {**more, "median_ms": r["median_ms"], "mean_dluv": r["mean_dluv"], "p95_dluv": r["p95_dluv"], "iou": r["iou"]}


def extract_composite(out: Path) -> dict:
    report = json.loads((out / "report.json").read_text())
    t = report["budget"]
    return {"about": "configs/composite.toml: each composite set, and each object's own rows of the same run",
            "measured_by": f"vdmbake configs/composite.toml -o {out}.bundle, vdmrender {out}.bundle -o {out}, then "
                           f"python tools/demo_results.py {out}",
            "when": datetime.date.today().isoformat(), "device": report["device"],
            "resolution": report["resolution"], "repeats": t["repeats"], "warmup": t["warmup"],
            "sets": [_row(c, set=c["set"], variants=c["variants"]) for c in report["composite"]],
            "rows": [_row(r, object=r["object"], variant=r["label"]) for r in report["rows"]]}


def main(argv: list[str]) -> int:
    out = Path(argv[0]) if len(argv) == 1 else None
    if out is None or not (out / "report.json").is_file():
        print("usage: python tools/demo_results.py OUT (a vdmrender output folder: make demo's, with lod.json, or "
              "configs/composite.toml's)", file=sys.stderr)
        return 2
    composite = bool(json.loads((out / "report.json").read_text()).get("composite"))
    if not composite and not (out / "lod.json").is_file():
        print(f"{out}: neither make demo's output (no lod.json) nor a composite run's", file=sys.stderr)
        return 2
    path = ROOT / "docs" / "results" / ("composite.json" if composite else "demo.json")
    doc = extract_composite(out) if composite else extract(out)
    path.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")
    print(f"wrote {path.relative_to(ROOT)}; run make docs to render its tables")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
