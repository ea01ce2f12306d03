"""The GL side of the hierarchical height-field tracer (shaders/include/heightfield_trace.glsl): upload a
vdmbake.common.pyramid.Pyramid as the RGBA32F mip chain the include reads, and set the include's uniforms."""
from __future__ import annotations

import moderngl

from vdmbake.common import pyramid

from ..gpu import gl


def pyramid_texture(ctx, p: pyramid.Pyramid):
    """The texture u_hf: pyramid.texture_levels uploaded level by level (texelFetch only: nearest filtering)."""
    levels = pyramid.texture_levels(p)
    h, w = levels[0].shape[:2]
    tex = ctx.texture((w, h), 4, levels[0].tobytes(), dtype="f4")
    tex.build_mipmaps(0, len(levels) - 1)          # allocates the chain; every level is then overwritten
    for L, a in enumerate(levels[1:], start=1):
        tex.write(a.tobytes(), level=L)
    tex.filter = (moderngl.NEAREST_MIPMAP_NEAREST, moderngl.NEAREST)
    tex.repeat_x = tex.repeat_y = False
    return tex


def uniforms(p: pyramid.Pyramid) -> dict:
    """u_hf_cells (x, y) and u_hf_top for a program that includes heightfield_trace.glsl."""
    ny, nx = p.cells
    return {"u_hf_cells": (nx, ny), "u_hf_top": p.top}


def bind(prog, tex, p: pyramid.Pyramid) -> None:
    gl.bind_textures(prog, u_hf=tex)
    gl.set_uniforms(prog, **uniforms(p))
