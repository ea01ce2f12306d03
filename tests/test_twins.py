"""Every GLSL include that has a numpy twin, against the twin, through one harness (tests/glsl_eval.py):
ONE table, one row per pair (or per variant of a pair), and ONE parametrised test over it.

A row: name, the GLSL includes, the GLSL body (reads the element's vec4 inputs, writes out0, out1, ...), the
numpy twin (float64, fed the float32 values the shader saw; returns one array (N, k <= 4) per output), the
input generator (ordinary values plus the hard cases: grazing angles, degenerate and near-zero vectors, huge
and tiny magnitudes where the twin claims to be stable), and the tolerance (atol, rtol): each component must
satisfy |glsl - twin| <= atol + rtol |twin|. Each tolerance is a float32 bound (eps = 6e-8 per rounding)
justified next to the row; a row that disagrees beyond float32 rounding is an xfail(strict) finding, with the
measured disagreement, never a looser tolerance. `setup` (optional) gives the uniforms, textures and defines.
"""
from __future__ import annotations

from types import SimpleNamespace
from typing import Callable, NamedTuple

import numpy as np
import pytest

import hf_cases
from vdmbake.kernels import octahedral as oc
from vdmbake.common import pyramid as P
from vdmbake.common import texspace, texture
from vdmbake.common.geometry import onb
from vdmbake.common.mesh import SurfaceFrame
import curved_ray as cr
from vdmrender.gpu import gl
from vdmrender.tracing import quadric_math, shading
from vdmrender.passes import hftrace
from vdmrender.common.camera import Camera, pixel_ray, window_depth
from glsl_eval import evaluate


class Twin(NamedTuple):
    name: str
    includes: list[str]
    body: str
    twin: Callable                    # (inputs: dict of float64 arrays as the shader saw them) -> [arrays]
    inputs: Callable                  # () -> dict of (N, k) arrays
    tol: tuple[float, float]          # (atol, rtol)
    setup: Callable | None = None     # (ctx) -> dict(uniforms=, textures=, defines=, declarations=)


def f32(a):
    """What the shader sees of a float64 value: float32, back in float64 for the twin."""
    return np.asarray(a, np.float32).astype(np.float64)


def unit(a):
    a = np.asarray(a, np.float64)
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


RNG_SEED = 7


def rng():
    return np.random.default_rng(RNG_SEED)


# ----------------------------------------------------------------------------- frame.glsl / geometry.onb

def onb_inputs():
    d = rng().normal(size=(300, 3))
    hard = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0.6, 0.8, 0],
            [1e-4, 0, -1], [0, 1e-4, -1], [1e-7, 1e-7, -1], [1e-3, -1e-3, 1], [-1e-7, 0, 1],   # near the poles
            [1, 1, -1e-7], [1, -1, 1e-7], [0, 1, -0.0]]                                           # the branch at z = 0
    return {"w": unit(np.concatenate([d, hard]))}


def onb_twin(x):
    u, v = onb(x["w"][:, :3])
    return [u, v]


# ----------------------------------------------------------------------------- camera.glsl / camera.py

CAMERA = Camera(np.array([3.0, -2.0, 1.5]), np.zeros(3), np.array([0.0, 0.0, 1.0]), 60.0, 40, 30, 0.5, 9.0)
VIEW_PROJ = CAMERA.projection() @ CAMERA.view()
INV_VIEW_PROJ = np.linalg.inv(VIEW_PROJ)
CAMERA_DECLS = "uniform mat4 u_m;\nuniform vec2 u_viewport;\n"


def pixel_ray_inputs():
    w, h = CAMERA.width, CAMERA.height
    y, x = np.mgrid[0:h, 0:w]
    frag = np.stack([x.ravel() + 0.5, y.ravel() + 0.5], 1)
    edges = [[0, 0], [w, h], [0, h], [w, 0], [w / 2, h / 2], [1e-3, h - 1e-3]]   # window corners and centre
    return {"frag": np.concatenate([frag, edges])}


def pixel_ray_twin(x):
    near, seg = pixel_ray(f32(INV_VIEW_PROJ), (CAMERA.width, CAMERA.height), x["frag"][:, :2])
    return [near, seg]


def window_depth_inputs():
    near, seg = pixel_ray(INV_VIEW_PROJ, (CAMERA.width, CAMERA.height), pixel_ray_inputs()["frag"])
    r = rng()
    s = np.concatenate([r.uniform(-0.1, 1.1, len(near)), np.zeros(len(near)), np.ones(len(near))])
    p = np.tile(near, (3, 1)) + np.tile(seg, (3, 1)) * s[:, None]      # inside, on the near and on the far plane
    return {"p": p}


def window_depth_twin(x):
    return [window_depth(f32(VIEW_PROJ), x["p"][:, :3])[:, None]]


# ----------------------------------------------------------------------------- shading.glsl / shading.py

LIGHT = SimpleNamespace(direction=f32(unit([0.45, -0.55, 0.7])), color=f32([1.0, 0.9, 0.8]), ambient=f32([0.12, 0.12, 0.13]))
MATERIAL = SimpleNamespace(diffuse=float(f32(0.9)), specular=float(f32(0.25)), shininess=48.0)
SHADING_UNIFORMS = dict(u_light_dir=tuple(LIGHT.direction), u_light_color=tuple(LIGHT.color),
                        u_ambient=tuple(LIGHT.ambient), u_kd=MATERIAL.diffuse, u_ks=MATERIAL.specular,
                        u_shininess=MATERIAL.shininess)


def shade_inputs():
    r = rng()
    n = 400
    N = unit(r.normal(size=(n, 3)))
    V = unit(r.normal(size=(n, 3)))
    L = LIGHT.direction
    # hard cases: the light grazing the surface (N . L = +-1e-4 and exactly 0, built exactly), the eye
    # opposite the light (L + V = 0: no half vector), the eye along the normal and along the light
    perp = unit(np.cross(L, [0.0, 0.0, 1.0]))
    graze = [unit(perp + s * L) for s in (1e-4, -1e-4, 3e-3)]
    hard_N = [*graze, perp, L, L, L, unit(L + [0, 0, 1]), [0.0, 0.0, 1.0]]
    hard_V = [L, L, unit(L + perp), L, -L, L, unit(L + 1e-3 * perp), -L, [0.0, 0.0, 1.0]]
    N = np.concatenate([N, hard_N])
    V = np.concatenate([V, hard_V])
    m = len(N)
    albedo = r.uniform(0.0, 1.0, (m, 3))
    albedo[-3:] = [0.0, 1.0, 1e-6]
    lit = (r.uniform(size=m) < 0.8).astype(float)
    lit[-len(hard_N):] = 1.0
    return {"a": np.concatenate([albedo, lit[:, None]], 1), "N": N, "V": V}


def shade_twin(x):
    return [shading.shade(x["a"][:, :3], x["N"][:, :3], x["V"][:, :3], x["a"][:, 3] > 0, LIGHT, MATERIAL)]


def safe_normalize_inputs(extreme=False):
    r = rng()
    d = r.normal(size=(200, 3))
    scale = 10.0 ** r.uniform(-15, 15, (200, 1))           # within float32's squares
    hard = [[0.0, 0.0, 0.0], [1e-15, 0, 0], [3e-16, -2e-16, 1e-16], [1e15, 1e15, -1e15], [0, 0, -1e-10]]
    if extreme:     # squares below FLT_MIN or above FLT_MAX
        hard = [[1e-19, 0, 0], [3e-20, 3e-20, 0], [2e19, 0, 0], [1e25, -1e25, 1e25], [1e-30, 0, 0]]
        return {"v": np.array(hard)}
    return {"v": np.concatenate([d * scale, hard])}


def safe_normalize_twin(x):
    return [shading.safe_normalize(x["v"][:, :3])]


# ----------------------------------------------------------------------------- quadric.glsl / quadric_math.py

def quadric_inputs():
    """Variance matrices T (columns as four vec4 inputs): spheres all over the view, small and far, large and
    near, disks (rank-deficient T) of every tilt, and some that reach the eye plane (unbounded: whole screen)."""
    r = rng()
    Ts = []
    eye = CAMERA.eye
    fwd = unit(CAMERA.target - eye)
    for k in range(300):
        depth = 10.0 ** r.uniform(-0.2, 1.2)
        c = eye + depth * unit(fwd + 0.4 * r.normal(size=3))
        kind = k % 5
        if kind == 3:    # a disk
            (u,), (v,) = onb(unit(r.normal(size=(1, 3))))
            Ts.append(quadric_math.disk_variance(c, u, v, depth * 10.0 ** r.uniform(-2, -0.5)))
        elif kind == 4:  # reaching the eye plane, or clearly not
            Ts.append(quadric_math.sphere_variance(eye + r.normal(size=3), 1.5 + r.uniform(0, 2)))
        else:            # angular radius from 1e-2 to 0.5 rad
            Ts.append(quadric_math.sphere_variance(c, depth * 10.0 ** r.uniform(-2, -0.3)))
    T = np.array(Ts)
    return {f"c{j}": T[:, :, j] for j in range(4)}


def quadric_twin(x):
    T = np.stack([x[f"c{j}"] for j in range(4)], 2)
    out = []
    for t in T:
        b = quadric_math.projected_bounds(f32(VIEW_PROJ), t)
        out.append((-1.0, -1.0, 1.0, 1.0) if b is None else b)
    return [np.array(out)]


# ----------------------------------------------------------------------------- curved_ray.glsl / curved_ray.py

def curved_ray_inputs():
    r = rng()
    n = 400
    t, h, d = r.uniform(0, 0.5, n), r.uniform(0, 0.06, n), r.uniform(0, 0.5, n)
    th, c = r.uniform(0, np.radians(85), n), r.uniform(-2, 3, n)
    # hard cases: straight down, grazing (89.9 and 90 degrees), the plane (c = 0) and nearly (|c| = 1e-6),
    # zero distance, depth and sigma, tiny values
    th = np.concatenate([th, [0.0, np.radians(89.9), np.pi / 2, 0.3, 0.3, 0.3, 1.0, 1.0, np.radians(89.9)]])
    c = np.concatenate([c, [0.5, 0.5, 0.0, 0.0, 1e-6, -1e-6, 2.0, -2.0, 1e-6]])
    t = np.concatenate([t, [0.2, 0.2, 0.0, 0.3, 1e-6, 0.2, 0.0, 1e-5, 0.4]])
    h = np.concatenate([h, [0.03, 0.0, 0.05, 0.0, 1e-6, 0.03, 0.0, 1e-5, 0.02]])
    d = np.concatenate([d, [0.1, 0.0, 0.2, 0.2, 1e-6, 0.0, 1e-5, 0.1, 0.3]])
    return {"a": np.stack([t, h, d, c], 1), "b": np.stack([np.sin(th), np.cos(th)], 1)}


def curved_ray_twin(x):
    t, h, d, c = x["a"].T
    st, ct = x["b"][:, 0], x["b"][:, 1]
    return [np.stack([*cr.curved_ray(t, 0.0, st, -ct, c), *cr.curved_ray(t, h, st, ct, c)], 1),
            np.stack([cr.ray_distance(d, ct, c), cr.depth_distance(h, st, ct, c), cr.exit_distance(h, st, ct, c)], 1)]


# ----------------------------------------------------------------------------- heightfield_trace.glsl / pyramid.py

HF_FIELDS = hf_cases.fields()
HF_RAYS = 160     # per field


def hf_inputs(mode, field):
    p = P.build(HF_FIELDS[field], mode)
    rays = hf_cases.random_rays(p, np.random.default_rng(4), HF_RAYS)
    return {"o": rays[:, :4], "d": rays[:, 4:8], "k": rays[:, 8]}


def hf_twin(mode, field):
    p = P.build(HF_FIELDS[field], mode)

    def twin(x):   # max_iter: the include's default HF_MAX_ITER
        return [np.array([[P.trace(p, o[:3], d[:3], o[3], d[3], bend=k[0], max_iter=256)]
                          for o, d, k in zip(x["o"], x["d"], x["k"])])]
    return twin


def hf_setup(mode, field):
    def setup(ctx):
        p = P.build(HF_FIELDS[field], mode)
        tex = hftrace.pyramid_texture(ctx, p)
        return dict(textures={"u_hf": tex}, uniforms=hftrace.uniforms(p), owned=[tex],
                    defines=("HF_CLAMP",) if mode == P.CLAMP else ())
    return setup


HF_BODY = "out0 = vec4(hf_trace_general(o.xyz, d.xyz, k.x, o.w, d.w, false));"


# ----------------------------------------------------------------------------- octahedral.glsl / octahedral.py

OCT_BASIS = oc.map_basis([0.2, -0.3, 0.93])


def oct_inputs(hemi):
    d = rng().normal(size=(1500, 3))
    hard = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 1, 0], [1, -1, 0], [-1, 0, 0], [1, 1, 1e-7], [1, 0, -1e-7],
            [1e-7, 0, 1], [1e-7, 1e-7, -1]]                          # poles, equator (the fold), near them
    if hemi:   # straight down has no nearest horizon point (every one is as near): left out
        hard[1] = hard[-1] = [0.0, 0.6, -0.8]
    d = unit(np.concatenate([d, hard])) @ OCT_BASIS                  # also in the map's own frame
    return {"e": d}


OCT_BODY = """
    ivec2 view[3];
    vec3 w;
    nearest_views(e.xyz, view, w);
    vec3 s = vec3(0.0);
    for (int k = 0; k < 3; k++) {
        vec3 ve, vu, vv;
        view_frame(view[k], ve, vu, vv);
        s += w[k] * ve;
    }
    out0 = vec4(s, w.x + w.y + w.z);
"""


def oct_twin(views, hemi):
    def twin(x):
        e, _, _ = oc.view_frames(views, hemi, OCT_BASIS)
        idx, w = oc.nearest_views(x["e"][:, :3], views, hemi, OCT_BASIS)
        blend = (w[..., None] * e[idx[..., 1], idx[..., 0]]).sum(1)
        return [np.concatenate([blend, w.sum(1)[:, None]], 1)]
    return twin


def oct_frame_inputs(views):
    j, i = np.mgrid[0:views, 0:views]
    return {"view": np.stack([i.ravel(), j.ravel()], 1)}


def oct_frame_twin(views, hemi):
    def twin(x):
        e, u, v = oc.view_frames(views, hemi, OCT_BASIS)
        i, j = x["view"][:, 0].astype(int), x["view"][:, 1].astype(int)
        return [e[j, i], u[j, i], v[j, i]]
    return twin


def oct_setup(views, hemi):
    return lambda ctx: dict(uniforms=dict(u_views=views, u_basis=np.ascontiguousarray(OCT_BASIS.T)),
                            defines=("HEMI",) if hemi else ())


# ----------------------------------------------------------------------------- mesostructure.glsl / texspace.py

TILING = (3.0, 2.0)


def meso_inputs(kind="ordinary"):
    """Per element: unit normal N, tangents dpdu, dpdv in N's plane, principal direction d1 (unit, in the
    plane) and curvatures, a texture-space normal and a texture direction. "ordinary": well-conditioned maps
    (anisotropy up to 3.2, tangents at least 30 degrees apart: cond(J^T J) <= 40), tile sizes from 1e-5 to 1e3
    world units; "tiny": the same with tiles of 1e-9 to 1e-7 world units; "degenerate": dpdu or dpdv zero or
    the two parallel (a pole)."""
    r = rng()
    n = 300
    N = unit(r.normal(size=(n, 3)))
    u, v = onb(N)
    ang = r.uniform(0, 2 * np.pi, (n, 2))
    ang[:, 1] = ang[:, 0] + r.choice([-1, 1], n) * r.uniform(np.pi / 6, 5 * np.pi / 6, n)
    size = 10.0 ** (r.uniform(-9, -7, (n, 1)) if kind == "tiny" else r.uniform(-5, 3, (n, 1)))
    aniso = 10.0 ** r.uniform(-0.5, 0.5, (n, 1))
    dpdu = size * (np.cos(ang[:, :1]) * u + np.sin(ang[:, :1]) * v)
    dpdv = size * aniso * (np.cos(ang[:, 1:]) * u + np.sin(ang[:, 1:]) * v)
    if kind == "degenerate":
        dpdu[: n // 3] = 0.0                                         # a pole: dP/du vanishes
        dpdv[n // 3: 2 * n // 3] = 0.0
        dpdv[2 * n // 3:] = 2.0 * dpdu[2 * n // 3:]                  # parallel tangents
    a = r.uniform(0, 2 * np.pi, (n, 1))
    d1 = np.cos(a) * u + np.sin(a) * v
    k = r.normal(size=(n, 2)) * 10.0 ** r.uniform(-2, 2, (n, 1)) / size
    n_tex = unit(r.normal(size=(n, 3)) + [0, 0, 1.5])
    n_tex[:5] = [[0, 0, 1], [1, 0, 0], [0, 1, 0], unit([1, 1, 1e-6]), [0, 0, -1]]
    t = r.normal(size=(n, 3))
    t[:3, :2] = [[0.0, 0.0], [1e-8, 0.0], [0.0, 1e-5]]               # no tangential part (V = N)
    return {"N": N, "dpdu": dpdu, "dpdv": dpdv, "d1": np.concatenate([d1, k[:, :1]], 1),
            "k2": np.concatenate([k[:, 1:], np.zeros((n, 3))], 1)[:, :1], "ntex": n_tex, "t": t}


MESO_BODY = """
    v_normal = N.xyz; v_dpdu = dpdu.xyz; v_dpdv = dpdv.xyz; v_d1 = d1.xyz; v_curv = vec2(d1.w, k2.x);
    Frame F = surface_frame(N.xyz);
    out0 = vec4(world_normal(F, ntex.xyz), F.sn);
    out1 = vec4(texture_curvature(F, t.xyz));
"""


def meso_twin(x):
    N = x["N"][:, :3]
    frame = SurfaceFrame(x["dpdu"][:, :3], x["dpdv"][:, :3], x["d1"][:, 3], x["k2"][:, 0], x["d1"][:, :3])
    J = texspace.jacobian(frame, TILING)
    wn = texspace.world_normals(J, N, x["ntex"][:, :3])
    t = x["t"][:, :2]
    l = np.linalg.norm(t, axis=1, keepdims=True)
    e = np.where(l > 1e-6, t / np.where(l > 1e-6, l, 1.0), [1.0, 0.0])
    # texture_curvature takes (D, 2) directions for every vertex: one direction per vertex here, the diagonal
    c = np.array([texspace.texture_curvature(SurfaceFrame(*(a[i:i + 1] for a in (frame.dpdu, frame.dpdv, frame.k1,
                                                                                  frame.k2, frame.d1))),
                                             N[i:i + 1], TILING, e[i:i + 1])[0, 0] for i in range(len(N))])
    return [np.concatenate([wn, texspace.normal_scale(J)[:, None]], 1), c[:, None]]


# `#define in`: the include's fragment inputs (v_dpdu, ...) become plain globals the body sets per element
MESO_SETUP = lambda ctx: dict(uniforms=dict(u_tiling=TILING), defines=("in",))        # noqa: E731


# ----------------------------------------------------------------------------- albedo.glsl / texture.sample

ALBEDO_MAP = np.random.default_rng(3).integers(0, 256, (5, 8, 3), dtype=np.uint8)
ALBEDO_MAP[0, 0] = [0, 0, 0]
ALBEDO_MAP[0, 1] = [255, 255, 255]           # a black/white edge: the widest blend


def albedo_inputs():
    r = rng()
    uv = r.uniform(-2, 3, (500, 2))
    h, w = ALBEDO_MAP.shape[:2]
    centres = np.stack(np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h), -1).reshape(-1, 2)
    hard = [[0, 0], [1, 1], [-1, 0.5], [1 / w, 0.5 / h], [1.5 / w, 0.5 / h], [1 - 1e-7, 1e-7], [37.3, -12.9]]
    return {"uv": np.concatenate([uv, centres, hard])}


def albedo_twin(x):
    return [texture.sample(ALBEDO_MAP, x["uv"][:, :2])]


def albedo_setup(ctx):
    tex = gl.albedo_texture(ctx, ALBEDO_MAP)
    return dict(textures={"u_albedo_map": tex}, owned=[tex])


# ----------------------------------------------------------------------------- the table

def xfail(row: Twin, why: str):
    return pytest.param(row, id=row.name, marks=pytest.mark.xfail(strict=True, reason=why))


TABLE = [
    # unit results from ~10 flops: 16 float32 ulps of 1 (measured 1.0e-7)
    Twin("onb", ["frame.glsl"], "vec3 u, v; onb(w.xyz, u, v); out0 = vec4(u, 0.0); out1 = vec4(v, 0.0);",
         onb_twin, onb_inputs, (2e-6, 0.0)),
    # world points of magnitude <= 20 from a float32 matrix product and a division by w: a few ulps of the
    # largest coordinate (ulp(16) = 1.9e-6) (measured 2.0e-6)
    Twin("pixel_ray", ["camera.glsl"],
         "vec3 a, s; pixel_ray(u_m, u_viewport, frag.xy, a, s); out0 = vec4(a, 0.0); out1 = vec4(s, 0.0);",
         pixel_ray_twin, pixel_ray_inputs, (2e-5, 0.0),
         lambda ctx: dict(uniforms=dict(u_m=INV_VIEW_PROJ, u_viewport=(float(CAMERA.width), float(CAMERA.height))),
                          declarations=CAMERA_DECLS)),
    # a depth in [0, 1] from c.z / c.w: c.z sums terms up to far / (far - near) |p| ~ 20, so a few ulps of 20
    # relative to c.w >= near = 0.5 (measured 4.8e-7)
    Twin("window_depth", ["camera.glsl"], "out0 = vec4(window_depth(u_m, p.xyz));", window_depth_twin,
         window_depth_inputs, (2e-5, 0.0),
         lambda ctx: dict(uniforms=dict(u_m=VIEW_PROJ), declarations=CAMERA_DECLS)),
    # radiance <= ~2: dot products and pow(x, 48) = exp2(48 log2 x), whose relative error is 48 x that of
    # x (48 * 2 ulps = 1.1e-5 relative) (measured 1.0e-6)
    Twin("shade", ["shading.glsl"], "out0 = vec4(shade(a.rgb, N.xyz, V.xyz, a.w), 0.0);", shade_twin,
         shade_inputs, (1e-6, 2e-5), lambda ctx: dict(uniforms=SHADING_UNIFORMS)),
    # unit results (or the zero vector) of one length and one division: 4 ulps of 1 (measured 9.7e-8)
    Twin("safe_normalize", ["shading.glsl"], "out0 = vec4(safe_normalize(v.xyz), 0.0);", safe_normalize_twin,
         safe_normalize_inputs, (5e-7, 0.0)),
    # NDC bounds from b^2 - a c in float32, which cancels: error ~ eps (b / a)^2 / rho for an angular radius rho
    # >= 1e-2 and |b / a| of a few: ~5e-5 (measured 1.2e-5)
    Twin("quadric_bounds", ["quadric.glsl"], "out0 = quadric_bounds(mat4(c0, c1, c2, c3));", quadric_twin,
         quadric_inputs, (1e-4, 0.0), lambda ctx: dict(uniforms=dict(u_view_proj=VIEW_PROJ))),
    # lengths <= ~1 from a few flops and one sqrt (the stable forms): a few ulps, relative (measured ratio 0.04;
    # the largest absolute difference, 3.5e3, is on depth_distance's deepest point ct / (c st^2) at c = 1e-6)
    Twin("curved_ray", ["curved_ray.glsl"],
         """float t = a.x, h = a.y, d = a.z, c = a.w, st = b.x, ct = b.y;
    out0 = vec4(curved_ray(t, 0.0, st, -ct, c), curved_ray(t, h, st, ct, c));
    out1 = vec4(ray_distance(d, ct, c), depth_distance(h, st, ct, c), exit_distance(h, st, ct, c), 0.0);""",
         curved_ray_twin, curved_ray_inputs, (1e-6, 1e-5)),
    # the hit t (<= 20; -1 both for a miss) from the same steps in float32: cell-local patch roots, a few ulps
    # of 16 (1.9e-6) times ~10 (measured 3.8e-6; no hit/miss disagreement)
    *(Twin(f"hf_trace {mode} {field}", ["heightfield_trace.glsl"], HF_BODY, hf_twin(mode, field),
           (lambda mode=mode, field=field: hf_inputs(mode, field)), (2e-5, 0.0), hf_setup(mode, field))
      for mode in P.MODES for field in HF_FIELDS),
    # unit vectors through encode, floor, weights, decode, normalize: ~30 flops, 64 ulps of 1 (measured 6.2e-7)
    *(Twin(f"octahedral nearest_views {views}{' hemi' if hemi else ''}", ["octahedral.glsl"], OCT_BODY,
           oct_twin(views, hemi), (lambda hemi=hemi: oct_inputs(hemi)), (4e-6, 0.0), oct_setup(views, hemi))
      for views in (8, 13) for hemi in (False, True)),
    # unit frames from decode and Duff's frame: 16 ulps of 1 (measured 2.3e-7)
    *(Twin(f"octahedral view_frame {views}{' hemi' if hemi else ''}", ["octahedral.glsl"],
           "vec3 e, u, v; view_frame(ivec2(view.xy), e, u, v); out0 = vec4(e, 0.0); out1 = vec4(u, 0.0); "
           "out2 = vec4(v, 0.0);", oct_frame_twin(views, hemi), (lambda views=views: oct_frame_inputs(views)),
           (2e-6, 0.0), oct_setup(views, hemi))
      for views in (8, 13) for hemi in (False, True)),
    # unit normals, s_n and curvatures through J^T J's inverse: cond(J^T J) <= 40 times a few float32 ulps
    # (measured 4.4e-5 absolute on curvatures of ~1e3, 0.044 of the tolerance)
    Twin("mesostructure frame", ["mesostructure.glsl"], MESO_BODY, meso_twin, meso_inputs, (2e-5, 2e-5), MESO_SETUP),
    # tiles of 1e-9..1e-7 world units: surface_frame forms J^T J from J scaled to unit size, so the same
    # bound holds as for ordinary tiles (before: an absolute 1e-30 floor on det ~ |J|^4 gave s_n 148x too large)
    Twin("mesostructure frame, tiny tiles", ["mesostructure.glsl"], MESO_BODY, meso_twin,
         lambda: meso_inputs("tiny"), (2e-5, 2e-5), MESO_SETUP),
    xfail(Twin("mesostructure frame, degenerate map", ["mesostructure.glsl"], MESO_BODY, meso_twin,
               lambda: meso_inputs("degenerate"), (2e-5, 2e-5), MESO_SETUP),
          "finding: a degenerate map (dP/du = 0, dP/dv = 0, or parallel tangents): texspace gives s_n = 0 "
          "(normal_scale) and curvature 0, surface_frame s_n = (1e-12 (a + c)^2)^(1/4) and curvatures up to "
          "6.6e4 texture units; world_normal is NaN for 6 of 300 elements (the parallel tangents) and elsewhere up "
          "to 2.0 from world_normals (opposite normals)"),
    # texels stored as half floats (gl.albedo_texture): 2^-12 = 2.4e-4 for values < 1, twice for the blend of
    # rounded texels and float32 weights (measured 2.2e-4)
    Twin("albedo sample", ["albedo.glsl"], "out0 = vec4(albedo_map(uv.xy), 0.0);", albedo_twin, albedo_inputs,
         (5e-4, 0.0), albedo_setup),
    # magnitudes whose squares leave float32 (|v| < 1e-19 or > 1.8e19): safe_normalize scales by the largest
    # component first (before: the zero vector there, where the twin gives a unit one)
    Twin("safe_normalize, extreme magnitudes", ["shading.glsl"], "out0 = vec4(safe_normalize(v.xyz), 0.0);",
         safe_normalize_twin, lambda: safe_normalize_inputs(extreme=True), (5e-7, 0.0)),
]


def measure(ctx, row: Twin):
    """(worst |glsl - twin| / (atol + rtol |twin|), worst |glsl - twin|) over every compared component."""
    inputs = {k: np.asarray(v, np.float64) for k, v in row.inputs().items()}
    setup = row.setup(ctx) if row.setup else {}
    try:
        want = row.twin({k: f32(v.reshape(len(v), -1)) for k, v in inputs.items()})
        got = evaluate(ctx, row.includes, row.body, inputs, len(want), uniforms=setup.get("uniforms", {}),
                       textures=setup.get("textures", {}), defines=setup.get("defines", ()),
                       declarations=setup.get("declarations", ""))
    finally:
        gl.release(*setup.get("owned", ()))
    atol, rtol = row.tol
    worst, diff = 0.0, 0.0
    for g, w in zip(got, want):
        w = np.asarray(w, np.float64).reshape(len(g), -1)
        g = g[:, : w.shape[1]].astype(np.float64)
        d = np.abs(g - w)
        d = np.where(np.isnan(g) & np.isnan(w), 0.0, np.where(np.isnan(d), np.inf, d))
        worst = max(worst, float((d / (atol + rtol * np.abs(np.nan_to_num(w)))).max()))
        diff = max(diff, float(d.max()))
    return worst, diff


@pytest.mark.parametrize("row", [pytest.param(r, id=r.name) if isinstance(r, Twin) else r for r in TABLE])
def test_glsl_include_matches_its_numpy_twin(ctx, row):
    worst, diff = measure(ctx, row)
    print(f"{row.name}: max |glsl - twin| {diff:.3g}, {worst:.3g} of the tolerance {row.tol}")
    assert worst <= 1.0, f"{row.name}: max |glsl - twin| {diff:.3g} is {worst:.3g} x the tolerance {row.tol}"

