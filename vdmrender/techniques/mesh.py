"""Technique `mesh`: the full mesh rasterised with the shared shading and a shadow map."""
from __future__ import annotations

import numpy as np

from .. import gl
from ..camera import Camera


def ortho(half: float, near: float, far: float) -> np.ndarray:
    return np.array([[1 / half, 0, 0, 0], [0, 1 / half, 0, 0],
                     [0, 0, -2 / (far - near), -(far + near) / (far - near)], [0, 0, 0, 1]])


def translation(t) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = t
    return m


class RasterMesh:
    """A triangle mesh drawn in two passes per frame: the shadow map, then the shaded frame."""

    POLYGON_OFFSET = (2.0, 2.0)   # slope-scaled and constant depth bias of the shadow-map pass
    SHADOW_BIAS = 0.0             # extra depth bias at lookup (depth-map units)

    def __init__(self, ctx, mesh, light, material, shadow_size: int):
        self.ctx, self.light, self.material = ctx, light, material
        self.anchor, radius = mesh.bounding_sphere()
        self.faces = len(mesh.faces)
        self.prog = gl.program(ctx, "mesh.vert", "mesh.frag")
        self.depth_prog = gl.program(ctx, "depth.vert", "depth.frag")
        self.buffers = [ctx.buffer(np.ascontiguousarray(a, dtype=dt).tobytes()) for a, dt in
                        ((mesh.vertices - self.anchor, "f4"), (mesh.normals, "f4"), (mesh.faces, "i4"))]
        vbo, nbo, ibo = self.buffers
        self.vao = ctx.vertex_array(self.prog, [(vbo, "3f", "in_pos"), (nbo, "3f", "in_normal")], ibo)
        self.depth_vao = ctx.vertex_array(self.depth_prog, [(vbo, "3f", "in_pos")], ibo)
        self.shadow = ctx.depth_texture((shadow_size, shadow_size))
        self.shadow.compare_func = "<="
        self.shadow.repeat_x = self.shadow.repeat_y = False
        import moderngl
        self.shadow.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.shadow_fbo = ctx.framebuffer(depth_attachment=self.shadow)
        # The light's view: orthographic along -L, fitted to the bounding sphere (anchor at its centre).
        r = radius * 1.01
        light_cam = Camera(np.asarray(light.direction) * 2 * r, np.zeros(3), np.array([0.0, 0.0, 1.0]),
                           90.0, shadow_size, shadow_size, r, 3 * r)
        self.light_mvp = ortho(r, r, 3 * r) @ light_cam.view()

    def render(self, camera, target) -> None:
        ctx = self.ctx
        import moderngl
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        self.shadow_fbo.use()
        ctx.viewport = (0, 0, *self.shadow.size)
        self.shadow_fbo.clear(depth=1.0)
        ctx.polygon_offset = self.POLYGON_OFFSET
        self.depth_prog["u_mvp"].write(gl.mat(self.light_mvp))
        self.depth_vao.render()
        ctx.polygon_offset = (0.0, 0.0)

        target.begin()
        p = self.prog
        gl.set_shading(p, self.light, self.material)
        p["u_mvp"].write(gl.mat(camera.projection() @ camera.view() @ translation(self.anchor)))
        p["u_eye"].value = tuple(camera.eye - self.anchor)
        p["u_light_mvp"].write(gl.mat(self.light_mvp))
        p["u_shadow_bias"].value = self.SHADOW_BIAS
        p["u_shadow_map"].value = 0
        self.shadow.use(0)
        self.vao.render()

    def release(self) -> None:
        for o in (self.vao, self.depth_vao, self.shadow_fbo, self.shadow, *self.buffers):
            o.release()


def variants(obj, entry, bundle, scene, options):
    """One variant: the full mesh."""
    def build(ctx):
        return RasterMesh(ctx, bundle.mesh(entry["mesh"]), scene.light, obj.material, scene.render.shadow_map)
    return [(None, None, build)]
