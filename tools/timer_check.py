"""An independent check of vdmrender's reported GPU times: for each row of a report, the same variant
timed another way, and the two compared per camera.

vdmrender times every pass of every frame in its own GL_TIME_ELAPSED query after its warm-up rule
(vdmrender.measuring.timing). Here, after a fixed sustained warm-up (default 2 s of continuous rendering), one
query spans N whole frames (the target's clear, then renderer.render through the kept view) and a second
one N clears alone; a frame's time is their difference over N. Nothing of vdmrender.measuring.timing is used.

    python tools/timer_check.py BUNDLE REPORT.json -o check.json [--frames 200] [--warmup-s 2]
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import click

from vdmbake.bundle.directory import Bundle
from vdmrender.gpu import gl
from vdmrender.common.camera import cameras_for
from vdmrender.techniques import variants


def frames_ms(ctx, target, renderer, cam, n: int) -> float:
    view, q_all, q_clear = target.kept(), ctx.query(time=True), ctx.query(time=True)
    ctx.finish()
    with q_all:
        for _ in range(n):
            target.clear()
            renderer.render(cam, view)
    ctx.finish()
    with q_clear:
        for _ in range(n):
            target.clear()
    return (q_all.elapsed - q_clear.elapsed) * 1e-6 / n


@click.command()
@click.argument("bundle", type=click.Path(exists=True, path_type=Path))
@click.argument("report", type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", "out", required=True, type=click.Path(path_type=Path))
@click.option("--frames", default=200, show_default=True, help="Frames per query.")
@click.option("--warmup-s", default=2.0, show_default=True, help="Sustained rendering before timing.")
@click.option("--device", default=None)
def main(bundle, report, out, frames, warmup_s, device):
    rep = json.loads(report.read_text())
    b = Bundle(bundle)
    scene = b.scene
    w, h = rep["resolution"]
    ctx = gl.create_context(device)
    target = gl.Target(ctx, w, h)
    rows = []
    for row in rep["rows"]:
        obj = next(o for o in scene.objects if o.name == row["object"])
        entry = b.manifest["objects"][obj.name]
        cams = cameras_for(scene.camera, entry["centre"], entry["radius"], w, h)
        v = next(v for v in variants(obj, entry, b, scene) if v.label == row["label"])
        r = v.build(ctx)
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < warmup_s:
            for cam in cams:
                target.clear()
                r.render(cam, target.kept())
            ctx.finish()
        mine = [frames_ms(ctx, target, r, cam, frames) for cam in cams]
        r.release()
        ratios = [round(a / b_, 4) for a, b_ in zip(row["camera_ms"], mine)]
        rows.append({"object": row["object"], "label": row["label"], "reported_ms": row["camera_ms"],
                     "check_ms": [round(x, 4) for x in mine], "ratio": ratios,
                     "within_5pct": all(abs(x - 1) <= 0.05 for x in ratios)})
        click.echo(f"{row['object']}: {row['label']:36} reported {row['camera_ms']} check "
                   f"{[round(x, 3) for x in mine]} ratio {ratios}")
    out.write_text(json.dumps({"device": gl.renderer_name(ctx), "frames_per_query": frames, "warmup_s": warmup_s,
                               "rows": rows}, indent=1) + "\n")
    target.release()
    ctx.release()


if __name__ == "__main__":
    main()
