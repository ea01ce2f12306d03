"""make bench-filtered: what a viewer sees (issue 30). For configs/lod-bunny.toml and configs/lod-villin.toml, every
variant at 512, 128, 32 and 16 px across, rendered under each anti-aliasing mode (none, msaa4, ssaa2, ssaa4) and
scored against the box-filtered reference (REFERENCE_SPP stratified samples per pixel) and, beside it, point-sampled
(aliased_*: no AA against the pixel centres); with each mode's GPU time and fragments per covered pixel. The
reference is traced once per config (the later runs find it in the output folder's cache). Then the reference's
own cost against its samples per pixel (trace seconds and rays, the scanned bunny at 256x256, two views).

    python -m bench.filtered -o out/bench [--quick]
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import click

from vdmbake.bundle.directory import Bundle

CONFIGS = ("lod-bunny", "lod-villin")
MODES = ("none", "msaa4", "ssaa2", "ssaa4")
SIZES = (512, 128, 32, 16)
REFERENCE_SPP = 16
SPP_COST = (1, 4, 16, 64)


def _run(cmd: list[str]) -> None:
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stderr[-4000:]}")


def render_modes(name: str, root: Path, modes, sizes, resolution: str | None) -> dict:
    """One bake, then one vdmrender run per mode into the same folder (the reference cached after the first):
    {mode: report.json}. A mode whose NAME-MODE.json is there from an earlier run is read, not run again (delete
    it to measure again)."""
    bundle = root / f"{name}.bundle"
    _run([sys.executable, "-m", "vdmbake.cli", f"configs/{name}.toml", "-o", str(bundle)])
    out, reports = root / name, {}
    for mode in modes:
        if (root / f"{name}-{mode}.json").is_file():
            reports[mode] = json.loads((root / f"{name}-{mode}.json").read_text())
            continue
        t0 = time.perf_counter()
        _run([sys.executable, "-m", "vdmrender.cli", str(bundle), "-o", str(out), "--no-flip",
              "--sizes", ",".join(map(str, sizes)), "--reference-spp", str(REFERENCE_SPP), "--antialias", mode]
             + (["--resolution", resolution] if resolution else []))
        reports[mode] = json.loads((out / "report.json").read_text())
        shutil.copy(out / "report.json", root / f"{name}-{mode}.json")
        click.echo(f"{name} {mode}: {time.perf_counter() - t0:.0f} s", err=True)
    return reports


def reference_cost(root: Path, spps, size: int) -> list[dict]:
    """Trace seconds and rays of the scanned bunny's reference at each samples-per-pixel count."""
    from vdmrender.tracing import reference
    from vdmrender.common.camera import cameras_for

    bundle = Bundle(root / "lod-bunny.bundle")
    scene, entry = bundle.scene, bundle.manifest["objects"]["scan"]
    obj = next(o for o in scene.objects if o.name == "scan")
    ref = reference.MeshReference(bundle.surface(entry), scene.light, obj.material)
    cams = cameras_for(scene.camera, entry["centre"], entry["radius"], size, size)
    out = []
    for spp in spps:
        rays0, t0 = ref.scene.rays_cast, time.perf_counter()
        for c in cams:
            reference.filtered(ref.render, c, spp)
        out.append({"spp": spp, "trace_s": round(time.perf_counter() - t0, 3), "rays": ref.scene.rays_cast - rays0,
                    "frames": len(cams), "size": [size, size]})
    return out


def table(results: dict, spp_cost: list[dict], device: str) -> str:
    modes = list(next(iter(results.values())))
    lines = ["# What a viewer sees: filtered error against point-sampled, per anti-aliasing mode", "",
             f"Device: {device}. Reference: {REFERENCE_SPP} samples per pixel (stratified, box filter). `aliased`: "
             "no AA against the pixel-centre reference; the other columns: the frames under each AA mode against "
             "the filtered reference. Error: mean ΔL\\*u\\*v\\*; cost: median GPU ms per frame and fragments shaded "
             "per covered pixel (the resolve included).", ""]
    for name, reports in results.items():
        rows = {mode: {(r["object"], r["label"], r["size_px"]): r for r in rep["sweep"]["rows"]}
                for mode, rep in reports.items()}
        keys = list(rows[modes[0]])
        lines += [f"## {name}", "", "| object | variant | px | aliased | " + " | ".join(f"{m}" for m in modes)
                  + " | " + " | ".join(f"{m} ms" for m in modes) + " | " + " | ".join(f"{m} frag/px" for m in modes)
                  + " |", "|---|---|---:|---:|" + "---:|" * (3 * len(modes))]
        for key in keys:
            rs = [rows[m].get(key) for m in modes]
            num = lambda x, d: "-" if x is None else f"{x:.{d}f}"   # noqa: E731
            lines.append(f"| {key[0]} | {key[1]} | {key[2]} | {num(rs[0]['aliased_mean_dluv'], 2)} | "
                         + " | ".join(num(r and r["mean_dluv"], 2) for r in rs) + " | "
                         + " | ".join(num(r and r["median_ms"], 2) for r in rs) + " | "
                         + " | ".join(num(r and (r.get("per_pixel") or {}).get("fragments"), 2) for r in rs) + " |")
        lines.append("")
    lines += ["## The reference's cost against samples per pixel", "",
              "| spp | trace s | rays | s per spp |", "|---:|---:|---:|---:|"]
    lines += [f"| {c['spp']} | {c['trace_s']:.2f} | {c['rays']} | {c['trace_s'] / c['spp']:.3f} |" for c in spp_cost]
    return "\n".join(lines) + "\n"


@click.command()
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"))
@click.option("--quick", is_flag=True, help="128x128 frames, sizes 128 and 16, modes none and ssaa2 (a smoke run).")
@click.option("--modes", default=",".join(MODES), show_default=True, help="The anti-aliasing modes to run.")
def main(out: Path, quick: bool, modes: str):
    root = out / "filtered"
    root.mkdir(parents=True, exist_ok=True)
    modes, sizes = (("none", "ssaa2"), (128, 16)) if quick else (tuple(modes.split(",")), SIZES)
    results = {name: render_modes(name, root, modes, sizes, "128x128" if quick else None) for name in CONFIGS}
    spp_cost = reference_cost(root, SPP_COST[:3] if quick else SPP_COST, 128 if quick else 256)
    device = next(iter(next(iter(results.values())).values()))["device"]
    doc = {"device": device, "reference_spp": REFERENCE_SPP, "modes": list(modes), "sizes_px": list(sizes),
           "rows": {name: {mode: rep["sweep"]["rows"] for mode, rep in reports.items()}
                    for name, reports in results.items()},
           "reference_cost": spp_cost}
    (out / "filtered.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "filtered.md").write_text(table(results, spp_cost, device))
    click.echo(f"{out / 'filtered.md'}  {out / 'filtered.json'}", err=True)


if __name__ == "__main__":
    main()
