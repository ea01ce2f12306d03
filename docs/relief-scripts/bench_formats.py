"""Texture layouts for the tracer on llvmpipe: interleaved timing of a 512^2 pass of relief-like rays
(bricks 128, 4 x 4 tiles on a plane seen at 45 and 70 degrees), view ray + shadow ray per pixel."""
import sys, time, statistics
import numpy as np, moderngl
from vdmbake.common import pyramid as P
from vdmbake.assets import heightfields
from vdmrender.gpu import gl
from vdmrender.passes import hftrace

FS = """#version 430
{defines}
{fetch}
#include "heightfield_trace.glsl"
uniform float u_theta;
out vec4 frag;
void main() {{
    vec2 q = gl_FragCoord.xy / 512.0;
    vec3 V = normalize(vec3(sin(u_theta) * (q.x - 0.3), sin(u_theta), cos(u_theta)));
    float N = 128.0, depth = 0.06;
    vec2 T = q * 4.0;
    vec3 o = vec3(T * N - 0.5, 0.0), d = vec3(-V.xy * N, V.z);
    float t = hf_trace(o, d, 0.0, depth / V.z);
    if (t < 0.0) t = hf_t_reached;
    vec3 L = normalize(vec3(0.5, 0.3, 0.8));
    vec3 h = o + d * t;
    float s = hf_trace_reentry(h, vec3(L.xy * N, -L.z), 0.0, h.z / L.z);
    frag = vec4(t, s, {count}, 1.0);
}}
"""
FETCH = {
 "A_rgba_corners": "",
 "B_rg_minmax+gather": """uniform sampler2D u_mm; uniform sampler2D u_s;
#define HF_FETCH(cell, level) hf_fetch_b(cell, level)
vec4 hf_fetch_b(ivec2 cell, int level) {
    vec2 m = texelFetch(u_mm, cell, level).xy;
    vec4 g = textureGather(u_s, (vec2(cell) + 1.0) / vec2(textureSize(u_s, 0))).wzxy;
    return level == 0 ? g : vec4(m, m);
}""",
 "C_rg_minmax+4fetch": """uniform sampler2D u_mm; uniform sampler2D u_s;
#define HF_FETCH(cell, level) hf_fetch_c(cell, level)
vec4 hf_fetch_c(ivec2 cell, int level) {
    vec2 m = texelFetch(u_mm, cell, level).xy;
    ivec2 n = textureSize(u_s, 0);
    ivec2 c1 = (cell + 1) % n;
    vec4 g = vec4(texelFetch(u_s, cell, 0).r, texelFetch(u_s, ivec2(c1.x, cell.y), 0).r,
                  texelFetch(u_s, ivec2(cell.x, c1.y), 0).r, texelFetch(u_s, c1, 0).r);
    return level == 0 ? g : vec4(m, m);
}""",
}

def main():
    ctx = gl.create_context()
    print(gl.renderer_name(ctx))
    N = 128
    s = (0.06 * (1 - heightfields.pattern(sys.argv[1] if len(sys.argv) > 1 else "bricks", N))).astype(np.float32)
    p = P.build(s, P.WRAP)
    A = hftrace.pyramid_texture(ctx, p)
    mm = ctx.texture((N, N), 2, np.ascontiguousarray(p.levels[0]).tobytes(), dtype="f4")
    mm.build_mipmaps(0, p.top)
    for L in range(1, p.top + 1):
        mm.write(np.ascontiguousarray(p.levels[L]).tobytes(), level=L)
    mm.filter = (moderngl.NEAREST_MIPMAP_NEAREST, moderngl.NEAREST)
    st = ctx.texture((N, N), 1, s.tobytes(), dtype="f4")
    st.filter = (moderngl.NEAREST, moderngl.NEAREST)
    st.repeat_x = st.repeat_y = True
    target = gl.Target(ctx, 512, 512)
    progs = {}
    for k, f in FETCH.items():
        for count in (False, True):
            src = FS.format(defines="#define HF_START_LEVEL 0\n" + ("#define COUNT" if count else ""), fetch=f,
                            count="float(hf_visits)" if count else "0.0")
            src = src.replace('#include "heightfield_trace.glsl"', (gl.SHADERS / "include" / "heightfield_trace.glsl").read_text())
            progs[k, count] = ctx.program(vertex_shader=gl.source("fullscreen.vert"), fragment_shader=src)
    vao = {k: ctx.vertex_array(pr, []) for k, pr in progs.items()}
    def run(key, theta):
        pr = progs[key]
        A.use(1); mm.use(2); st.use(3)
        gl.set_uniforms(pr, u_hf=1, u_mm=2, u_s=3, u_theta=theta, **hftrace.uniforms(p))
        target.begin()
        vao[key].render(mode=moderngl.TRIANGLES, vertices=3)
        ctx.finish()
    for theta in (np.radians(45), np.radians(70)):
        ref = None
        for k in FETCH:
            run((k, True), theta)
            a = target.read()
            print(f"theta {np.degrees(theta):.0f} {k}: visits/pixel (view+shadow) mean {a[...,2].mean():.2f}")
            ref = a if ref is None else ref
            assert np.allclose(a[..., :2], ref[..., :2]), k
        times = {k: [] for k in FETCH}
        for rep in range(7):
            for k in FETCH:
                t0 = time.perf_counter(); run((k, False), theta); times[k].append((time.perf_counter() - t0) * 1e3)
        base = statistics.median(times["A_rgba_corners"])
        for k, v in times.items():
            print(f"theta {np.degrees(theta):.0f} {k:22s} median {statistics.median(v):7.2f} ms  ratio {statistics.median(v)/base:.3f}")

main()
