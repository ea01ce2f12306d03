"""Techniques that draw an object's mesostructure (VDM, Wang et al. 2003, and its peers):
`vdm` (knob k: eigenfunctions reconstructed), `pom` (knob steps), `bump`, all per pixel over the
base mesh with its interpolated surface frame; and `displaced` (knob level), the base mesh
subdivided and displaced, rasterised. All share the shading model and the base mesh's shadow map
for shadows cast across the object; vdm and pom add the mesostructure's own self-shadows."""
from __future__ import annotations

import moderngl
import numpy as np

from vdmbake import displace, vdm, vdm_storage

from .. import gl
from .mesh import RasterMesh, RasterPasses

# VDM shadow test (sec. 3.2): P' is shadowed if d_L < h / cos(theta_L) - eps, eps = this x depth + this
# texels. Torus, bricks 64^2, 32 x 16 views, 256^2, vdm@all: eps 0 -> 5.89 dLuv, 0.25 texel -> 3.12,
# 0.1 depth + 1 texel -> 2.05, 0.2 depth + 2 texels -> 2.05 (vdm@8 2.20), 0.5 depth + 1 texel -> 2.05. With the
# paper's 128^2 x 32 x 8 on the same torus (512^2) 0.1 + 1 gives vdm@8 2.56 against 2.50, and a light 0.6 deg
# above the horizon 1.32 against 1.13; but 2 texels of a 16^2 field are long: cliffs on a plane 0.95 (0.82).
SHADOW_EPS_DEPTH, SHADOW_EPS_TEXELS = 0.2, 2.0
# Refined VDM: the height field is searched within this fraction of the depth (along the ray's descent)
# on either side of the lookup's hit: wide enough for the tables' interpolation error, narrow enough
# that a few samples still resolve a brick's edge (docs/vdm-render-notes.md has the sweep).
REFINE_WINDOW = 0.25


def heights(bundle, meso_entry) -> np.ndarray:
    return bundle.exr(meso_entry["height"])["height"]["h"].astype(np.float64)


def displaced_mesh(bundle, obj, entry, levels: int | None = None):
    """The base mesh subdivided `levels` times (half-texel edges if None: the reference) and displaced."""
    m = obj.mesostructure
    base = bundle.mesh(entry["mesh"])
    if levels is None:
        levels = displace.reference_levels(base, m.size, m.tiling)
    return displace.displaced(base, heights(bundle, entry["mesostructure"]), m.depth, m.tiling, levels)


def _texture(tex, repeat: bool, mipmaps: bool):
    tex.repeat_x = tex.repeat_y = repeat
    if mipmaps:
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    else:
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    return tex


def _vec4s(a: np.ndarray):
    """A (n, 4) array as a GLSL vec4[n] uniform's value (moderngl takes a one-element array as its element)."""
    rows = [tuple(map(float, r)) for r in a]
    return rows if len(rows) > 1 else rows[0]


def _groups(a: np.ndarray, axis: int) -> np.ndarray:
    """Pad the eigenfunction axis to a multiple of 4 and split it into (groups, 4) at that axis."""
    k = a.shape[axis]
    pad = [(0, 0)] * a.ndim
    pad[axis] = (0, -k % 4)
    a = np.pad(a, pad)
    return a.reshape(a.shape[:axis] + (-1, 4) + a.shape[axis + 1:])


class MesostructurePass(RasterPasses):
    """The base mesh with its frame, drawn by one mesostructure fragment stage."""

    NORMAL_OFFSET_TEXELS = 1.5   # the lookups are at the base surface, which the shadow map also holds

    def __init__(self, ctx, obj, entry, bundle, scene, frag: str, defines: tuple = (), **uniforms):
        mesh = bundle.mesh(entry["mesh"])
        anchor, radius = mesh.bounding_sphere()
        super().__init__(ctx, scene.light, obj.material, anchor, radius, scene.render.shadow_map)
        self.faces = len(mesh.faces)
        m = obj.mesostructure
        f = mesh.frame
        cols = [mesh.vertices - anchor, mesh.normals, mesh.uvs, f.dpdu, f.dpdv, np.stack([f.k1, f.k2], 1), f.d1]
        vbo = ctx.buffer(np.ascontiguousarray(np.concatenate(cols, 1), "f4").tobytes())
        ibo = ctx.buffer(np.ascontiguousarray(mesh.faces, "i4").tobytes())
        self.add("mesostructure.vert", defines, [vbo, ibo],
                 [(vbo, "3f 3f 2f 3f 3f 2f 3f", "in_pos", "in_normal", "in_uv", "in_dpdu", "in_dpdv", "in_curv",
                   "in_d1")],
                 [(vbo, "3f 64x", "in_pos")], ibo, frag=frag, depth_vertex="mesh.vert",
                 optional=True)
        h = heights(bundle, entry["mesostructure"])
        n = vdm.height_normals(h, m.depth)
        self.textures = {
            "u_height": _texture(ctx.texture(h.shape[::-1], 1, h.astype("f4").tobytes(), dtype="f4"), True, True),
            "u_normals": _texture(ctx.texture(h.shape[::-1], 3, n.astype("f4").tobytes(), dtype="f4"), True, False)}
        self.uniforms = {"u_tiling": tuple(m.tiling), "u_depth": m.depth, **uniforms}

    def bind_frame(self, prog, camera) -> None:
        for unit, (name, tex) in enumerate(self.textures.items(), start=1):
            tex.use(unit)
            gl.set_uniforms(prog, **{name: unit})
        gl.set_uniforms(prog, **self.uniforms)

    def release(self) -> None:
        super().release()
        for tex in self.textures.values():
            tex.release()


def vdm_weights(bundle, meso_entry, m) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stored weights W (phi, y, x, k) as written (float32, float16 or uint8 codes) and the
    per-eigenfunction (scale, offset) that turn them into weights (vdmbake/vdm_storage.py)."""
    parts = bundle.exr(meso_entry["vdm"])
    k = meso_entry["k"]
    W = np.stack([parts["W"][f"W.{i:03d}"] for i in range(k)], -1).reshape(m.phi, m.size, m.size, k)
    if "W_dequant" in parts:
        return W.astype(np.uint8), parts["W_dequant"]["scale"][0], parts["W_dequant"]["offset"][0]
    return W, np.ones(k, np.float32), np.zeros(k, np.float32)


class VDMPass(MesostructurePass):
    """VDM with the first k eigenfunctions of the baked SVD (sec. 3.3); refine > 0 finishes the view
    ray's hit and the self-shadow on the height field (shaders/vdm.frag). original: the first
    implementation's lookup, float weights mip-mapped (for before/after measurements); as_float:
    the weights dequantised to float32 on upload (to measure what their storage costs)."""

    def __init__(self, ctx, obj, entry, bundle, scene, k, refine: int = 0, original: bool = False,
                 as_float: bool = False, defines: tuple = ()):
        meso = entry["mesostructure"]
        m = obj.mesostructure
        parts = bundle.exr(meso["vdm"])
        stored = meso["k"]
        k = stored if k == "all" else min(k, stored)
        W, scale, offset = vdm_weights(bundle, meso, m)
        E_vdm = np.stack([parts["E_vdm"][f"E.{i:03d}"] for i in range(stored)])
        E_mvm = np.stack([parts["E_mvm"][f"E.{i:03d}"][0] for i in range(stored)])
        if original or as_float:
            W = vdm_storage.dequantise(W, scale, offset)
            scale, offset = np.ones_like(scale), np.zeros_like(offset)
        if not original:                       # the first k only, so that E is 0 past k and k can be compiled in
            W, E_vdm, E_mvm, scale, offset = W[..., :k], E_vdm[:k], E_mvm[:k], scale[:k], offset[:k]
        dtype = {"uint8": "f1", "float16": "f2"}.get(W.dtype.name, "f4")     # f1: unsigned normalised bytes
        if dtype == "f1":
            scale = scale * 255                                          # the sampler returns code / 255
        W = _groups(W, 3).transpose(3, 0, 1, 2, 4)                        # (groups, phi, y, x, 4)
        E_vdm, E_mvm = _groups(E_vdm, 0), _groups(E_mvm, 0)               # (groups, 4, c, theta), (groups, 4, c)
        scale, offset = _groups(scale, 0), _groups(offset, 0)             # (groups, 4)
        cs = meso["curvatures"]
        n_c = len(cs)
        axis = (cs[0], (n_c - 1) / (cs[-1] - cs[0]) if n_c > 1 else 0.0, n_c)
        g = W.shape[0]
        half_bin = 0.25 * np.pi / m.theta                                 # theta samples are bin centres
        defines = (f"K {k}", f"REFINE {refine}", *(("ORIGINAL_LOOKUP",) if original else ()), *defines)
        super().__init__(ctx, obj, entry, bundle, scene, "vdm.frag", defines, u_k=int(k), u_groups=g, u_n_phi=m.phi,
                         u_curv_axis=tuple(float(x) for x in axis),
                         u_cos_range=(float(np.cos(0.5 * np.pi - half_bin)), float(np.cos(half_bin))),
                         u_shadow_eps=SHADOW_EPS_DEPTH * m.depth + SHADOW_EPS_TEXELS / m.size,
                         u_window=REFINE_WINDOW * m.depth,
                         u_W_scale=_vec4s(scale), u_W_offset=_vec4s(offset))
        data = np.ascontiguousarray(W if dtype != "f4" else W.astype(np.float32))
        self.textures["u_W"] = _texture(ctx.texture_array((m.size, m.size, g * m.phi), 4, data.tobytes(), dtype=dtype),
                                        True, original)
        self.textures["u_E_vdm"] = _texture(ctx.texture_array(
            (m.theta, n_c, g), 4, np.ascontiguousarray(E_vdm.transpose(0, 2, 3, 1), "f4").tobytes(), dtype="f4"),
            False, False)
        self.textures["u_E_mvm"] = _texture(ctx.texture(
            (n_c, g), 4, np.ascontiguousarray(E_mvm.transpose(0, 2, 1), "f4").tobytes(), dtype="f4"), False, False)


def vdm_variants(obj, entry, bundle, scene, options):
    """One variant per k and refine setting: vdm@K (the paper's algorithm) and vdm@KrR (refined, R samples)."""
    return [(k if r == 0 else f"{k}r{r}", lambda ctx, k=k, r=r: VDMPass(ctx, obj, entry, bundle, scene, k, r))
            for r in options["refine"] for k in options["k"]]


def pom_variants(obj, entry, bundle, scene, options):
    return [(s, lambda ctx, s=s: MesostructurePass(ctx, obj, entry, bundle, scene, "pom.frag", u_steps=s))
            for s in options["steps"]]


def bump_variants(obj, entry, bundle, scene, options):
    return [(None, lambda ctx: MesostructurePass(ctx, obj, entry, bundle, scene, "bump.frag"))]


def displaced_variants(obj, entry, bundle, scene, options):
    return [(level, lambda ctx, level=level: RasterMesh(ctx, displaced_mesh(bundle, obj, entry, level), scene.light,
                                                        obj.material, scene.render.shadow_map))
            for level in options["levels"]]
