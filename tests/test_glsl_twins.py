"""The GLSL ideas shared by several shaders (shaders/include/frame.glsl, camera.glsl) against their
numpy twins (vdmbake.common.geometry.onb, vdmrender.common.camera.pixel_ray and window_depth), evaluated per pixel
on the GL device (llvmpipe here): the two must agree to float32 precision."""
from __future__ import annotations

import numpy as np

from vdmbake.common.geometry import onb
from vdmrender.gpu import gl
from vdmrender.common.camera import Camera, pixel_ray, window_depth

VERTEX = gl.source("fullscreen.vert")
RNG = np.random.default_rng(7)


def run(ctx, body: str, inputs: np.ndarray, outputs: int, m=None) -> list[np.ndarray]:
    """Run `body` (GLSL reading `inp`, this pixel's input, and writing out0, out1, ...) once per pixel of
    a float target of the inputs' (H, W) size; row 0 at the bottom (GL's window order)."""
    h, w = inputs.shape[:2]
    outs = "".join(f"layout(location = {i}) out vec4 out{i};\n" for i in range(outputs))
    frag = gl.expand(f"""#version 430
#include "frame.glsl"
#include "camera.glsl"
uniform sampler2D u_in;
uniform mat4 u_m;
uniform vec2 u_viewport;
{outs}
void main() {{
    vec4 inp = texelFetch(u_in, ivec2(gl_FragCoord.xy), 0);
    {body}
}}
""")
    prog = ctx.program(vertex_shader=VERTEX, fragment_shader=frag)
    prog.extra = {"name": "twin harness", "may_lack": frozenset({"u_in", "u_m", "u_viewport"})}   # a body reads some
    tex = ctx.texture((w, h), 4, np.ascontiguousarray(inputs, "f4").tobytes(), dtype="f4")
    targets = [ctx.texture((w, h), 4, dtype="f4") for _ in range(outputs)]
    fbo = ctx.framebuffer(targets)
    vao = ctx.vertex_array(prog, [])
    fbo.use()
    ctx.viewport = (0, 0, w, h)
    gl.bind_textures(prog, u_in=tex)
    gl.set_uniforms(prog, u_viewport=(float(w), float(h)), u_m=m if m is not None else np.eye(4))
    vao.render(vertices=3)
    out = [np.frombuffer(t.read(), np.float32).reshape(h, w, 4).copy() for t in targets]
    gl.release(vao, fbo, *targets, tex, prog)
    return out


def directions() -> np.ndarray:
    """Unit vectors: random ones, the axes both ways, and the hard cases near w = (0, 0, -1)."""
    d = RNG.normal(size=(200, 3))
    special = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0],
               [1e-4, 0, -1], [0, 1e-4, -1], [1e-7, 1e-7, -1], [0.6, 0.8, 0], [1e-3, -1e-3, 1]]
    d = np.concatenate([d, special])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_frame_twins_agree(ctx):
    w = directions()
    inputs = np.zeros((1, len(w), 4), np.float32)
    inputs[0, :, :3] = w
    u_gl, v_gl = run(ctx, "vec3 u, v; onb(inp.xyz, u, v); out0 = vec4(u, 0.0); out1 = vec4(v, 0.0);", inputs, 2)
    u, v = onb(w.astype(np.float32).astype(np.float64))
    assert np.abs(u_gl[0, :, :3] - u).max() < 2e-5 and np.abs(v_gl[0, :, :3] - v).max() < 2e-5
    # and both are orthonormal, right-handed frames
    for a, b in ((u, v), (u_gl[0, :, :3].astype(np.float64), v_gl[0, :, :3].astype(np.float64))):
        assert np.abs(np.linalg.norm(a, axis=1) - 1).max() < 1e-5 and np.abs(np.einsum("ij,ij->i", a, b)).max() < 1e-5
        assert np.abs(np.cross(a, b) - w).max() < 1e-5


def test_pixel_ray_and_window_depth_twins_agree(ctx):
    cam = Camera(np.array([3.0, -2.0, 1.5]), np.zeros(3), np.array([0.0, 0.0, 1.0]), 60.0, 40, 30, 0.5, 9.0)
    view_proj = cam.projection() @ cam.view()
    inv = np.linalg.inv(view_proj)
    h, w = 30, 40
    near_gl, seg_gl = run(ctx, "vec3 a, s; pixel_ray(u_m, u_viewport, gl_FragCoord.xy, a, s); "
                               "out0 = vec4(a, 0.0); out1 = vec4(s, 0.0);", np.zeros((h, w, 4)), 2, m=inv)
    y, x = np.mgrid[0:h, 0:w]
    frag = np.stack([x.ravel() + 0.5, y.ravel() + 0.5], 1)
    near, seg = pixel_ray(inv, (w, h), frag)
    assert np.abs(near_gl[..., :3].reshape(-1, 3) - near).max() < 1e-5 * np.abs(near).max()
    assert np.abs(seg_gl[..., :3].reshape(-1, 3) - seg).max() < 1e-5 * np.abs(seg).max()
    # the near end lies on the near plane, the far end on the far plane
    for p, plane in ((near, cam.near), (near + seg, cam.far)):
        depth = -(np.concatenate([p, np.ones((len(p), 1))], 1) @ cam.view().T)[:, 2]
        assert np.allclose(depth, plane, rtol=1e-9)
    # window depth of points along these rays: 0 at the near plane, 1 at the far one, the GL's value
    s = RNG.uniform(-0.1, 1.1, size=len(near))
    p = near + seg * s[:, None]
    inputs = np.zeros((h, w, 4), np.float32)
    inputs[..., :3] = p.reshape(h, w, 3)
    (depth_gl,) = run(ctx, "out0 = vec4(window_depth(u_m, inp.xyz));", inputs, 1, m=view_proj)
    depth = window_depth(view_proj, inputs[..., :3].reshape(-1, 3).astype(np.float64))
    assert np.abs(depth_gl[..., 0].ravel() - depth).max() < 1e-5
    assert depth.min() == 0.0 and depth.max() == 1.0     # clamped outside the near and far planes
