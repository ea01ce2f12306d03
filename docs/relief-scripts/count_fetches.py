"""Instrumented fetch counts per covered pixel at 512^2 on a bundle's cameras: relief (relief.frag with COUNT:
cell visits of the view and shadow rays, one pyramid texelFetch each, plus one normal-map fetch) and pom (an
instrumented copy of pom.frag counting its depth_at lookups, each a trilinear R32F fetch, plus one normal-map
fetch). Also the mean over covered 4x4 pixel blocks of the block's max (what a SIMD pixel group pays)."""
import re, sys, numpy as np
from vdmbake.bundle import Bundle
from vdmbake.scene import parse_scene_dict
from vdmrender import gl
from vdmrender.camera import cameras_for
from vdmrender.techniques.mesostructure import MesostructurePass, ReliefPass

SH = gl.SHADERS

def pom_copy():
    """pom.frag with every depth_at lookup counted; the colour output holds the view and shadow counts."""
    s = (SH / "pom.frag").read_text()
    head, sep, body = s.partition('#include "mesostructure.glsl"')
    body = re.sub(r"(?<![A-Za-z_])depth_at\(", "counted(", body)
    body = body.replace("    // Self-shadow:", "    int n_view = n_fetch;\n    // Self-shadow:")
    body = body.replace("    frag = vec4(shade(u_albedo, n, Vw, lit), 1.0);",
                        "    frag = vec4(float(n_view), float(n_fetch - n_view), 0.0, 1.0);")
    return (head + sep + "\nint n_fetch = 0;\n"
            "float counted(vec2 T, vec2 dx, vec2 dy) { n_fetch++; return depth_at(T, dx, dy); }" + body)


def stats(frames, block=4):
    pix = np.concatenate([a[a[..., 3] > 0] for a in frames])
    bm = []
    for a in frames:
        res = a.shape[0]
        blk = a.reshape(res // block, block, res // block, block, 4)
        cov = blk[..., 3].max(axis=(1, 3)) > 0
        bm.append(np.stack([blk[..., 0].max(axis=(1, 3))[cov], blk[..., 1].max(axis=(1, 3))[cov]], -1))
    bm = np.concatenate(bm)
    return {"view_mean": pix[:, 0].mean(), "shadow_mean": pix[:, 1].mean(), "view_p95": np.percentile(pix[:, 0], 95),
            "view_max": pix[:, 0].max(), "shadow_max": pix[:, 1].max(),
            "view_block_max": bm[:, 0].mean(), "shadow_block_max": bm[:, 1].mean()}

def main(path, res=512):
    b = Bundle(path); scene = parse_scene_dict(b.manifest["scene"], "m")
    obj = scene.objects[0]; entry = b.manifest["objects"][obj.name]
    cams = cameras_for(scene.camera, entry["centre"], entry["radius"], res, res)
    ctx = gl.create_context(); t = gl.Target(ctx, res, res)
    out = {}
    copy = SH / "pom_count.frag"
    copy.write_text(pom_copy())
    try:
        rs = {f"relief@{it}": ReliefPass(ctx, obj, entry, b, scene, it, defines=("COUNT",)) for it in (8, 16, 32, 4096)}
        rs.update({f"pom@{s}": MesostructurePass(ctx, obj, entry, b, scene, "pom_count.frag", u_steps=s) for s in (16, 32)})
        for k, r in rs.items():
            frames = []
            for c in cams:
                r.render(c, t); frames.append(t.read())
            out[k] = stats(frames)
            r.release()
    finally:
        copy.unlink()
    for k, s in out.items():
        print(f"{path} {k:12s} " + "  ".join(f"{a} {v:.2f}" for a, v in s.items()))
    return out

if __name__ == "__main__":
    for p in sys.argv[1:]:
        main(p)
