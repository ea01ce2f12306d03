"""Evaluate a GLSL snippet per element of arrays on the GL device: the test harness that compares the shader
includes (shaders/include/) with their numpy twins (tests/test_twins.py), usable for any probe.

`evaluate` draws one fullscreen pass into RGBA32F targets, one fragment per element: the fragment reads
its element's inputs (vec4 texels of RGBA32F textures, fetched without filtering), runs `body`, and writes
out0, out1, ... (vec4 each), read back as float32. Only the public helpers of vdmrender.gpu.gl are used
(expand, source, set_uniforms, release), and the program is strict as every other one (a uniform given
that the program does not have is an error, vdmrender.gpu.gl.strict).
"""
from __future__ import annotations

import math

import numpy as np

from vdmrender.gpu import gl

MAX_WIDTH = 1024    # elements per row of the targets


def _as_vec4(a: np.ndarray, n: int | None) -> np.ndarray:
    a = np.asarray(a, np.float64)
    a = a.reshape(len(a), -1) if a.ndim != 1 else a[:, None]
    if a.shape[1] > 4:
        raise ValueError(f"glsl_eval: an input has {a.shape[1]} components per element; at most 4 (a vec4)")
    if n is not None and len(a) != n:
        raise ValueError(f"glsl_eval: inputs of {len(a)} and {n} elements")
    return np.concatenate([a, np.zeros((len(a), 4 - a.shape[1]))], 1)


def evaluate(ctx, includes: list[str], body: str, inputs: np.ndarray | dict[str, np.ndarray], outputs: int,
             uniforms: dict = {}, textures: dict = {}, defines: tuple[str, ...] = (),
             declarations: str = "") -> list[np.ndarray]:
    """Run `body` once per element of `inputs` on the GL device; returns `outputs` float32 arrays (N, 4).

    includes: files of shaders/include/ (e.g. ["frame.glsl"]), included in this order after `defines`
        (each "NAME" or "NAME VALUE", written as #define lines first) and before `declarations` (global
        GLSL text: the uniforms or helper functions a body needs).
    body: GLSL statements in main() that read the element's inputs and write vec4 out0 .. out{outputs-1}
        (initialised to zero). An array `inputs` (N,) or (N, k <= 4) is read as vec4 `inp`; a dict
        {name: (N,) or (N, k <= 4)} as one vec4 per name. Missing components are 0. `idx` is the
        element's index (int). Values reach the shader as float32: round a twin's inputs the same way.
    uniforms: set by vdmrender.gpu.gl.set_uniforms (a 4x4 array is a matrix given row-major).
    textures: {sampler uniform: a moderngl texture (bound as it is, owned by the caller) or an array
        (H, W, C <= 4) uploaded as a float32 texture with nearest filtering and released here}.
    """
    named = dict(inputs) if isinstance(inputs, dict) else {"inp": inputs}
    n = None
    packed = {}
    for name, a in named.items():
        packed[name] = _as_vec4(a, n)
        n = len(packed[name])
    if not n:
        raise ValueError("glsl_eval: no elements to evaluate")
    w = min(n, MAX_WIDTH)
    h = math.ceil(n / w)
    header = "".join(f"#define {d}\n" for d in defines) + "".join(f'#include "{f}"\n' for f in includes)
    samplers = "".join(f"uniform sampler2D u_eval_{name};\n" for name in packed)
    outs = "".join(f"layout(location = {i}) out vec4 out{i};\n" for i in range(outputs))
    reads = "".join(f"    vec4 {name} = texelFetch(u_eval_{name}, px, 0);\n" for name in packed)
    zero = "".join(f"    out{i} = vec4(0.0);\n" for i in range(outputs))
    frag = gl.expand(f"""#version 430
{header}
{declarations}
{samplers}uniform int u_eval_width;
{outs}
void main() {{
    ivec2 px = ivec2(gl_FragCoord.xy);
    int idx = px.y * u_eval_width + px.x;
{reads}{zero}    {{
{body}
    }}
}}
""")
    prog = ctx.program(vertex_shader=gl.source("fullscreen.vert"), fragment_shader=frag)
    # the body need not read every input (nor the index)
    prog.extra = {"name": "glsl_eval", "may_lack": frozenset({"u_eval_width", *(f"u_eval_{k}" for k in packed)})}
    made, targets, fbo, vao = [], [], None, None
    try:
        units = {}
        for name, a in packed.items():
            grid = np.zeros((h * w, 4), np.float32)
            grid[:n] = a
            tex = ctx.texture((w, h), 4, grid.tobytes(), dtype="f4")
            made.append(tex)
            units[f"u_eval_{name}"] = tex
        for name, t in textures.items():
            if isinstance(t, np.ndarray):
                a = np.ascontiguousarray(t if t.ndim == 3 else t[..., None], np.float32)
                if a.shape[2] > 4:
                    raise ValueError(f"glsl_eval: texture {name} has {a.shape[2]} channels; at most 4")
                t = ctx.texture((a.shape[1], a.shape[0]), a.shape[2], a.tobytes(), dtype="f4")
                t.filter = (ctx.NEAREST, ctx.NEAREST)
                made.append(t)
            units[name] = t
        targets = [ctx.texture((w, h), 4, dtype="f4") for _ in range(outputs)]
        fbo = ctx.framebuffer(targets)
        vao = ctx.vertex_array(prog, [])
        fbo.use()
        ctx.viewport = (0, 0, w, h)
        gl.bind_textures(prog, **units)
        gl.set_uniforms(prog, u_eval_width=w, **uniforms)
        vao.render(vertices=3)
        return [np.frombuffer(t.read(), np.float32).reshape(h * w, 4)[:n].copy() for t in targets]
    finally:
        gl.release(vao, fbo, *targets, *made, prog)
