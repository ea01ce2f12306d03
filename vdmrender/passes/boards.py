"""What both billboard renderers share (Vichitvejpaisal2005): the unit box each billboard is drawn as, the
shading offsets and the coarse mesh's push back (§3.4), the colour maps' texture (§3.1), the coarse mesh's
draws, and the raster matrix with its far plane at infinity. The thesis's march is
techniques/billboards.py, the exact hierarchical trace techniques/billboards_hier.py."""
from __future__ import annotations

import moderngl
import numpy as np

from ..gpu import gl
from .raster import MeshInputs
from .shadowmap import translation

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


def coarse_draws(ctx, mesh, centre, model=None, mipmaps: bool = False) -> tuple[dict, MeshInputs]:
    """The coarse mesh (Vichitvejpaisal2005 §3.4) uploaded once about the object's centre, with the asset's colours
    where it carries them (raster.MeshInputs), and drawn by mesh.vert two ways: {"depth": (program, vao) writing depth only
    (depth.frag), "shaded": (program, vao) (mesh.frag)}; and its inputs (the shaded pass binds them). model: the
    buffer of the copies' matrices (one per instance, INSTANCED, pushed per copy: `pushed`), or None for an object
    drawn once. mipmaps: its albedo map mip-mapped (the scene's render.mipmaps)."""
    inputs = MeshInputs(ctx, mesh, centre, mipmaps)
    placed = ("INSTANCED", "PUSHED") if model is not None else ()
    attributes = inputs.attributes + ([(model, "16f/i", "in_model")] if model is not None else [])
    draws = {}
    for kind, frag, defines in (("depth", "depth.frag", placed), ("shaded", "mesh.frag", inputs.defines + placed)):
        prog = gl.program(ctx, "mesh.vert", frag, defines)
        draws[kind] = (prog, gl.vertex_array(ctx, prog, attributes, inputs.index, subset=kind == "depth"))
    return draws, inputs


def pushed(view_proj, behind: float, *, eye=None, light=None, radius: float = 0.0, copies: bool = False) -> dict:
    """The coarse mesh's uniforms under view_proj, depth-tested as if `behind` farther from the eye (eye:
    anchor-relative; the same pixels, farther) or from the light (light: its direction) than it is (§3.4). Drawn
    once: a matrix folded into u_mvp, a scaling about the eye by behind at the object's distance (at least its
    radius) or a shift along the light. Copies: per vertex in mesh.vert (PUSHED), `behind` times each copy's scale
    along its own ray, since one matrix would push a copy near the eye less and a far one more."""
    if copies:
        away = (*eye, 1.0) if eye is not None else (*(-np.asarray(light, np.float64)), 0.0)
        return {"u_mvp": view_proj, "u_away": tuple(float(x) for x in away), "u_behind": behind}
    if eye is not None:
        k = 1.0 + behind / max(float(np.linalg.norm(eye)), radius)
        return {"u_mvp": view_proj @ (translation(eye) @ np.diag([k, k, k, 1.0]) @ translation(-eye))}
    return {"u_mvp": view_proj @ translation(-np.asarray(light, np.float64) * behind)}


def albedo_maps(ctx, bordered, boards=None):
    """The billboards' colour maps (Vichitvejpaisal2005 §3.1; vdmbake.kernels.billboard_maps.albedo_texels, bordered like
    their normal and depth maps) as one RGB16F texture array, linear filtering, one layer per billboard;
    None where the bake stored none (an asset without colours: the material's albedo). boards (their alpha maps),
    given under the scene's render.mipmaps: the colours weighted by coverage with their mip chain (covered_colours)."""
    if not bordered or any(m.albedo is None for m in bordered):
        return None
    data = np.stack([np.asarray(m.albedo, np.float32) for m in bordered])
    if boards is not None:
        return covered_colours(ctx, data, np.stack([np.pad(np.asarray(b.alpha) > 0.5, 1) for b in boards]))
    tex = ctx.texture_array((data.shape[2], data.shape[1], len(bordered)), 3, data.astype(np.float16).tobytes(),
                            dtype="f2")
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = False
    return tex


FILL = 1.0 / 256   # covered_colours: the weight of a filled empty texel against a covered one's 1


def covered_colours(ctx, colour: np.ndarray, covered: np.ndarray, max_level: int = 1000):
    """Colour maps of what a view or billboard covers, mip-mapped where a level must average the covered texels
    only (the scene's render.mipmaps): RGBA16F of (colour x coverage, coverage), a texture array for (layers, h, w)
    and a texture for (h, w). GL's chain averages both, so rgb / a (board_albedo.glsl, octahedral.glsl under
    MIPMAPS) is the mean colour of the covered texels of the footprint at every level; a chain of the colours
    themselves would mix in the empty texels (0 past the bake's few rings of fill) and darken every silhouette
    as the level grows. The bake's fill (empty texels near covered ones, which hits up to a texel past the
    coverage read) weighs FILL: nothing beside a covered texel, its colour where the footprint covers nothing.
    max_level: the last level built (the octahedral atlas's tiles share one texture)."""
    filled = np.asarray(colour).max(-1) > 0
    w = np.where(covered, np.float32(1), np.where(filled, np.float32(FILL), np.float32(0)))[..., None]
    data = np.ascontiguousarray(np.concatenate([colour * w, w], -1), np.float16)
    if data.ndim == 4:
        tex = ctx.texture_array((data.shape[2], data.shape[1], data.shape[0]), 4, data.tobytes(), dtype="f2")
    else:
        tex = ctx.texture((data.shape[1], data.shape[0]), 4, data.tobytes(), dtype="f2")
    tex.build_mipmaps(0, max_level)
    tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = False
    return tex


def infinite_far(projection: np.ndarray) -> np.ndarray:
    """A perspective projection with its far plane at infinity: same x, y, w and near plane."""
    p = projection.copy()
    n = p[2, 3] / (p[2, 2] - 1.0)        # from (f + n) / (n - f) and 2 f n / (n - f)
    p[2, 2], p[2, 3] = -1.0, -2.0 * n
    return p
