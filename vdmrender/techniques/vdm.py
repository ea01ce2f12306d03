"""Renderer of `vdm`: view-dependent displacement mapping per pixel (Wang2003 §3.2-3.3,
shaders/vdm.frag) with the first k eigenfunctions of the baked SVD, refined on the height field if asked."""
from __future__ import annotations

import numpy as np

from vdmbake.bundle import parts
from vdmbake.errors import InputError

from ..passes.mesostructure import MesostructurePass, texture

# VDM's shadow test (Wang2003 §3.2 step 3): P' is lit unless d_L < h / cos(theta_L) - eps, with eps this many
# mesostructure depths plus this many texels: the tables' angular sampling and the flat shadow test put the
# light's hit that far off (the sweep that chose them is in docs/tuning.md).
SHADOW_EPS_DEPTH, SHADOW_EPS_TEXELS = 0.2, 2.0
# Refined VDM: the height field is searched within this fraction of the depth (along the ray's descent)
# on either side of the lookup's hit: wide enough for the tables' interpolation error, narrow enough
# that a few samples still resolve a brick's edge (docs/mesostructure.md has the sweep).
REFINE_WINDOW = 0.25


def _groups(a: np.ndarray, axis: int) -> np.ndarray:
    """Pad the eigenfunction axis to a multiple of 4 and split it into (groups, 4) at that axis."""
    k = a.shape[axis]
    pad = [(0, 0)] * a.ndim
    pad[axis] = (0, -k % 4)
    a = np.pad(a, pad)
    return a.reshape(a.shape[:axis] + (-1, 4) + a.shape[axis + 1:])


def _vec4s(a: np.ndarray):
    """A (n, 4) array as a GLSL vec4[n] uniform's value (moderngl takes a one-element array as its element)."""
    rows = [tuple(map(float, r)) for r in a]
    return rows if len(rows) > 1 else rows[0]


class VDMPass(MesostructurePass):
    """The base mesh drawn by shaders/vdm.frag: W as a texture array (layer group * n_phi + phi) in its stored
    format (8-bit codes sampled as unsigned normalised bytes, then scale and offset per eigenfunction), the
    first k only with k compiled in; E_vdm and E_mvm as clamped, linearly filtered tables. refine > 0 finishes
    the view ray's hit and the self-shadow on the height field. original: the first implementation's lookup
    (float weights, mip-mapped, k as a uniform), kept to measure the gain; as_float: the weights dequantised
    on upload (to measure what their storage costs). Under the scene's render.mipmaps (MIPMAPS) W gets its mip
    chain, built on upload from the stored weights (a level's weights are the mean of the finer level's, which is
    the truncated SVD of the mean table: vdm.frag's vdm_lookup), so the bundle stores level 0 only."""

    def __init__(self, ctx, src, k, refine: int = 0, original: bool = False, as_float: bool = False):
        m, part = src.obj.mesostructure, src.part
        t = src.bundle.read(part["tables"], parts.VDM)
        n_c = len(part["curvatures"])
        if (t.W.shape[:3], t.W.shape[3], t.E_vdm.shape[1:]) != ((m.phi, m.size, m.size), part["k"], (n_c, m.theta)):
            raise InputError(f"{src.bundle.path / part['tables']}: VDM tables of shapes W {t.W.shape}, E_vdm "
                             f"{t.E_vdm.shape} do not fit the scene's mesostructure (phi {m.phi}, size {m.size}, "
                             f"theta {m.theta}), k {part['k']} and {n_c} curvatures; re-bake with vdmbake --force.")
        k = part["k"] if k == "all" else min(k, part["k"])
        W, E_vdm, E_mvm, scale, offset = t.W, t.E_vdm, t.E_mvm, t.scale, t.offset
        if original or as_float:
            W = (W.astype(np.float32) * scale + offset).astype(np.float32)
            scale, offset = np.ones_like(scale), np.zeros_like(offset)
        if not original:                       # the first k only, so that E is 0 past k and k can be compiled in
            W, E_vdm, E_mvm, scale, offset = W[..., :k], E_vdm[:k], E_mvm[:k], scale[:k], offset[:k]
        dtype = {"uint8": "f1", "float16": "f2"}.get(W.dtype.name, "f4")     # f1: unsigned normalised bytes
        if dtype == "f1":
            scale = scale * 255                                          # the sampler returns code / 255
        W = _groups(W, 3).transpose(3, 0, 1, 2, 4)                        # (groups, phi, y, x, 4)
        E_vdm, E_mvm = _groups(E_vdm, 0), _groups(E_mvm, 0)               # (groups, 4, c, theta), (groups, 4, c)
        scale, offset = _groups(scale, 0), _groups(offset, 0)             # (groups, 4)
        cs = part["curvatures"]
        n_c = len(cs)
        axis = (cs[0], (n_c - 1) / (cs[-1] - cs[0]) if n_c > 1 else 0.0, n_c)
        g = W.shape[0]
        half_bin = 0.25 * np.pi / m.theta                                 # theta samples are bin centres
        defines = (f"K {k}", f"REFINE {refine}", *(("ORIGINAL_LOOKUP",) if original else ()))
        # each variant of the stage sets only what it reads: k is compiled in (but in the original lookup),
        # the weights' scale and offset only for stored weights, the refinement window only when refining
        # the paper's shadow lookup only without refinement (the light's angle clamped to the sampled ones)
        variant = ({"u_k": int(k)} if original else {"u_W_scale": _vec4s(scale), "u_W_offset": _vec4s(offset)}) | (
            {"u_window": REFINE_WINDOW * m.depth} if refine else
            {"u_cos_range": (float(np.cos(0.5 * np.pi - half_bin)), float(np.cos(half_bin)))})
        super().__init__(ctx, src, "vdm.frag", curvature=True, defines=defines, u_groups=g, u_n_phi=m.phi,
                         u_curv_axis=tuple(float(x) for x in axis),
                         u_shadow_eps=SHADOW_EPS_DEPTH * m.depth + SHADOW_EPS_TEXELS / m.size, **variant)
        limit = ctx.info["GL_MAX_ARRAY_TEXTURE_LAYERS"]
        if g * m.phi > limit:   # the driver would leave the texture incomplete and draw garbage, silently
            raise InputError(f"object {src.obj.name!r}: vdm k = {k} stores {g} groups of 4 eigenfunctions x {m.phi} "
                             f"view azimuths = {g * m.phi} texture layers, over this GL device's limit of {limit}; "
                             "lower k (or phi) in the scene.")
        data = np.ascontiguousarray(W if dtype != "f4" else W.astype(np.float32))
        self.textures["u_W"] = texture(ctx.texture_array((m.size, m.size, g * m.phi), 4, data.tobytes(), dtype=dtype),
                                       True, original or src.mipmaps)
        self.textures["u_E_vdm"] = texture(ctx.texture_array(
            (m.theta, n_c, g), 4, np.ascontiguousarray(E_vdm.transpose(0, 2, 3, 1), "f4").tobytes(), dtype="f4"),
            False, False)
        self.textures["u_E_mvm"] = texture(ctx.texture(
            (n_c, g), 4, np.ascontiguousarray(E_mvm.transpose(0, 2, 1), "f4").tobytes(), dtype="f4"), False, False)


def build(ctx, src, variant):
    return VDMPass(ctx, src, variant.k, variant.refine)
