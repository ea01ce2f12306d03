"""make bench, enhanced-billboards part: the thesis's appendix A comparison, written to JSON and
markdown, never asserted.

Models comparable to tables A-1/A-2 (sphere, torus, cone, cylinder) and a real scanned bunny, each
at 800x600, 400x300 and 200x150: the full mesh, the coarse mesh alone, the thesis's billboards
(100-step march, hit range 0.01 and 0.02) and the improved ones, each with and without the coarse
mesh, greedy projection; plus the axis projection's billboard count and storage for comparison.

    python -m vdmrender.bench_billboards -o out/bench [--quick]
"""
from __future__ import annotations

import itertools
import json
from pathlib import Path

import click

from . import progress
from .bench import measure_scene

MODELS = [("sphere", 'primitive = "sphere"'), ("torus", 'primitive = "torus"'), ("cone", 'primitive = "cone"'),
          ("cylinder", 'primitive = "cylinder"'), ("bunny", 'mesh = "pkg:pymeshfix/examples/StanfordBunny.ply"')]
RESOLUTIONS = [(800, 600), (400, 300), (200, 150)]
# Thesis appendix A-2 (hit range 0.01; with coarse mesh), for the models we have.
THESIS = {"sphere": (25.81, 6.56), "torus": (58.09, 51.80), "cone": (5.56, 3.33), "cylinder": (39.45, 31.85)}
VARIANTS = ["greedy-hit0.01", "greedy-hit0.02", "greedy-improved", "greedy-hit0.01+coarse",
            "greedy-hit0.02+coarse", "greedy-improved+coarse", "axis-improved+coarse"]

SCENE = """
[render]
resolution = [{w}, {h}]
repeats = 1
warmup = 1
shadow_map = {shadow_map}
[camera]
orbit = {{ count = 1, elevation_deg = 25, azimuth_deg = 30, distance = 2.6, fov_deg = 40 }}
[[objects]]
name = "{name}"
{source}
techniques = {{ mesh = {{}}, coarse = {{ ratios = [0.1] }}, billboards = {{ variants = {variants}, resolution = {res} }} }}
"""


def _markdown(rows: list[dict], bakes: dict, device: str) -> str:
    lines = [f"# Enhanced billboards benchmark ({device})", "",
             "| model | billboards greedy / axis | faces left out (greedy) | maps MB greedy / axis | bake s |",
             "|---|---:|---|---:|---:|"]
    for name, b in bakes.items():
        lines.append(f"| {name} | {b['greedy']} / {b['axis']} | {b['leftover']} | {b['greedy_mb']:.2f} / "
                     f"{b['axis_mb']:.2f} | {b['bake_s']:.1f} |")
    lines += ["", "| model | resolution | variant | median ms | mean ΔLuv | thesis (A-2) | p95 | IoU |",
              "|---|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        thesis = THESIS.get(r["object"])
        ref = ""
        if thesis and r["resolution"] == "800x600" and r["label"].endswith("hit0.01"):
            ref = f"{thesis[0]:.2f}"
        elif thesis and r["resolution"] == "800x600" and r["label"].endswith("hit0.01+coarse"):
            ref = f"{thesis[1]:.2f}"
        lines.append(f"| {r['object']} | {r['resolution']} | {r['label']} | {r['median_ms']:.1f} | "
                     f"{r['mean_dluv']:.3f} | {ref} | {r['p95_dluv']:.2f} | {r['iou']:.4f} |")
    return "\n".join(lines) + "\n"


@click.command()
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"), show_default=True)
@click.option("--quick", is_flag=True, help="Sphere only, 200x150, 64-texel maps (a smoke run).")
def main(out: Path, quick: bool):
    """Run the billboard benchmark and write OUT/billboards.json and OUT/billboards.md."""
    models = MODELS[:1] if quick else MODELS
    resolutions = RESOLUTIONS[-1:] if quick else RESOLUTIONS
    res, shadow_map = (64, 512) if quick else (512, 1024)
    rows, bakes = [], {}
    for (name, source), (w, h) in progress.bar(list(itertools.product(models, resolutions)), "bench-billboards",
                                               unit="scene"):
        tag = f"billboards-{name}-{w}x{h}"
        for r in measure_scene(out, tag, SCENE.format(w=w, h=h, name=name, source=source, res=res,
                                                      shadow_map=shadow_map, variants=json.dumps(VARIANTS))):
            rows.append({**r, "resolution": f"{w}x{h}"})
            click.echo(f"{name:8} {w}x{h} {r['label']:36} {r['median_ms']:9.1f} ms  dLuv {r['mean_dluv']:.3f}  "
                       f"IoU {r['iou']:.4f}", err=True)
        if name not in bakes:
            bundle = out / "bundles" / f"{tag}.bundle"
            m = json.loads((bundle / "manifest.json").read_text())
            bb = m["objects"][name]["techniques"]["billboards"]
            timing = json.loads((bundle / "timing.json").read_text())["steps_s"].get(name, {})
            bakes[name] = {"greedy": len(bb["greedy"]["faces"]), "axis": len(bb["axis"]["faces"]),
                           "leftover": bb["greedy"]["leftover"],
                           "greedy_mb": m["parts"][bb["greedy"]["maps"]]["bytes"] / 2**20,
                           "axis_mb": m["parts"][bb["axis"]["maps"]]["bytes"] / 2**20,
                           "bake_s": timing.get("billboards_greedy_s", 0.0)}
    out.mkdir(parents=True, exist_ok=True)
    device = rows[0]["device"]
    (out / "billboards.json").write_text(json.dumps({"device": device, "map_resolution": res, "shadow_map": shadow_map,
                                                     "bakes": bakes, "rows": rows}, indent=1) + "\n")
    (out / "billboards.md").write_text(_markdown(rows, bakes, device))
    click.echo(f"wrote {out / 'billboards.json'}, {out / 'billboards.md'}")


if __name__ == "__main__":
    main()
