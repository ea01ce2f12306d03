"""Frame time and error of the mesostructure techniques with and without the tile albedo, interleaved in one
process (docs/mesostructure.md, the colour tile section). Modes per variant: `plain` (the entry without mesostructure_albedo: the
material's u_albedo, as before), `srgb8` (the tile as gl.albedo_texture uploads it, GL_SRGB8), `f16` (the same
tile decoded on the CPU and uploaded as linear RGBA16F: a measurement of llvmpipe's sRGB decode, not in the
product). Per round (the order reversed every other round) every (variant, mode) renders every camera once untimed, once timed (process CPU time and
wall time, ctx.finish() inside); medians over rounds and cameras, ratios the medians of each
render's ratio to the same variant's plain render of the same round and camera. Error: mean dLuv against the reference frames
a vdmrender run of the same bundle cached (reference/OBJECT/NNN.exr).
    python albedo_time.py BUNDLE RENDER_OUT ROUNDS [LABEL ...]"""
import statistics
import sys
import time
from pathlib import Path

import moderngl
import numpy as np

from vdmbake.formats import exr
from vdmbake.bundle import parts
from vdmbake.bundle.directory import Bundle
from vdmbake.common.colour import srgb8_to_linear
from vdmrender.gpu import gl
from vdmrender.common import images
from vdmrender.comparing import metrics
from vdmrender.common.camera import cameras_for
from vdmrender.techniques import variants


def f16_texture(ctx, tile):
    h, w = tile.shape[:2]
    data = np.dstack([srgb8_to_linear(tile), np.ones((h, w))]).astype("f2")
    tex = ctx.texture((w, h), 4, data.tobytes(), dtype="f2")
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = True
    return tex


bundle_path, out, rounds = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
labels = sys.argv[4:] or ["vdm@8", "vdm@8r4", "pom@16", "relief@32"]
bundle = Bundle(bundle_path)
scn = bundle.scene
obj = scn.objects[0]
entry = bundle.manifest["objects"][obj.name]
tile = bundle.read(entry["mesostructure_albedo"], parts.ALBEDO_MAP)
w, h = scn.render.resolution
cams = cameras_for(scn.camera, entry["centre"], entry["radius"], w, h)
refs = []
for k in range(len(cams)):
    p = exr.read(out / f"reference/{obj.name}/{k:03d}.exr")["reference"]
    refs.append(images.encode(np.stack([p[c] for c in "RGBA"], -1), scn.render.background))
ctx = gl.create_context()
target = gl.Target(ctx, w, h)
plain = {k: v for k, v in entry.items() if k != "mesostructure_albedo"}
renderers = {}
for mode, e in (("plain", plain), ("srgb8", entry), ("f16", entry)):
    for v in variants(obj, e, bundle, scn):
        if v.label in labels:
            r = v.build(ctx)
            if mode == "f16":
                r.textures["u_albedo_map"].release()
                r.textures["u_albedo_map"] = f16_texture(ctx, tile)
            renderers[(v.label, mode)] = r
cpu = {k: [] for k in renderers}
wall = {k: [] for k in renderers}
err = {}
for rnd in range(rounds):
    order = list(renderers.items())
    for key, r in (order if rnd % 2 == 0 else order[::-1]):     # alternate the order: no position favoured
        for k, cam in enumerate(cams):
            r.render(cam, target)
            ctx.finish()
            c0, t0 = time.process_time(), time.perf_counter()
            r.render(cam, target)
            ctx.finish()
            cpu[key].append((time.process_time() - c0) * 1e3)
            wall[key].append((time.perf_counter() - t0) * 1e3)
            if rnd == 0:
                err.setdefault(key, []).append(metrics.compare(images.encode(target.read(), scn.render.background),
                                                               refs[k])["mean"])
print(f"{'variant':>10} {'mode':>6} {'CPU ms':>8} {'x plain':>8} {'wall ms':>8} {'x plain':>8} {'mean dLuv':>9}")
for (label, mode) in renderers:
    ratio = lambda d: statistics.median([a / b for a, b in zip(d[(label, mode)], d[(label, "plain")])])  # noqa: E731
    print(f"{label:>10} {mode:>6} {statistics.median(cpu[(label, mode)]):8.1f} {ratio(cpu):8.3f} "
          f"{statistics.median(wall[(label, mode)]):8.1f} {ratio(wall):8.3f} {np.mean(err[(label, mode)]):9.3f}")
