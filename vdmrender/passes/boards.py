"""What both billboard renderers share (Vichitvejpaisal2005): the unit box each billboard is drawn as, the
shading offsets and the coarse mesh's push back (§3.4), the colour maps' texture (§3.1), the coarse mesh's
draws, and the raster matrix with its far plane at infinity. The thesis's march is
techniques/billboards.py, the exact hierarchical trace techniques/billboards_hier.py."""
from __future__ import annotations

import moderngl
import numpy as np

from .. import gl
from .raster import MeshInputs

NORMAL_OFFSET_TEXELS = 0.7   # shadow lookups move this far along the normal, in shadow-map texels (as impostors) ...
BOARD_TEXELS = 1.0           # ... plus this many of the billboard's map texels: less gives acne where billboards
                             # overlap (the sweep is in docs/tuning.md)
COARSE_BEHIND = 0.05         # the coarse mesh is depth-tested as if this far (x radius) behind where it is, so that
                             # it fills holes rather than poking through the billboards (its vertices lie off the
                             # surface; the sweep is in docs/tuning.md)

# The unit cube [0, 1]^3 as 12 triangles, counter-clockwise seen from outside.
CORNERS = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float32)
CUBE = CORNERS[np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])].reshape(-1, 3)


def coarse_draws(ctx, mesh, anchor) -> tuple[dict, MeshInputs]:
    """The coarse mesh (Vichitvejpaisal2005 §3.4) uploaded once, anchor-relative, with the asset's colours
    where it carries them (raster.MeshInputs), and drawn by mesh.vert two ways: {"depth": (program, vao) writing depth only
    (depth.frag), "shaded": (program, vao) (mesh.frag)}; and its inputs (the shaded pass binds them)."""
    inputs = MeshInputs(ctx, mesh, anchor)
    draws = {}
    for kind, frag, defines in (("depth", "depth.frag", ()), ("shaded", "mesh.frag", inputs.defines)):
        prog = gl.program(ctx, "mesh.vert", frag, defines)
        draws[kind] = (prog, gl.vertex_array(ctx, prog, inputs.attributes, inputs.index, subset=kind == "depth"))
    return draws, inputs




def albedo_maps(ctx, bordered):
    """The billboards' colour maps (Vichitvejpaisal2005 §3.1; vdmbake.kernels.billboard_maps.albedo_texels, bordered like
    their normal and depth maps) as one RGB16F texture array, linear filtering, one layer per billboard;
    None where the bake stored none (an asset without colours: the material's albedo)."""
    if not bordered or any(m.albedo is None for m in bordered):
        return None
    data = np.stack([np.asarray(m.albedo, np.float16) for m in bordered])
    tex = ctx.texture_array((data.shape[2], data.shape[1], len(bordered)), 3, data.tobytes(), dtype="f2")
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = False
    return tex


def infinite_far(projection: np.ndarray) -> np.ndarray:
    """A perspective projection with its far plane at infinity: same x, y, w and near plane."""
    p = projection.copy()
    n = p[2, 3] / (p[2, 2] - 1.0)        # from (f + n) / (n - f) and 2 f n / (n - f)
    p[2, 2], p[2, 3] = -1.0, -2.0 * n
    return p
