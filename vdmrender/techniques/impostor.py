"""Renderer of `impostor`: spheres and capped cylinders ray cast per pixel on screen-aligned quads
(Sigg et al. 2006; de Poel & Bresser 2009). Knob `shading`: direct; deferred (G-buffer of normal
and mu, then one shading pass); outlines (deferred plus Sobel silhouettes and creases).
Shadows come from a shadow map of the same ray-cast quadrics, drawn from the light.
Instances (issue 23): every copy of the object's quadrics in one instanced draw per pass and kind (Copies,
shaders/include/quadric_copies.glsl), the shadow map spanning them all."""
from __future__ import annotations

import moderngl
import numpy as np

from vdmbake.bundle import parts
from vdmbake.common import instances as placing

from ..gpu import gl
from ..passes.raster import Passes
from ..passes.shadowmap import ShadowMap, translation

NORMAL_OFFSET_TEXELS = 0.7   # shadow lookups move this far along the normal, in shadow-map texels: less gives
                             # acne, more detaches shadows (docs/tuning.md)

# What each pass variant (its #define) compiles away of the shared vertex layout: the shadow map's
# depth pass reads no colour.
DROPS = {"depth": ("in_rgb",), "direct": (), "gbuffer": ()}


class Copies:
    """The copies of an instanced quadrics object on the GPU (shaders/include/quadric_copies.glsl): each copy's
    similarity in a storage buffer (64 bytes a copy), beside the bake's quadric rows, which the renderer uploads
    once and binds as storage buffers too. The rows are relative to the object's centre and the matrices map them
    to the GPU space about the copies (`anchor`, `radius`: vdmbake.common.instances.enclosing), as every instanced
    renderer does. Storage buffers, not per-instance attributes: instance i = copy * N + k needs both i / N and
    i mod N, and an attribute's divisor steps with one of them only."""

    BINDINGS = {"models": 0, "sphere": 1, "cylinder": 2}   # quadric_copies.glsl's

    def __init__(self, ctx, q, world):
        self.centre, radius = q.bounding_sphere()
        self.anchor, self.radius = placing.enclosing(world, self.centre, radius)
        self.models = ctx.buffer(reserve=len(world) * 64)
        self.place(world)

    def place(self, world) -> None:
        """Draw these copies (world matrices, at most as many as built with) from now on."""
        self.models.write(placing.model_columns(world, self.centre, self.anchor))
        self.count = len(world)

    def bind(self, prog, kind: str, rows, quadrics: int) -> None:
        """Bind the matrices and one kind's rows (a buffer of `quadrics` rows) for a draw of `prog`."""
        self.models.bind_to_storage_buffer(self.BINDINGS["models"])
        rows.bind_to_storage_buffer(self.BINDINGS[kind])
        gl.set_uniforms(prog, u_quadrics=quadrics)

    def release(self) -> None:
        self.models.release()


class Impostors(Passes):
    def __init__(self, ctx, q, light, material, shadow_size: int, shading: str, silhouette: float, crease: float,
                 instances=None):
        """q: vdmbake.kernels.quadrics.QuadricSet; instances: (N, 4, 4) world matrices of the object's copies
        (vdmbake.common.instances), all drawn by one instanced draw per pass and kind (INSTANCED)."""
        self.ctx, self.light, self.material, self.shading = ctx, light, material, shading
        self.silhouette, self.crease = (silhouette, crease) if shading == "outlines" else (0.0, 0.0)
        centre, radius = q.bounding_sphere()
        self.anchor, self.copies, instanced = centre, None, ()
        if instances is not None:
            self.copies, instanced = Copies(ctx, q, instances), ("INSTANCED",)
            self.anchor, radius = self.copies.anchor, self.copies.radius
        self.faces = None
        corners = gl.quad_corners(ctx)
        s, c = q.instances(centre)
        self.buffers = [corners]
        self.draws = []   # (pass, program, vao, kind, rows, quadrics)
        passes = {"depth": ()} | ({"direct": ("DIRECT",)} if shading == "direct" else {"gbuffer": ("GBUFFER",)})
        for kind, data, layout, names in (("sphere", s, "4f 3f/i", ("in_sphere", "in_rgb")),
                                          ("cylinder", c, "3f 3f 1f 3f/i", ("in_p0", "in_p1", "in_radius", "in_rgb"))):
            if not len(data):
                continue
            rows = ctx.buffer(np.ascontiguousarray(data, "f4").tobytes())
            self.buffers.append(rows)
            attributes = [(corners, "2f", "in_corner")] + ([] if instanced else [(rows, layout, *names)])
            for name, defines in passes.items():
                prog = gl.program(ctx, f"{kind}.vert", f"{kind}.frag", defines + instanced, DROPS[name])
                self.draws.append((name, prog, gl.vertex_array(ctx, prog, attributes), kind, rows, len(data)))
        self.shadow = ShadowMap(ctx, shadow_size, light.direction, radius)
        self.gbuffer = self.fullscreen = None
        if shading != "direct":
            self.deferred = gl.program(ctx, "fullscreen.vert", "deferred.frag")
            self.fullscreen = gl.vertex_array(ctx, self.deferred, [])

    def place(self, instances) -> None:
        """Draw these copies (world matrices, at most as many as built with) from now on."""
        self.copies.place(instances)

    def _draw(self, which: str, view_proj: np.ndarray, size, **uniforms) -> None:
        for name, prog, vao, kind, rows, n in self.draws:
            if name == which:
                gl.set_uniforms(prog, u_view_proj=view_proj, u_inv_view_proj=np.linalg.inv(view_proj),
                                u_viewport=tuple(float(x) for x in size), **uniforms)
                if which == "direct":
                    gl.set_shading(prog, self.light, self.material, albedo=False)   # colours per instance
                    self.shadow.bind(prog, normal_offset=NORMAL_OFFSET_TEXELS * self.shadow.texel)
                if self.copies:
                    self.copies.bind(prog, kind, rows, n)
                vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=n * (self.copies.count if self.copies else 1))

    def _gbuffer(self, size):
        if self.gbuffer is None or self.gbuffer[0].size != size:
            if self.gbuffer:
                for o in self.gbuffer:
                    o.release()
            normal_mu = self.ctx.texture(size, 4, dtype="f4")
            albedo = self.ctx.texture(size, 4, dtype="f2")   # 8 bits would show (docs/tuning.md)
            depth = self.ctx.depth_renderbuffer(size)
            self.gbuffer = (normal_mu, albedo, depth, self.ctx.framebuffer([normal_mu, albedo], depth))
        return self.gbuffer

    def passes(self, camera, target) -> list:
        """The frame's passes in order, as (name, callable): the shadow map, then the shaded quadrics
        (direct), or the G-buffer and its shading pass (deferred, outlines)."""
        ctx = self.ctx
        view_proj = camera.projection() @ camera.view() @ translation(self.anchor)
        eye = tuple(camera.eye - self.anchor)

        def shadow():
            self.shadow.begin()
            self._draw("depth", self.shadow.view_proj, self.shadow.texture.size)

        def direct():
            target.begin()
            self._draw("direct", view_proj, target.size, u_eye=eye)

        def gbuffer():
            _, _, _, fbo = self._gbuffer(target.size)
            fbo.use()
            ctx.viewport = (0, 0, *target.size)
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            self._draw("gbuffer", view_proj, target.size)

        def shade():
            # Depth-tested with the depth of the G-buffer's hits (deferred.frag writes gl_FragDepth), so the
            # shaded quadrics meet whatever else the target holds (a composite frame) as the direct pass does.
            normal_mu, albedo, _, _ = self.gbuffer
            target.begin()
            p = self.deferred
            gl.set_shading(p, self.light, self.material, albedo=False)   # albedo from the G-buffer
            self.shadow.bind(p, normal_offset=NORMAL_OFFSET_TEXELS * self.shadow.texel)
            gl.bind_textures(p, u_normal_mu=normal_mu, u_albedo_cov=albedo)
            gl.set_uniforms(p, u_eye=eye, u_view_proj=view_proj,
                            u_inv_view_proj=np.linalg.inv(view_proj), u_viewport=tuple(float(x) for x in target.size),
                            u_near_far=(camera.near, camera.far), u_silhouette=self.silhouette, u_crease=self.crease)
            self.fullscreen.render(moderngl.TRIANGLES, vertices=3)

        if self.shading == "direct":
            return [("shadow", shadow), ("frame", direct)]
        return [("shadow", shadow), ("gbuffer", gbuffer), ("shade", shade)]

    def release(self) -> None:
        gl.release(*(vao for _, _, vao, *_ in self.draws), *self.buffers, self.shadow, *(self.gbuffer or ()),
                   self.fullscreen, self.copies)



def build(ctx, src, shading):
    o = src.options
    return Impostors(ctx, src.bundle.read(src.entry["quadrics"], parts.QUADRICS), src.scene.light, src.obj.material,
                     src.shadow_map, shading, o.silhouette, o.crease, src.instances)
