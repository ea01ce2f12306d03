"""Technique `mesh`: the full mesh rasterised with the shared shading and a shadow map."""
from __future__ import annotations

import moderngl
import numpy as np

from .. import gl
from .shadowmap import ShadowMap, translation


class RasterPasses:
    """Triangle meshes drawn in two passes per frame: the shadow map (depth.frag, with polygon
    offset), then the shaded frame (mesh.frag). Subclasses fill `draws` with
    (fragment stage, program, vertex array, instances) for both stages."""

    POLYGON_OFFSET = (2.0, 2.0)   # slope-scaled and constant depth bias of the shadow-map pass

    def __init__(self, ctx, light, material, anchor, radius: float, shadow_size: int):
        self.ctx, self.light, self.material, self.anchor = ctx, light, material, anchor
        self.shadow = ShadowMap(ctx, shadow_size, light.direction, radius)
        self.buffers, self.draws = [], []

    def add(self, vertex: str, defines: tuple, buffers: list, attributes: list, depth_attributes: list,
            index, instances: int = 1) -> None:
        """One draw in both passes; the depth pass reads only `depth_attributes`."""
        self.buffers += buffers
        for frag, attrs in (("mesh.frag", attributes), ("depth.frag", depth_attributes)):
            prog = gl.program(self.ctx, vertex, frag, defines)
            self.draws.append((frag, prog, self.ctx.vertex_array(prog, attrs, index), instances))

    def render(self, camera, target) -> None:
        ctx = self.ctx
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        self.shadow.begin()
        ctx.polygon_offset = self.POLYGON_OFFSET
        for frag, prog, vao, n in self.draws:
            if frag == "depth.frag":
                gl.set_uniforms(prog, u_mvp=self.shadow.view_proj)
                vao.render(instances=n)
        ctx.polygon_offset = (0.0, 0.0)
        target.begin()
        mvp = camera.projection() @ camera.view() @ translation(self.anchor)
        for frag, prog, vao, n in self.draws:
            if frag == "mesh.frag":
                gl.set_shading(prog, self.light, self.material)
                gl.set_uniforms(prog, u_mvp=mvp, u_eye=tuple(camera.eye - self.anchor))
                self.shadow.bind(prog)
                vao.render(instances=n)

    def release(self) -> None:
        for _, _, vao, _ in self.draws:
            vao.release()
        for o in (*self.buffers, self.shadow):
            o.release()


class RasterMesh(RasterPasses):
    """One triangle mesh with per-vertex normals and the material's albedo."""

    def __init__(self, ctx, mesh, light, material, shadow_size: int):
        anchor, radius = mesh.bounding_sphere()
        super().__init__(ctx, light, material, anchor, radius, shadow_size)
        self.faces = len(mesh.faces)
        vbo, nbo, ibo = (ctx.buffer(np.ascontiguousarray(a, dtype=dt).tobytes()) for a, dt in
                         ((mesh.vertices - anchor, "f4"), (mesh.normals, "f4"), (mesh.faces, "i4")))
        self.add("mesh.vert", (), [vbo, nbo, ibo], [(vbo, "3f", "in_pos"), (nbo, "3f", "in_normal")],
                 [(vbo, "3f", "in_pos")], ibo)


def variants(obj, entry, bundle, scene, options):
    """One variant: the full mesh."""
    def build(ctx):
        return RasterMesh(ctx, bundle.mesh(entry["mesh"]), scene.light, obj.material, scene.render.shadow_map)
    return [(None, build)]
