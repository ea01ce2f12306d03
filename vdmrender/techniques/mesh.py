"""Technique `mesh`: the full mesh rasterised with the shared shading and a shadow map."""
from __future__ import annotations

import numpy as np

import moderngl

from .. import gl
from .shadowmap import ShadowMap, translation


class RasterMesh:
    """A triangle mesh drawn in two passes per frame: the shadow map, then the shaded frame."""

    POLYGON_OFFSET = (2.0, 2.0)   # slope-scaled and constant depth bias of the shadow-map pass

    def __init__(self, ctx, mesh, light, material, shadow_size: int):
        self.ctx, self.light, self.material = ctx, light, material
        self.anchor, radius = mesh.bounding_sphere()
        self.faces = len(mesh.faces)
        self.prog = gl.program(ctx, "mesh.vert", "mesh.frag")
        self.depth_prog = gl.program(ctx, "mesh.vert", "depth.frag")
        self.buffers = [ctx.buffer(np.ascontiguousarray(a, dtype=dt).tobytes()) for a, dt in
                        ((mesh.vertices - self.anchor, "f4"), (mesh.normals, "f4"), (mesh.faces, "i4"))]
        vbo, nbo, ibo = self.buffers
        self.vao = ctx.vertex_array(self.prog, [(vbo, "3f", "in_pos"), (nbo, "3f", "in_normal")], ibo)
        self.depth_vao = ctx.vertex_array(self.depth_prog, [(vbo, "3f", "in_pos")], ibo)
        self.shadow = ShadowMap(ctx, shadow_size, light.direction, radius)

    def render(self, camera, target) -> None:
        ctx = self.ctx
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        self.shadow.begin()
        ctx.polygon_offset = self.POLYGON_OFFSET
        gl.set_uniforms(self.depth_prog, u_mvp=self.shadow.view_proj)
        self.depth_vao.render()
        ctx.polygon_offset = (0.0, 0.0)

        target.begin()
        p = self.prog
        gl.set_shading(p, self.light, self.material)
        gl.set_uniforms(p, u_mvp=camera.projection() @ camera.view() @ translation(self.anchor),
                        u_eye=tuple(camera.eye - self.anchor))
        self.shadow.bind(p)
        self.vao.render()

    def release(self) -> None:
        for o in (self.vao, self.depth_vao, self.shadow, *self.buffers):
            o.release()


def variants(obj, entry, bundle, scene, options):
    """One variant: the full mesh."""
    def build(ctx):
        return RasterMesh(ctx, bundle.mesh(entry["mesh"]), scene.light, obj.material, scene.render.shadow_map)
    return [(None, None, build)]
