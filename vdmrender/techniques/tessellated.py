"""Technique `tessellated`: the quadrics as instanced triangle meshes, the impostors' peer.
Knob `level`: spheres are icospheres subdivided `level` times (20 * 4^level faces), cylinders
prisms with 4 * 2^level sides and flat caps. Same shading and shadow map as `mesh`."""
from __future__ import annotations

import moderngl
import numpy as np

from vdmbake import primitives

from .. import gl
from .mesh import RasterMesh
from .shadowmap import ShadowMap, translation


class Tessellated:
    def __init__(self, ctx, q, light, material, shadow_size: int, level: int):
        self.ctx, self.light, self.material = ctx, light, material
        self.anchor, radius = q.bounding_sphere()
        sphere = primitives.icosphere(level)
        prism = primitives.cylinder(1.0, 2.0, 4 * 2 ** level, 1, 1)
        self.faces = len(q.spheres) * len(sphere.faces) + len(q.cylinders) * len(prism.faces)
        s = np.concatenate([q.spheres[:, :3] - self.anchor, q.spheres[:, 3:], q.sphere_rgb], 1)
        c = np.concatenate([q.cylinders[:, :3] - self.anchor, q.cylinders[:, 3:6] - self.anchor,
                            q.cylinders[:, 6:], q.cylinder_rgb], 1)
        self.buffers, self.draws = [], []
        for mesh, data, layout, names, defines in (
                (sphere, s, "4f 3f/i", ("in_sphere", "in_rgb"), ("SPHERE",)),
                (prism, c, "3f 3f 1f 3f/i", ("in_p0", "in_p1", "in_radius", "in_rgb"), ())):
            if not len(data):
                continue
            vbo, nbo, ibo, inst = (ctx.buffer(np.ascontiguousarray(a, dt).tobytes()) for a, dt in
                                   ((mesh.vertices, "f4"), (mesh.normals, "f4"), (mesh.faces, "i4"), (data, "f4")))
            self.buffers += [vbo, nbo, ibo, inst]
            for frag in ("mesh.frag", "depth.frag"):
                prog = gl.program(ctx, "instanced.vert", frag, defines)
                vao = ctx.vertex_array(prog, [(vbo, "3f", "in_pos"), (nbo, "3f", "in_normal"), (inst, layout, *names)],
                                       ibo, skip_errors=frag == "depth.frag")   # the depth pass reads no normal or colour
                self.draws.append((frag, prog, vao, len(data)))
        self.shadow = ShadowMap(ctx, shadow_size, light.direction, radius)

    def render(self, camera, target) -> None:
        ctx = self.ctx
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        self.shadow.begin()
        ctx.polygon_offset = RasterMesh.POLYGON_OFFSET
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


def variants(obj, entry, bundle, scene, options):
    def builder(level):
        return lambda ctx: Tessellated(ctx, bundle.quadrics(entry["quadrics"]), scene.light, obj.material,
                                       scene.render.shadow_map, level)
    return [("level", level, builder(level)) for level in options["levels"]]
