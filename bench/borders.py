"""Open boundaries (issue 10; VDM sec. 5): a plane with a real elevation model as its mesostructure,
seen at 35 and 3 degrees above it and 35 degrees below, every mesostructure technique against the
displaced reference. Written to JSON and markdown, never asserted.

The elevation model is matplotlib's sample `jacksboro_fault_dem.npz` (344 x 403 int16 metres), written
as a 16-bit PNG of its metres and as a float EXR: one normalisation rule makes them the same surface.
Each row carries the surface score (border and inside pixels apart, vdmrender.tracing.borders) and the score
over every pixel (mean_dluv_all, iou_all: what the report counted before).

    python -m bench.borders -o out/bench-borders [--height png|exr|exr-flipped] [--res 256]

(`exr-flipped` writes the picture upside down: what code that does not flip picture rows needs to
see the same surface, for before / after comparisons.)
"""
from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from bench.quadrics import measure_scene

VIEWS = [("above35", 35), ("above3", 3), ("below35", -35)]

SCENE = """
[render]
resolution = [{res}, {res}]
repeats = 3
warmup = 1
shadow_map = 1024
[camera]
orbit = {{ count = 1, elevation_deg = {elev}, azimuth_deg = 30, distance = 2.4, fov_deg = 40 }}
[light]
direction = [0.45, -0.55, 0.7]
[[objects]]
name = "dem"
primitive = "plane"
expect_empty = {expect_empty}
params = {{ size = 2.0, segments = 8 }}
techniques = {{ mesh = {{}}, bump = {{}}, pom = {{ steps = [16, 32] }}, vdm = {{ k = [8] }}, displaced = {{ levels = [4] }} }}
[objects.mesostructure]
height = "{height}"
size = 128
depth = 0.05
tiling = [1, 1]
phi = 32
theta = 8
curvatures = 16
"""


def write_dem(folder: Path) -> dict:
    """The DEM as dem.png (16-bit, metres), dem.exr (float metres) and dem-flipped.exr (rows reversed)."""
    from matplotlib import cbook
    from PIL import Image

    from vdmbake.formats import exr

    z = np.asarray(cbook.get_sample_data("jacksboro_fault_dem.npz")["elevation"])
    folder.mkdir(parents=True, exist_ok=True)
    im = Image.new("I;16", z.shape[::-1])
    im.frombytes(z.astype("<u2").tobytes())
    im.save(folder / "dem.png")
    exr.write(folder / "dem.exr", {"dem": {"Y": z.astype(np.float32)}})
    exr.write(folder / "dem-flipped.exr", {"dem": {"Y": z[::-1].astype(np.float32).copy()}})
    return {"png": "dem.png", "exr": "dem.exr", "exr-flipped": "dem-flipped.exr"}


def _markdown(rows: list[dict], device: str, res: int) -> str:
    lines = [f"# Plane with a real elevation model, open borders ({device}, {res}x{res})", "",
             "| view | variant | median ms | surface px | border px | inside px | mean ΔLuv surface | IoU surface "
             "| mean ΔLuv apart | mean ΔLuv all | IoU all |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        g = lambda k, f: format(r[k], f) if r.get(k) is not None else "-"  # noqa: E731
        lines.append(f"| {r['view']} | {r['label']} | {r['median_ms']:.1f} | {g('surface_px', 'd')} | {g('border_px', 'd')} | "
                     f"{g('inside_px', 'd')} | {g('mean_dluv', '.3f')} | {g('iou', '.4f')} | {g('mean_dluv_apart', '.3f')} | "
                     f"{g('mean_dluv_all', '.3f')} | {g('iou_all', '.4f')} |")
    return "\n".join(lines) + "\n"


@click.command()
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench-borders"), show_default=True)
@click.option("--height", type=click.Choice(["png", "exr", "exr-flipped"]), default="png", show_default=True)
@click.option("--res", type=int, default=256, show_default=True)
def main(out: Path, height: str, res: int):
    """Run the open-border benchmark and write OUT/borders.json and OUT/borders.md."""
    files = write_dem(out / "scenes")
    rows = []
    for view, elev in VIEWS:
        for r in measure_scene(out, f"dem-{view}", SCENE.format(res=res, elev=elev, height=files[height],
                                                                expect_empty="true" if elev < 0 else "false")):
            rows.append({**r, "view": view, "elevation_deg": elev})
            click.echo(f"{view:8} {r['label']:12} {r['median_ms']:8.1f} ms  dLuv {r['mean_dluv']:.3f} IoU {r['iou']:.4f}"
                       f"  all: {r.get('mean_dluv_all', r['mean_dluv']):.3f} / {r.get('iou_all', r['iou']):.4f}"
                       f"  border {r.get('border_px', '-')} inside {r.get('inside_px', '-')}", err=True)
    device = rows[0]["device"]
    (out / "borders.json").write_text(json.dumps({"device": device, "resolution": [res, res], "height": height,
                                                  "rows": rows}, indent=1) + "\n")
    (out / "borders.md").write_text(_markdown(rows, device, res))
    click.echo(f"wrote {out / 'borders.json'}, {out / 'borders.md'}")


if __name__ == "__main__":
    main()
