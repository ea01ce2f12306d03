"""Renderer of `tessellated`: the quadrics as instanced triangle meshes, the impostors' peer.
Knob `level`: spheres are icospheres subdivided `level` times (20 * 4^level faces), cylinders
prisms with 4 * 2^level sides and flat caps. Same shading and shadow map as `mesh`.
Instances (issue 23): every copy of every quadric in one instanced draw per pass and kind, as the impostors
(impostor.Copies, shaders/include/quadric_copies.glsl)."""
from __future__ import annotations

import numpy as np

from vdmbake.common import geometry
from vdmbake.bundle import parts

from .impostor import Copies
from ..passes.raster import RasterPasses


class Tessellated(RasterPasses):
    UNIFORM_ALBEDO = False   # each quadric's colour comes with its instance (in_rgb)

    def __init__(self, ctx, q, light, material, shadow_size: int, level: int, instances=None):
        """q: vdmbake.kernels.quadrics.QuadricSet; instances: (N, 4, 4) world matrices of the object's copies
        (vdmbake.common.instances), all drawn by one instanced draw per pass and kind (INSTANCED)."""
        centre, radius = q.bounding_sphere()
        anchor, self.copies, instanced = centre, None, ()
        if instances is not None:
            self.copies, instanced = Copies(ctx, q, instances), ("INSTANCED",)
            anchor, radius = self.copies.anchor, self.copies.radius
        super().__init__(ctx, light, material, anchor, radius, shadow_size)
        sphere = geometry.icosphere(level)
        prism = geometry.cylinder(1.0, 2.0, 4 * 2 ** level, 1, 1)
        self.faces = len(q.spheres) * len(sphere.faces) + len(q.cylinders) * len(prism.faces)
        s, c = q.instances(centre)
        self.rows = {}   # each draw's program: (kind, its rows buffer, quadrics), what the copies' draws bind
        for kind, mesh, data, layout, names, defines in (
                ("sphere", sphere, s, "4f 3f/i", ("in_sphere", "in_rgb"), ("SPHERE",)),
                ("cylinder", prism, c, "3f 3f 1f 3f/i", ("in_p0", "in_p1", "in_radius", "in_rgb"), ())):
            if not len(data):
                continue
            vbo, nbo, ibo, rows = (ctx.buffer(np.ascontiguousarray(a, dt).tobytes()) for a, dt in
                                   ((mesh.vertices, "f4"), (mesh.normals, "f4"), (mesh.faces, "i4"), (data, "f4")))
            attributes = [(vbo, "3f", "in_pos"), (nbo, "3f", "in_normal")] + (
                [] if instanced else [(rows, layout, *names)])
            self.add("instanced.vert", defines + instanced, [vbo, nbo, ibo, rows], attributes, ibo, len(data))
            self.rows.update({prog: (kind, rows, len(data)) for _, prog, _, _ in self.draws[-2:]})
        if instances is not None:   # the instance count of every draw is set by place
            self.place(instances)

    def place(self, instances) -> None:
        """Draw these copies (world matrices, at most as many as built with) from now on."""
        self.copies.place(instances)
        self.draws = [(stage, prog, vao, self.rows[prog][2] * len(instances)) for stage, prog, vao, _ in self.draws]

    def passes(self, camera, target) -> list:
        """RasterPasses' passes; with copies, each pass first binds every draw's quadric rows and matrices."""
        out = super().passes(camera, target)
        if self.copies is None:
            return out

        def bound(run):
            def go():
                for prog, (kind, rows, quadrics) in self.rows.items():
                    self.copies.bind(prog, kind, rows, quadrics)
                run()
            return go

        return [(name, bound(run)) for name, run in out]

    def release(self) -> None:
        super().release()
        if self.copies:
            self.copies.release()


def build(ctx, src, level):
    return Tessellated(ctx, src.bundle.read(src.entry["quadrics"], parts.QUADRICS), src.scene.light,
                       src.obj.material, src.shadow_map, level, src.instances)
