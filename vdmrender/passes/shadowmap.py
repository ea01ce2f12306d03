"""A shadow map along the light direction, shared by every rasterised or ray-cast technique."""
from __future__ import annotations

import moderngl
import numpy as np

from ..common.camera import Camera
from ..gpu import gl


def ortho(half: float, near: float, far: float) -> np.ndarray:
    return np.array([[1 / half, 0, 0, 0], [0, 1 / half, 0, 0],
                     [0, 0, -2 / (far - near), -(far + near) / (far - near)], [0, 0, 0, 1]])


def translation(t) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = t
    return m


class ShadowMap:
    """Orthographic depth map of the object seen along -L, fitted to its bounding sphere.
    Coordinates are anchor-relative (the sphere's centre is the origin); one nearest-texel
    comparison per lookup (hard shadows, like the reference's single shadow ray)."""

    def __init__(self, ctx, size: int, light_dir, radius: float):
        self.ctx = ctx
        self.texture = ctx.depth_texture((size, size))
        self.texture.compare_func = "<="
        self.texture.repeat_x = self.texture.repeat_y = False
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.fbo = ctx.framebuffer(depth_attachment=self.texture)
        r = radius * 1.01
        cam = Camera(np.asarray(light_dir, float) * 2 * r, np.zeros(3), np.array([0.0, 0.0, 1.0]),
                     90.0, size, size, r, 3 * r)
        self.view_proj = ortho(r, r, 3 * r) @ cam.view()
        self.texel = 2 * r / size   # world size of one texel

    def begin(self, clear: bool = True) -> None:
        """Start the light's pass: the map cleared (unless not `clear`), depth-tested, no face culled."""
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE)
        self.fbo.use()
        self.ctx.viewport = (0, 0, *self.texture.size)
        if clear:
            self.fbo.clear(depth=1.0)

    def bind(self, prog, normal_offset: float = 0.0) -> None:
        gl.bind_textures(prog, u_shadow_map=self.texture)
        gl.set_uniforms(prog, u_light_mvp=self.view_proj, u_normal_offset=normal_offset)

    def release(self) -> None:
        gl.release(self.fbo, self.texture)


class ShadowView(ShadowMap):
    """One object's view of a scene-wide shadow map (vdmrender.views.composite): the scene's texture, in
    coordinates relative to the object's anchor (`offset`: anchor minus the map's centre). Its light pass
    draws into the map without clearing it (the composite frame clears it once, before every object's
    pass), so every object casts shadows on every other; the map belongs to the composite, not to it."""

    def __init__(self, shared: ShadowMap, offset):
        self.ctx, self.texture, self.fbo, self.texel = shared.ctx, shared.texture, shared.fbo, shared.texel
        self.view_proj = shared.view_proj @ translation(offset)

    def begin(self, clear: bool = False) -> None:
        super().begin(clear=False)

    def release(self) -> None:
        """The composite releases the shared map."""
