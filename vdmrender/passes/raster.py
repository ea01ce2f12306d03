"""Rasterised triangle meshes with the shared shading and a shadow map: the passes of `mesh`, `coarse`,
`displaced`, `tessellated` and the mesostructure techniques."""
from __future__ import annotations

import moderngl
import numpy as np

from vdmbake.common import instances as copies

from ..gpu import gl
from .shadowmap import ShadowMap, translation


class Passes:
    """A renderer whose frame is a list of passes (`passes`: (name, callable) in order): render runs
    them; vdmrender.measuring.timing times each."""

    def passes(self, camera, target) -> list:
        raise NotImplementedError

    def render(self, camera, target) -> None:
        for _, run in self.passes(camera, target):
            run()


class RasterPasses(Passes):
    """Triangle meshes drawn in two passes per frame: the shadow map (depth.frag, with polygon
    offset), then the shaded frame (mesh.frag, or a subclass's fragment stage, whose extra
    uniforms and textures `bind_frame` sets). Subclasses fill `draws` through `add`."""

    POLYGON_OFFSET = (2.0, 2.0)   # slope-scaled and constant depth bias of the shadow-map pass
    NORMAL_OFFSET_TEXELS = 0.0    # shadow lookups move this far along the normal, in shadow-map texels
    cull_face = None              # faces the frame pass leaves out ("back" or "front"); the shadow pass draws all
    UNIFORM_ALBEDO = True         # the material's albedo as u_albedo (False: colours per instance)

    def __init__(self, ctx, light, material, anchor, radius: float, shadow_size: int):
        self.ctx, self.light, self.material, self.anchor = ctx, light, material, anchor
        self.shadow = ShadowMap(ctx, shadow_size, light.direction, radius)
        self.buffers, self.draws = [], []

    def add(self, vertex: str, defines: tuple, buffers: list, attributes: list, index, instances: int = 1,
            frag: str = "mesh.frag", depth_vertex: str | None = None, may_lack: tuple[str, ...] = ()) -> None:
        """One draw in both passes, from one vertex layout: the depth pass (through `depth_vertex` if
        given) reads the attributes its program has, the rest is padding. may_lack: attributes and
        uniforms the frame pass's fragment stage may compile away (one vertex layout serves several
        fragment stages; gl.program)."""
        self.buffers += buffers
        for stage, vert, fs, lack in (("frame", vertex, frag, may_lack), ("shadow", depth_vertex or vertex, "depth.frag", ())):
            prog = gl.program(self.ctx, vert, fs, defines, lack)
            vao = gl.vertex_array(self.ctx, prog, attributes, index, subset=stage == "shadow")
            self.draws.append((stage, prog, vao, instances))

    def bind_frame(self, prog, camera) -> None:
        """Extra uniforms and textures of the frame pass (none for plain meshes)."""

    def passes(self, camera, target) -> list:
        """The frame's passes in order, as (name, callable): render runs them, a profile times each."""
        ctx = self.ctx

        def shadow():
            self.shadow.begin()
            ctx.polygon_offset = self.POLYGON_OFFSET
            for stage, prog, vao, n in self.draws:
                if stage == "shadow":
                    gl.set_uniforms(prog, u_mvp=self.shadow.view_proj)
                    vao.render(instances=n)
            ctx.polygon_offset = (0.0, 0.0)

        def frame():
            target.begin()
            if self.cull_face:
                ctx.enable(moderngl.CULL_FACE)
                ctx.cull_face = self.cull_face
            mvp = camera.projection() @ camera.view() @ translation(self.anchor)
            for stage, prog, vao, n in self.draws:
                if stage == "frame":
                    gl.set_shading(prog, self.light, self.material, self.UNIFORM_ALBEDO)
                    gl.set_uniforms(prog, u_mvp=mvp, u_eye=tuple(camera.eye - self.anchor))
                    self.shadow.bind(prog, normal_offset=self.NORMAL_OFFSET_TEXELS * self.shadow.texel)
                    self.bind_frame(prog, camera)
                    vao.render(instances=n)
            ctx.disable(moderngl.CULL_FACE)
        return [("shadow", shadow), ("frame", frame)]

    def release(self) -> None:
        gl.release(*(vao for _, _, vao, _ in self.draws), *self.buffers, self.shadow)


class MeshInputs:
    """What mesh.vert reads of one triangle mesh, uploaded once: anchor-relative positions, normals and,
    where the asset has them, its colours per vertex (VERTEX_COLOR) and texture coordinates with its albedo
    map (ALBEDO_MAP, vdmbake.common.texture); the material's albedo (u_albedo) where it has neither. mipmaps: the
    albedo map mip-mapped (gl.albedo_texture; the scene's render.mipmaps)."""

    def __init__(self, ctx, mesh, anchor, mipmaps: bool = False):
        vbo, nbo, self.index = (ctx.buffer(np.ascontiguousarray(a, dtype=dt).tobytes()) for a, dt in
                                ((mesh.vertices - anchor, "f4"), (mesh.normals, "f4"), (mesh.faces, "i4")))
        self.buffers, self.defines = [vbo, nbo, self.index], ()
        self.attributes = [(vbo, "3f", "in_pos"), (nbo, "3f", "in_normal")]
        if mesh.colors is not None:
            cbo = ctx.buffer(np.ascontiguousarray(mesh.colors, dtype="f4").tobytes())
            self.buffers.append(cbo)
            self.attributes.append((cbo, "3f", "in_color"))
            self.defines += ("VERTEX_COLOR",)
        self.albedo_map = None
        if mesh.texture is not None:
            tbo = ctx.buffer(np.ascontiguousarray(mesh.uvs, dtype="f4").tobytes())
            self.buffers.append(tbo)
            self.attributes.append((tbo, "2f", "in_uv"))
            self.defines += ("ALBEDO_MAP",)
            self.albedo_map = gl.albedo_texture(ctx, mesh.texture, mipmaps)
        self.uniform_albedo = not self.defines   # u_albedo only where the asset has no colour of its own

    def bind(self, prog) -> None:
        """The albedo map of the shaded pass, if any."""
        if self.albedo_map is not None:
            gl.bind_textures(prog, u_albedo_map=self.albedo_map)

    def release(self) -> None:
        gl.release(*self.buffers, self.albedo_map)


class RasterMesh(RasterPasses):
    """One triangle mesh with per-vertex normals and the material's albedo, or the asset's own: colours per
    vertex and an albedo map read at its texture coordinates, where it has them (MeshInputs). instances: (N, 4, 4)
    world matrices of its copies (vdmbake.common.instances), drawn by one instanced draw per pass (INSTANCED), the
    shadow map covering them all. mipmaps: its albedo map mip-mapped (the scene's render.mipmaps)."""

    def __init__(self, ctx, mesh, light, material, shadow_size: int, instances=None, mipmaps: bool = False):
        self.centre, radius = mesh.bounding_sphere()   # the data is uploaded about the object's centre
        anchor, attributes, defines, buffers = self.centre, [], (), []
        self.model = None
        if instances is not None:   # the GPU space about the copies (instances.enclosing)
            anchor, radius = copies.enclosing(instances, self.centre, radius)
            self.model = ctx.buffer(reserve=len(instances) * 64)
            attributes, defines, buffers = [(self.model, "16f/i", "in_model")], ("INSTANCED",), [self.model]
        super().__init__(ctx, light, material, anchor, radius, shadow_size)
        self.faces = len(mesh.faces)
        self.inputs = MeshInputs(ctx, mesh, self.centre, mipmaps)
        self.UNIFORM_ALBEDO = self.inputs.uniform_albedo
        self.add("mesh.vert", self.inputs.defines + defines, buffers, self.inputs.attributes + attributes,
                 self.inputs.index)
        if instances is not None:   # the instance count of every draw is set by place
            self.place(instances)

    def place(self, instances) -> None:
        """Draw these copies (world matrices, at most as many as built with) from now on."""
        self.model.write(copies.model_columns(instances, self.centre, self.anchor))
        self.draws = [(stage, prog, vao, len(instances)) for stage, prog, vao, _ in self.draws]

    def bind_frame(self, prog, camera) -> None:
        self.inputs.bind(prog)

    def release(self) -> None:
        super().release()
        self.inputs.release()
