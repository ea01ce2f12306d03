"""make bench-mipmaps: what the scene's render.mipmaps gains (issue 30), per variant and screen size, written
to JSON and markdown, never asserted.

Two scenes cut down from the configs: the textured bunny of configs/lod-bunny.toml (an albedo map: mesh and
coarse meshes read it; billboards and octahedral impostors, whose colour maps are not mip-mapped, are the
control) and the brick torus of configs/vdm-torus-bricks.toml (VDM's weights, the normal map and the colour
tile; the paper's sampling). Each is baked once; a second bundle beside it differs only in its scene's
render.mipmaps (the parts are the same files, hard-linked: mipmaps is read by the renderer alone). Both are
rendered by vdmrender at the screen sizes SIZES with the reference averaged over --spp samples per pixel
(render.reference_spp); sweep.csv gives each variant's mean ΔLuv against that filtered reference (mean_dluv)
and against the pixel centres' (aliased_mean_dluv), and its GPU time.

    python -m bench.mipmaps -o out/bench [--spp 16]
"""
from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import click

SIZES = "512,128,32,16"
SCENES = {
    "bunny": """
[render]
resolution = [512, 512]
repeats = 1
warmup = 0
shadow_map = 1024
[camera]
up = [0, 0, 1]
orbit = { count = 2, elevation_deg = 20, azimuth_deg = 30, distance = 2.6, fov_deg = 40 }
[[objects]]
name = "bunny"
mesh = "pkg:pymeshlab/tests/sample_meshes/bunny10k_textured.obj"
transform = { rotate_deg = [90, 0, 0] }
[objects.techniques]
mesh = {}
coarse = { ratios = [0.1, 0.01] }
billboards = { variants = ["greedy-hier+coarse"], resolution = 256, coarse_ratio = 0.1 }
octahedral = { variants = ["full-9x128-march"] }
""",
    "torus": """
[render]
resolution = [512, 512]
repeats = 1
warmup = 0
[camera]
orbit = { count = 2, elevation_deg = 30, azimuth_deg = 30, distance = 2.4, fov_deg = 40 }
[[objects]]
name = "torus"
primitive = "torus"
params = { major = 1.0, minor = 0.35, segments = 256, rings = 64 }
[objects.mesostructure]
height = "bricks"
albedo = "bricks"
size = 128
depth = 0.06
tiling = [16, 4]
phi = 32
theta = 8
curvatures = 16
[objects.techniques]
vdm = { k = [8], refine = [0, 4] }
pom = { steps = [16] }
bump = {}
mesh = {}
""",
}


def tool(name: str, *args) -> None:
    subprocess.run([str(Path(sys.executable).parent / name), *map(str, args)], check=True)


def with_mipmaps(bundle: Path, out: Path) -> None:
    """A copy of `bundle` whose scene has render.mipmaps = true, its parts hard-linked."""
    if out.exists():
        shutil.rmtree(out)
    shutil.copytree(bundle, out, copy_function=os.link)
    manifest = out / "manifest.json"
    m = json.loads(manifest.read_text())
    m["scene"]["render"]["mipmaps"] = True
    manifest.unlink()                       # a link: the original's manifest stays as it is
    manifest.write_text(json.dumps(m, indent=1))


def rows(sweep_csv: Path) -> list[dict]:
    with open(sweep_csv, newline="") as f:
        return list(csv.DictReader(f))


def table(results: dict, spp: int) -> str:
    lines = ["# Mipmaps on and off (render.mipmaps), mean ΔLuv per variant and screen size\n",
             f"Filtered: against the reference averaged over {spp} samples per pixel (box); point: against the pixel "
             "centres' (1 sample). GPU ms: median per frame. Two cameras per size.\n"]
    for scene, by in results.items():
        lines += [f"\n## {scene}\n", "| variant | px | filtered off | filtered on | gain | point off | point on | ms off | ms on |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for (label, size), r in sorted(by.items(), key=lambda kv: (kv[0][0], -int(kv[0][1]))):
            off, on = r["off"], r["on"]
            f = lambda row, k: float(row[k]) if row.get(k) not in (None, "") else float("nan")
            lines.append(f"| {label} | {size} | {f(off, 'mean_dluv'):.3f} | {f(on, 'mean_dluv'):.3f} | "
                         f"{f(off, 'mean_dluv') - f(on, 'mean_dluv'):+.3f} | {f(off, 'aliased_mean_dluv'):.3f} | "
                         f"{f(on, 'aliased_mean_dluv'):.3f} | {f(off, 'median_ms'):.2f} | {f(on, 'median_ms'):.2f} |")
    return "\n".join(lines) + "\n"


@click.command()
@click.option("-o", "--out", "out", type=click.Path(path_type=Path), default=Path("out/bench"))
@click.option("--spp", type=int, default=16, help="the reference's samples per pixel (N x N)")
@click.option("--scene", "only", multiple=True, type=click.Choice(list(SCENES)), help="only these scenes")
def main(out: Path, spp: int, only) -> None:
    work = out / "mipmaps"
    work.mkdir(parents=True, exist_ok=True)
    results = {}
    for name, text in SCENES.items():
        if only and name not in only:
            continue
        (work / f"{name}.toml").write_text(text)
        plain, mipped = work / f"{name}.bundle", work / f"{name}-mipmaps.bundle"
        tool("vdmbake", work / f"{name}.toml", "-o", plain)
        with_mipmaps(plain, mipped)
        by = {}
        for key, bundle in (("off", plain), ("on", mipped)):
            run = work / f"{name}-{key}"
            tool("vdmrender", bundle, "-o", run, "--sizes", SIZES, "--reference-spp", spp)
            for r in rows(run / "sweep.csv"):
                by.setdefault((r["label"], r["size_px"]), {})[key] = r
        results[name] = {k: v for k, v in by.items() if len(v) == 2}
    (out / "mipmaps.json").write_text(json.dumps(
        {"spp": spp, "sizes": SIZES, "scenes": {s: [{"label": k[0], "size_px": int(k[1]), **v} for k, v in by.items()]
                                               for s, by in results.items()}}, indent=1))
    (out / "mipmaps.md").write_text(table(results, spp))
    print(table(results, spp))


if __name__ == "__main__":
    main()
