"""Error ablations at 512^2 against each run folder's cached reference (instrumented copies of the stages,
written to shaders/ for the run and removed after): relief@32 as committed; FLAT (straight rays, pixel frame);
bent rays without turning the normal; mip-mapped normal lookups (textureGrad, as pom does); pom@16 as
committed and with relief's finest-level normal lookup."""
import sys, numpy as np
from vdmbake import exr
from vdmbake.bundle import Bundle
from vdmbake.scene import parse_scene_dict
from vdmrender import gl, images
from vdmrender.camera import cameras_for
from vdmrender.metrics import compare
from vdmrender.techniques.mesostructure import MesostructurePass, ReliefPass

SH = gl.SHADERS
relief = (SH / "relief.frag").read_text()
pom = (SH / "pom.frag").read_text()
copies = {
    "relief_noturn.frag": relief.replace("    nw = turned(nw, N, F, T1 - T);", "    // (no turn)"),
    "relief_mip.frag": relief.replace("textureLod(u_normals, T1, 0.0)", "textureGrad(u_normals, T1, dFdx(T), dFdy(T))"),
    "pom_lod0.frag": pom.replace("textureGrad(u_normals, T1, dx, dy)", "textureLod(u_normals, T1, 0.0)"),
}
for k, v in copies.items():
    assert v != {"relief_noturn.frag": relief, "relief_mip.frag": relief, "pom_lod0.frag": pom}[k], k

def run(path, folder):
    b = Bundle(path); scene = parse_scene_dict(b.manifest["scene"], "m")
    obj = scene.objects[0]; entry = b.manifest["objects"][obj.name]
    cams = cameras_for(scene.camera, entry["centre"], entry["radius"], 512, 512)
    bg = scene.render.background
    refs = [images.encode(np.stack([exr.read(f"{folder}/reference/{obj.name}/{k:03d}.exr")["reference"][c] for c in "RGBA"], -1), bg)
            for k in range(len(cams))]
    ctx = gl.create_context(); t = gl.Target(ctx, 512, 512)
    import vdmrender.techniques.mesostructure as M
    def relief_with(frag, defines=()):
        orig = M.MesostructurePass.__init__
        def init(self, ctx, obj, entry, bundle, scene, _frag, defines=(), **u):
            orig(self, ctx, obj, entry, bundle, scene, frag, defines, **u)
        M.MesostructurePass.__init__ = init
        try:
            return ReliefPass(ctx, obj, entry, b, scene, 32, defines=defines)
        finally:
            M.MesostructurePass.__init__ = orig
    rs = {"relief@32": ReliefPass(ctx, obj, entry, b, scene, 32),
          "relief@32 FLAT": ReliefPass(ctx, obj, entry, b, scene, 32, defines=("FLAT",)),
          "relief@32 bent, normal not turned": relief_with("relief_noturn.frag"),
          "relief@32 mip-mapped normals": relief_with("relief_mip.frag"),
          "pom@16": MesostructurePass(ctx, obj, entry, b, scene, "pom.frag", u_steps=16),
          "pom@16 finest-level normals": MesostructurePass(ctx, obj, entry, b, scene, "pom_lod0.frag", u_steps=16)}
    for k, r in rs.items():
        vals, ious = [], []
        for c, ref in zip(cams, refs):
            r.render(c, t); m = compare(images.encode(t.read(), bg), ref); vals.append(m["values"]); ious.append(m["iou"])
        print(f"{obj.name:13s} {k:36s} mean dLuv {np.concatenate(vals).mean():.3f}  IoU {np.mean(ious):.4f}")
        r.release()

for k, v in copies.items():
    (SH / k).write_text(v)
try:
    for s in sys.argv[1:]:
        run(f"out/m/{s}.bundle", f"out/m/r-{s}")
finally:
    for k in copies:
        (SH / k).unlink()
