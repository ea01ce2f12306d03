"""Interleaved timing of a scene's variants (and relief stage variants) on llvmpipe: every round renders
each variant once per camera (shadow map included, ctx.finish() inside the timed region), in turn, so the
load of the shared machine hits all alike; medians over rounds and ratios to a baseline variant."""
import time, statistics, json, argparse
from vdmbake.bundle import Bundle
from vdmbake.scene import parse_scene_dict
from vdmrender import gl
from vdmrender.camera import cameras_for
from vdmrender.techniques import variants
from vdmrender.techniques.mesostructure import ReliefPass

ap = argparse.ArgumentParser()
ap.add_argument("bundle"); ap.add_argument("--rounds", type=int, default=7); ap.add_argument("--res", type=int, default=512)
ap.add_argument("--base", default="displaced@2"); ap.add_argument("--extra", nargs="*", default=[],
                help="relief stage variants ITER:FRAG:DEF+DEF (FRAG: another stage file in shaders/, or empty), "
                     "e.g. 32::FLAT; or pomcull:STEPS (pom with relief's back-face culling)")
ap.add_argument("--only", nargs="*", default=None)
a = ap.parse_args()
b = Bundle(a.bundle)
scene = parse_scene_dict(b.manifest["scene"], "m")
obj = scene.objects[0]; entry = b.manifest["objects"][obj.name]
cams = cameras_for(scene.camera, entry["centre"], entry["radius"], a.res, a.res)
ctx = gl.create_context()
target = gl.Target(ctx, a.res, a.res)
rs = {v.label: v.build(ctx) for v in variants(obj, entry, b, scene) if a.only is None or v.label in a.only}
for e in a.extra:
    if e.startswith("pomcull:"):          # pom with relief's back-face culling, for a fair comparison
        from vdmrender.techniques.mesostructure import MesostructurePass, back_faces
        steps = int(e.split(":")[1])
        r = MesostructurePass(ctx, obj, entry, b, scene, "pom.frag", u_steps=steps)
        r.cull_face = back_faces(b.mesh(entry["mesh"]))
        rs[f"pom@{steps}+cull"] = r
        continue
    it, frag, defs = (e.split(":") + ["", ""])[:3]
    r = ReliefPass.__new__(ReliefPass)
    import vdmrender.techniques.mesostructure as M
    if frag:
        orig = M.MesostructurePass.__init__
        def init(self, ctx, obj, entry, bundle, scene, _frag, defines=(), **u):
            orig(self, ctx, obj, entry, bundle, scene, frag, defines, **u)
        M.MesostructurePass.__init__ = init
        r = ReliefPass(ctx, obj, entry, b, scene, int(it), defines=tuple(x for x in defs.split("+") if x))
        M.MesostructurePass.__init__ = orig
    else:
        r = ReliefPass(ctx, obj, entry, b, scene, int(it), defines=tuple(x for x in defs.split("+") if x))
    rs[f"relief@{it}:{frag}:{defs}"] = r
times = {k: [] for k in rs}
cpu = {k: [] for k in rs}
for k, r in rs.items():      # warm-up (compiles)
    for c in cams:
        r.render(c, target); ctx.finish()
for rnd in range(a.rounds):
    for k, r in rs.items():
        for c in cams:
            t0 = time.perf_counter(); c0 = time.process_time()
            r.render(c, target); ctx.finish()
            times[k].append((time.perf_counter() - t0) * 1e3); cpu[k].append((time.process_time() - c0) * 1e3)
base = statistics.median(times[a.base]) if a.base in times else None
res = {}
for k, v in times.items():
    m = statistics.median(v)
    res[k] = {"median_ms": round(m, 2), "ratio": round(m / base, 3) if base else None}
    mn = min(v); bmin = min(times[a.base]) if a.base in times else None
    cm = statistics.median(cpu[k]); cb = statistics.median(cpu[a.base]) if a.base in cpu else None
    res[k]["cpu_ms"] = round(cm, 2); res[k]["cpu_ratio"] = round(cm / cb, 3) if cb else None
    print(f"{k:36s} wall median {m:8.2f} ms ratio {m / base if base else float('nan'):.3f} | min ratio {mn / bmin if bmin else float('nan'):.3f} | cpu median {cm:8.2f} ms ratio {cm / cb if cb else float('nan'):.3f}")
print(json.dumps(res))
