"""Renderer of `vdm`: view-dependent displacement mapping per pixel (Wang et al. 2003, sec. 3.2-3.3,
shaders/vdm.frag) with the first k eigenfunctions of the baked SVD."""
from __future__ import annotations

import numpy as np

from vdmbake import parts

from .mesostructure import MesostructurePass, texture

# VDM's shadow test (sec. 3.2 step 3): P' is lit unless d_L < h / cos(theta_L) - eps, with eps this many
# mesostructure depths plus this many texels: the tables' angular sampling and the flat shadow test put the
# light's hit that far off (the sweep that chose them is in docs/tuning.md).
SHADOW_EPS_DEPTH, SHADOW_EPS_TEXELS = 0.2, 2.0


def _groups(a: np.ndarray, axis: int) -> np.ndarray:
    """Pad the eigenfunction axis to a multiple of 4 and split it into (groups, 4) at that axis."""
    k = a.shape[axis]
    pad = [(0, 0)] * a.ndim
    pad[axis] = (0, -k % 4)
    a = np.pad(a, pad)
    return a.reshape(a.shape[:axis] + (-1, 4) + a.shape[axis + 1:])


class VDMPass(MesostructurePass):
    """The base mesh drawn by shaders/vdm.frag: W as a mip-mapped texture array (layer group * n_phi + phi),
    E_vdm and E_mvm as clamped, linearly filtered tables."""

    def __init__(self, ctx, src, k):
        m, part = src.obj.mesostructure, src.part
        t = src.bundle.read(part["tables"], parts.VDM)
        k = part["k"] if k == "all" else min(k, part["k"])
        W = _groups(t.W, 3).transpose(3, 0, 1, 2, 4)                      # (groups, phi, y, x, 4)
        E_vdm = _groups(t.E_vdm, 0)                                       # (groups, 4, c, theta)
        E_mvm = _groups(t.E_mvm, 0)                                       # (groups, 4, c)
        cs = part["curvatures"]
        n_c = len(cs)
        axis = (cs[0], (n_c - 1) / (cs[-1] - cs[0]) if n_c > 1 else 0.0, n_c)
        super().__init__(ctx, src, "vdm.frag", curvature=True, u_k=int(k), u_groups=W.shape[0], u_n_phi=m.phi,
                         u_curv_axis=tuple(float(x) for x in axis),
                         u_shadow_eps=SHADOW_EPS_DEPTH * m.depth + SHADOW_EPS_TEXELS / m.size)
        g = W.shape[0]
        self.textures["u_W"] = texture(ctx.texture_array(
            (m.size, m.size, g * m.phi), 4, np.ascontiguousarray(W, "f4").tobytes(), dtype="f4"), True, True)
        self.textures["u_E_vdm"] = texture(ctx.texture_array(
            (m.theta, n_c, g), 4, np.ascontiguousarray(E_vdm.transpose(0, 2, 3, 1), "f4").tobytes(), dtype="f4"),
            False, False)
        self.textures["u_E_mvm"] = texture(ctx.texture(
            (n_c, g), 4, np.ascontiguousarray(E_mvm.transpose(0, 2, 1), "f4").tobytes(), dtype="f4"), False, False)


def build(ctx, src, k):
    return VDMPass(ctx, src, k)
