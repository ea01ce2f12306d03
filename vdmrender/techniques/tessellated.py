"""Renderer of `tessellated`: the quadrics as instanced triangle meshes, the impostors' peer.
Knob `level`: spheres are icospheres subdivided `level` times (20 * 4^level faces), cylinders
prisms with 4 * 2^level sides and flat caps. Same shading and shadow map as `mesh`."""
from __future__ import annotations

import numpy as np

from vdmbake.common import geometry
from vdmbake.bundle import parts

from ..passes.raster import RasterPasses


class Tessellated(RasterPasses):
    UNIFORM_ALBEDO = False   # each quadric's colour comes with its instance (in_rgb)

    def __init__(self, ctx, q, light, material, shadow_size: int, level: int):
        anchor, radius = q.bounding_sphere()
        super().__init__(ctx, light, material, anchor, radius, shadow_size)
        sphere = geometry.icosphere(level)
        prism = geometry.cylinder(1.0, 2.0, 4 * 2 ** level, 1, 1)
        self.faces = len(q.spheres) * len(sphere.faces) + len(q.cylinders) * len(prism.faces)
        s, c = q.instances(anchor)
        for mesh, data, layout, names, defines in (
                (sphere, s, "4f 3f/i", ("in_sphere", "in_rgb"), ("SPHERE",)),
                (prism, c, "3f 3f 1f 3f/i", ("in_p0", "in_p1", "in_radius", "in_rgb"), ())):
            if not len(data):
                continue
            vbo, nbo, ibo, inst = (ctx.buffer(np.ascontiguousarray(a, dt).tobytes()) for a, dt in
                                   ((mesh.vertices, "f4"), (mesh.normals, "f4"), (mesh.faces, "i4"), (data, "f4")))
            self.add("instanced.vert", defines, [vbo, nbo, ibo, inst],
                     [(vbo, "3f", "in_pos"), (nbo, "3f", "in_normal"), (inst, layout, *names)], ibo, len(data))



def build(ctx, src, level):
    return Tessellated(ctx, src.bundle.read(src.entry["quadrics"], parts.QUADRICS), src.scene.light,
                       src.obj.material, src.shadow_map, level)
