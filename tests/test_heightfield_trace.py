"""The exact hierarchical height-field tracer: the min/max pyramid (vdmbake/common/pyramid.py), its numpy traversal
against an independent brute force, and the GLSL include (shaders/include/heightfield_trace.glsl) run on
rays read from textures, one ray per pixel, against the same brute force. Stress cases: vertical walls
(cliffs), one-texel slots and walls, grazing rays, rays straight down, rays along cell edges and through
cell corners, rays far from the origin, non-power-of-two fields, wrap and clamp."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.assets import heightfields
from vdmbake.common import pyramid as P
from vdmrender.gpu import gl
from vdmrender.passes import hftrace

from hf_cases import fields, random_rays, slot_field


def agree(a, b, scale=1.0, tol=1e-6):
    """Both miss, or both hit at the same t (relative tolerance)."""
    return (a < 0) == (b < 0) and (a < 0 or abs(a - b) <= tol * (abs(b) + scale))


# ----------------------------------------------------------------------------- the pyramid

@pytest.mark.parametrize("mode", P.MODES)
@pytest.mark.parametrize("shape", [(8, 8), (13, 6), (5, 7), (2, 2), (1, 9)])
def test_pyramid_layout(mode, shape):
    """Level sizes ceil(n / 2^L) down to one texel; every level-L texel bounds the bilinear surface over the
    level-0 cells it covers (checked on a dense grid of points per cell), and is the exact min/max of them."""
    if mode == P.CLAMP and min(shape) < 2:
        pytest.skip("a clamped field needs two samples per side")
    rng = np.random.default_rng(1)
    s = rng.random(shape).astype(np.float32)
    p = P.build(s, mode)
    ny, nx = p.cells
    assert (ny, nx) == (shape if mode == P.WRAP else (shape[0] - 1, shape[1] - 1))
    for L, a in enumerate(p.levels):
        assert a.shape == (-(-ny // 2 ** L), -(-nx // 2 ** L), 2)
    assert p.levels[-1].shape[:2] == (1, 1)
    g = np.linspace(0.0, 1.0, 9)
    for L, a in enumerate(p.levels):
        k = 2 ** L
        for i in range(a.shape[0]):
            for j in range(a.shape[1]):
                y0, y1, x0, x1 = i * k, min((i + 1) * k, ny), j * k, min((j + 1) * k, nx)
                Y, X = np.meshgrid(np.arange(y0, y1)[:, None] + g, np.arange(x0, x1)[:, None] + g, indexing="ij")
                v = P.bilinear(s, mode, X.ravel(), Y.ravel())
                assert a[i, j, 0] <= v.min() + 1e-7 and v.max() <= a[i, j, 1] + 1e-7
                # exact: the corner samples of the cells it covers are surface points
                c = P.corners(s, mode)[y0:y1, x0:x1]
                assert a[i, j, 0] == c.min() and a[i, j, 1] == c.max()


def test_texture_levels_follow_gl_mip_sizes():
    """Padded to powers of two (GL halves mip sizes with floor); level 0 the corners, above (min, max, min, max)."""
    s = np.random.default_rng(2).random((13, 6)).astype(np.float32)
    p = P.build(s, P.WRAP)
    t = P.texture_levels(p)
    assert [a.shape[:2] for a in t] == [(16, 8), (8, 4), (4, 2), (2, 1), (1, 1)]
    assert np.array_equal(t[0][:13, :6], P.corners(s, P.WRAP))
    assert np.array_equal(t[0][13:], np.zeros((3, 8, 4))) and np.array_equal(t[0][:, 6:], np.zeros((16, 2, 4)))
    for L in range(1, len(t)):
        a = p.levels[L]
        assert np.array_equal(t[L][:a.shape[0], :a.shape[1]], np.concatenate([a, a], -1))


def test_parts_round_trip(tmp_path):
    """The bundle's EXR parts (vdmbake.formats.exr) give back the same pyramid."""
    from vdmbake.formats import exr
    p = P.build(np.random.default_rng(3).random((13, 6)).astype(np.float32), P.WRAP)
    exr.write(tmp_path / "p.exr", P.to_parts(p))
    q = P.from_parts(exr.read(tmp_path / "p.exr"), P.WRAP)
    assert q.mode == P.WRAP and np.array_equal(q.samples, p.samples)
    assert len(q.levels) == len(p.levels) and all(np.array_equal(a, b) for a, b in zip(q.levels, p.levels))


def test_bad_fields_are_refused():
    with pytest.raises(ValueError):
        P.build(np.ones((1, 4)), P.CLAMP)
    with pytest.raises(ValueError):
        P.build(np.array([[0.0, np.nan]]), P.WRAP)
    with pytest.raises(ValueError):
        P.build(np.ones((4, 4)), "mirror")


# ----------------------------------------------------------------------------- the exact patch

def test_brute_force_on_known_surfaces():
    """The reference itself, on surfaces with known answers: a flat field, a plane, a bilinear saddle."""
    flat = np.full((4, 4), 0.25)
    assert P.first_hit(flat, P.WRAP, [1.3, 2.2, 0.0], [0.0, 0.0, 2.0], 0.0, 1.0) == pytest.approx(0.125)
    assert P.first_hit(flat, P.WRAP, [1.3, 2.2, 0.0], [3.0, -1.0, 0.5], 0.0, 1.0) == pytest.approx(0.5)
    assert P.first_hit(flat, P.WRAP, [1.3, 2.2, 0.0], [3.0, -1.0, 0.5], 0.0, 0.4) == -1.0
    plane = np.add.outer(np.zeros(4), np.arange(4.0)) * 0.1 + 0.2        # depth 0.2 + 0.1 x (clamped, 0 <= x <= 3)
    # ray z = 0.3 + 0.05 t, x = 3 - t: hit where 0.3 + 0.05 t = 0.2 + 0.1 (3 - t), t = 0.2 / 0.15
    assert P.first_hit(plane, P.CLAMP, [3.0, 1.0, 0.3], [-1.0, 0.0, 0.05], 0.0, 3.0) == pytest.approx(0.2 / 0.15)
    saddle = np.array([[0.0, 1.0], [1.0, 0.0]])                          # depth x + y - 2 x y on the one cell
    # ray x = y = t at z = 0.49 starts below the corner (depth 0): a hit at t0; re-entry: it comes out where
    # 2 t - 2 t^2 = 0.49, t = (1 - sqrt(0.02)) / 2, and goes back in at t = (1 + sqrt(0.02)) / 2
    p = P.build(saddle, P.CLAMP)
    for hit in (P.first_hit, lambda *a: P.trace(p, *a[2:])):
        assert hit(saddle, P.CLAMP, [0.0, 0.0, 0.49], [1.0, 1.0, 0.0], 0.0, 1.0) == 0.0
        assert hit(saddle, P.CLAMP, [0.0, 0.0, 0.49], [1.0, 1.0, 0.0], 0.0, 1.0, True) == pytest.approx(
            (1 + np.sqrt(0.02)) / 2)


def test_patch_quadratic_is_stable():
    """The Numerical Recipes form keeps a root accurate where the textbook formula cancels: a nearly flat
    patch (A tiny), a ray nearly along it (B >> A C)."""
    c = np.array([0.0, 1e-7, 0.0, 0.0])             # e = -1e-7: A = 1e-7 du dv
    s, _ = P.patch_hit(c, 0.1, 0.2, -1e-6, 1.0, 1.0, 1e-3, 1.0, False)
    f = lambda x: -1e-6 + 1e-3 * x - P.bilinear(np.array([[0.0, 1e-7], [0.0, 0.0]]), P.CLAMP, 0.1 + x, 0.2 + x)
    assert s > 0 and abs(f(s)) < 1e-15
    assert P.patch_hit(np.zeros(4), 0.5, 0.5, 0.0, 1.0, 0.0, 0.0, 1.0, False)[0] == 0.0   # on the surface: t0
    assert P.patch_hit(np.zeros(4), 0.5, 0.5, 0.0, 1.0, 0.0, 0.0, 1.0, True)[0] == -1.0   # inside, never out


# ----------------------------------------------------------------------------- numpy traversal vs brute force

@pytest.mark.parametrize("mode", P.MODES)
@pytest.mark.parametrize("reentry", [False, True])
def test_traversal_matches_brute_force(mode, reentry):
    rng = np.random.default_rng(3)
    for name, s in fields().items():
        if mode == P.CLAMP and min(s.shape) < 2:
            continue
        p = P.build(s, mode)
        for start in (1, 64):
            for r in random_rays(p, rng, 64):
                a = P.trace(p, r[:3], r[4:7], r[3], r[7], reentry, r[8], start_level=start)
                b = P.first_hit(s, mode, r[:3], r[4:7], r[3], r[7], reentry, r[8])
                assert agree(a, b), (name, start, r.tolist(), a, b)


def test_iteration_cap():
    """A ray that needs more visits than the cap stops with exhausted set, above the surface at t_reached."""
    s = 1.0 - heightfields.pattern("bricks", 32)
    p = P.build(s, P.WRAP)
    o, d = np.array([0.3, 0.4, 0.0]), np.array([40.0, 3.0, 0.01])
    st = P.TraceStats()
    full = P.trace(p, o, d, 0.0, 100.0, stats=st)
    assert full > 0 and st.visits > 8
    cut = P.TraceStats()
    assert P.trace(p, o, d, 0.0, 100.0, max_iter=8, stats=cut) == -1.0 and cut.exhausted
    assert 0.0 <= cut.t_reached < full
    q = o + d * cut.t_reached
    assert q[2] < P.bilinear(s, P.WRAP, q[0], q[1])


# ----------------------------------------------------------------------------- GLSL

# The tracer's cell visits per ray: the probe counts its STEP()s per pixel (cost_count.glsl counts them per frame).
PROBE = """#version 430
{defines}
int hf_visits = 0;
#define STEP() hf_visits++
#define FETCH(e) (e)
#define SEARCH()
#include "heightfield_trace.glsl"
uniform sampler2D u_o;     // origin, t0
uniform sampler2D u_d;     // direction, t1
uniform sampler2D u_k;     // bend
uniform int u_reentry;
out vec4 frag;
void main() {{
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 a = texelFetch(u_o, p, 0), b = texelFetch(u_d, p, 0);
    float k = texelFetch(u_k, p, 0).r;
    float t = hf_trace_general(a.xyz, b.xyz, k, a.w, b.w, u_reentry != 0);
    frag = vec4(t, float(hf_visits), hf_exhausted ? 1.0 : 0.0, hf_t_reached);
}}
"""


def trace_gl(ctx, p: P.Pyramid, rays: np.ndarray, reentry=False, defines=()) -> np.ndarray:
    """Each ray (origin, t0, direction, t1, bend) traced by the include in one pixel: (t, visits, exhausted,
    t_reached)."""
    defs = (["HF_CLAMP"] if p.mode == P.CLAMP else []) + list(defines)
    src = PROBE.format(defines="\n".join(f"#define {x}" for x in defs)).replace(
        '#include "heightfield_trace.glsl"', (gl.SHADERS / "include" / "heightfield_trace.glsl").read_text().replace(
            '#include "cost_count.glsl"', ""))
    prog = ctx.program(vertex_shader=gl.source("fullscreen.vert"), fragment_shader=src)
    w = len(rays)
    tex_o = ctx.texture((w, 1), 4, np.ascontiguousarray(rays[:, :4], np.float32).tobytes(), dtype="f4")
    tex_d = ctx.texture((w, 1), 4, np.ascontiguousarray(rays[:, 4:8], np.float32).tobytes(), dtype="f4")
    tex_k = ctx.texture((w, 1), 1, np.ascontiguousarray(rays[:, 8], np.float32).tobytes(), dtype="f4")
    for t in (tex_o, tex_d, tex_k):
        t.filter = (ctx.NEAREST, ctx.NEAREST)
    hf = hftrace.pyramid_texture(ctx, p)
    target = gl.Target(ctx, w, 1)
    try:
        gl.bind_textures(prog, u_o=tex_o, u_d=tex_d, u_k=tex_k)
        hftrace.bind(prog, hf, p)
        gl.set_uniforms(prog, u_reentry=int(reentry))
        target.begin()
        ctx.vertex_array(prog, []).render(mode=ctx.TRIANGLES, vertices=3)
        return target.read()[0].astype(np.float64)
    finally:
        for o in (tex_o, tex_d, tex_k, hf, target, prog):
            o.release()


def f32(rays):
    return rays.astype(np.float32).astype(np.float64)     # the rays as the GPU sees them


@pytest.mark.parametrize("mode", P.MODES)
@pytest.mark.parametrize("reentry", [False, True])
def test_glsl_matches_brute_force(ctx, mode, reentry):
    """float32 on the GPU against float64 brute force: every ray agrees (hit or miss, t within 2e-4 of the
    ray's length scale). Measured: worst relative t error 3e-6; cell visits equal to the numpy twin's for
    nearly all rays."""
    rng = np.random.default_rng(4)
    worst, same, total = 0.0, 0, 0
    for name, s in fields().items():
        p = P.build(s, mode)
        rays = f32(random_rays(p, rng, 160))
        out = trace_gl(ctx, p, rays, reentry)
        for r, g in zip(rays, out):
            b = P.first_hit(s, mode, r[:3], r[4:7], r[3], r[7], reentry, r[8])
            scale = r[7] - r[3]
            assert agree(g[0], b, scale, 2e-4), (name, r.tolist(), g.tolist(), b)
            if b >= 0:
                worst = max(worst, abs(g[0] - b) / scale)
            st = P.TraceStats()
            P.trace(p, r[:3], r[4:7], r[3], r[7], reentry, r[8], stats=st)
            same += int(st.visits == g[1])
            total += 1
    print(f"worst relative t error {worst:.2e}, visits equal to numpy's for {same}/{total}")
    assert same >= 0.97 * total


def test_glsl_thin_slot_and_wall(ctx):
    """A one-texel slot (depth 1 in depth 0: a V-shaped trench between x = 7 and 9) entered from every 1/32
    texel across it, and a one-texel wall (depth 0 in depth 1: a ridge, peak at x = 8) approached at every
    1/64 of its height, each at slopes from steep to grazing and both ways: every hit where brute force has it
    (none slips through a wall, none stops short)."""
    rays, fields_ = [], {"slot": P.build(slot_field(16, "slot"), P.WRAP), "wall": P.build(slot_field(16, "wall"),
                                                                                          P.WRAP)}
    for slope in (0.02, 0.3, 1.0, 8.0):                    # depth per texel travelled
        for y in (3.0, 3.37):
            for sx in (1.0, -1.0):
                rays += [("slot", [x, y, 0.0, 0.0, sx, 0.0, slope, 60.0, 0.0]) for x in np.arange(7.0, 9.0, 1 / 32)]
                rays += [("wall", [8.0 - 5.0 * sx, y, z, 0.0, sx, 0.0, slope * 0.01, 60.0, 0.0])
                         for z in np.arange(-0.01, 1.0, 1 / 64)]
    for kind, p in fields_.items():
        r = f32(np.array([x for k, x in rays if k == kind]))
        out = trace_gl(ctx, p, r)
        hits = 0
        for ray, g in zip(r, out):
            b = P.first_hit(p.samples, P.WRAP, ray[:3], ray[4:7], ray[3], ray[7])
            assert agree(g[0], b, 1.0, 1e-5), (kind, ray.tolist(), g.tolist(), b)
            hits += b > 0
        assert hits >= 0.9 * len(r)          # the rays do reach the walls (not the start point)


def test_glsl_far_from_origin(ctx):
    """Wrap mode, rays starting 10^4 texels from the origin (float32 spacing 1e-3 texel there)."""
    rng = np.random.default_rng(5)
    s = fields()["cliffs 16"]
    p = P.build(s, P.WRAP)
    rays = f32(random_rays(p, rng, 300, far=True))
    out = trace_gl(ctx, p, rays)
    for r, g in zip(rays, out):
        b = P.first_hit(s, P.WRAP, r[:3], r[4:7], r[3], r[7], bend=r[8])
        assert agree(g[0], b, r[7], 1e-3), (r.tolist(), g.tolist(), b)


def test_glsl_start_level_and_cap(ctx):
    """HF_START_LEVEL changes the visits, not the hits; HF_MAX_ITER stops the loop with hf_exhausted set."""
    rng = np.random.default_rng(6)
    s = fields()["bricks 32"]
    p = P.build(s, P.WRAP)
    rays = f32(random_rays(p, rng, 300))
    top = trace_gl(ctx, p, rays)
    low = trace_gl(ctx, p, rays, defines=("HF_START_LEVEL 1",))
    assert np.array_equal(top[:, 0] >= 0, low[:, 0] >= 0)
    hit = top[:, 0] >= 0
    assert np.allclose(top[hit, 0], low[hit, 0], rtol=1e-5, atol=1e-6)
    cap = trace_gl(ctx, p, rays, defines=("HF_MAX_ITER 4",))
    assert (cap[:, 1] <= 4).all()
    stopped = cap[:, 2] > 0
    assert stopped.any() and (cap[stopped, 0] == -1.0).all() and (top[stopped, 1] > 4).all()
    assert (cap[stopped, 3] <= np.where(hit, top[:, 0], np.inf)[stopped] + 1e-6).all()
