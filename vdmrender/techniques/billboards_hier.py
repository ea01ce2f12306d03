"""Enhanced billboards by the hierarchical march: the render side of the `hier` method.

The thesis's billboards (Vichitvejpaisal2005 §3.3; techniques/billboards.py) rasterise each
billboard's box and ray-march its depth map per fragment: a pixel under n boxes runs n marches of a step
per texel, shades n hits and keeps the nearest by the depth test, which writing gl_FragDepth keeps from
rejecting anything early on llvmpipe. Here a frame is:
  1. the shadow map: the shadow mesh (the coarse mesh) rasterised, pushed away from the light by
     COARSE_BEHIND so that it does not shadow the billboard surface it approximates; without a shadow
     mesh, the billboards traced into it by pass 4 from the light's camera (docs/impostors.md
     has the cost and the error of both);
  2. with hole filling (Vichitvejpaisal2005 §3.4), the coarse mesh's depth, pushed back as in pass 5: no ray needs to go
     past it, since what lies behind would lose the depth test against the coarse mesh anyway;
  3. the occupancy pre-pass (billboard_occupancy.vert/.frag): per billboard, the boxes of its occupied
     pyramid cells at OCCUPANCY_LEVEL rasterised into its own tile of one float texture, keeping per pixel
     the ray parameter where the ray enters the first of them: nothing of that billboard lies before;
  4. one screen triangle scissored to the boxes' screen rectangle (billboard_hier.frag): per pixel, the ray
     through the billboards it meets in 3, each from its entry to its box's exit, to the depth of 2 and to
     the nearest hit so far, traced exactly and two-sided through the billboard's min/max pyramid (include
     heightfield_trace.glsl, pyramid baked by vdmbake/kernels/billboard_maps.py); the nearest hit shaded once
     (from behind if it was met from below), its exact depth written;
  5. with hole filling, the coarse mesh shaded and depth-tested as if COARSE_BEHIND farther than it is
     (as techniques/billboards.py), so that it fills only the pixels no billboard hit; drawn after the
     billboards, its hidden fragments fail the early depth test unshaded.
Instances (issue 23): every copy in one instanced draw per pass. Pass 4 draws a quad over each copy's
bounding sphere (bounding_quad.vert, INSTANCED) instead of the screen triangle, and its fragments take the
ray into the copy's frame (copy.glsl), where the billboards' arrays hold; the coarse and shadow meshes are
drawn instanced. Pass 3 is left out: its tiles are one per billboard (a copy's would be one per billboard
and copy), so each ray starts at the boxes it meets; the coarse depth of pass 2, over every copy, still
bounds it.
"""
from __future__ import annotations

import moderngl
import numpy as np

from vdmbake.common import instances as copies
from vdmbake.common import pyramid
from vdmbake.errors import InputError

from ..gpu import gl
from ..passes.boards import (
    BOARD_TEXELS, COARSE_BEHIND, CORNERS, CUBE, NORMAL_OFFSET_TEXELS, albedo_maps, coarse_draws, infinite_far,
    pushed)
from ..passes.raster import Passes, RasterPasses
from ..passes.shadowmap import ShadowMap, translation

OCCUPANCY_LEVEL = 4   # pass 3 draws the boxes of the non-empty pyramid cells of this level (16^2 texels)
MAX_TEXTURE = 16384   # pass 3's tiles share one texture of at most this side
LEVELS = 16           # pyramid levels the shader's origin table holds (maps up to 32768 texels)


class HierBillboards(Passes):
    def __init__(self, ctx, boards, bordered, light, material, shadow_size: int, coarse=None, bounds=None,
                 shadow_mesh=None, instances=None, mipmaps: bool = False):
        """boards: vdmbake.bundle.parts.Billboard (their boxes: origin, axes, size); bordered: their
        vdmbake.bundle.parts.BorderedMaps with pyramids; coarse: an optional TriMesh that fills holes (Vichitvejpaisal2005 §3.4);
        shadow_mesh: the TriMesh that casts the shadows (None: the billboards do); bounds: (centre, radius)
        of the model; instances: (N, 4, 4) world matrices of the object's copies (vdmbake.common.instances),
        None: drawn once; mipmaps: the colour maps and the coarse mesh's albedo map mip-mapped (render.mipmaps)."""
        boards, bordered = list(boards), list(bordered)
        if not boards and coarse is None:
            raise InputError("billboards: nothing to draw (no billboard and no coarse mesh).")
        if len(bordered) != len(boards) or any(m.pyramid is None for m in bordered):
            raise InputError("billboards: the hierarchical march needs every billboard's pyramid (bake a hier variant).")
        if len({m.maps.shape for m in bordered}) > 1:
            raise InputError(f"billboards: the maps must all be of one size; got {sorted({m.maps.shape for m in bordered})}.")
        if boards and bordered[0].pyramid.top >= LEVELS:
            raise InputError(f"billboards: maps of {bordered[0].maps.shape[0] - 2} texels have more pyramid levels "
                             f"than the {LEVELS} the renderer holds.")
        self.ctx, self.light, self.material = ctx, light, material
        self.faces = len(coarse.faces) if coarse is not None else 0
        self.centre, self.radius = np.asarray(bounds[0], np.float64), float(bounds[1])   # the data is about the centre
        self.anchor = self.centre
        self.behind = COARSE_BEHIND * self.radius
        self.objects, self.count, self.draws = [], len(boards), {}
        self.model = self.placed = None     # the copies' matrices (place) and how many are drawn
        reach = self.radius
        if instances is not None:   # the GPU space about the copies (instances.enclosing)
            self.anchor, reach = copies.enclosing(instances, self.centre, self.radius)
            self.model = ctx.buffer(reserve=len(instances) * 64)
            self.corners_quad = gl.quad_corners(ctx)
            self.objects += [self.model, self.corners_quad]
            self.place(instances)
        self.shadow = ShadowMap(ctx, shadow_size, light.direction, reach)
        self.depth = self.occupancy = None        # pass 2's and pass 3's targets, made at the first frame's size
        self.albedo_maps = self.coarse = None
        uploaded = {}                             # a mesh filling holes and casting shadows is uploaded once
        for mesh in (coarse, shadow_mesh):
            if mesh is not None and id(mesh) not in uploaded:
                uploaded[id(mesh)] = coarse_draws(ctx, mesh, self.centre, self.model, mipmaps)
                self.objects.append(uploaded[id(mesh)][1])
        if coarse is not None:
            draws, self.coarse = uploaded[id(coarse)]
            self.draws["coarse depth"] = draws["depth"]
            self.draws["coarse"] = draws["shaded"]
        if shadow_mesh is not None:
            self.draws["shadow mesh"] = uploaded[id(shadow_mesh)][0]["depth"]
        if not boards:
            return
        res = bordered[0].maps.shape[0] - 2
        origin = np.array([np.asarray(b.origin, np.float64) - self.centre for b in boards])
        edges = np.array([np.asarray(b.axes, np.float64) * np.asarray(b.size, np.float64)[:, None] for b in boards])
        self.corners = origin[:, None] + CORNERS[None] @ edges          # (boards, 8, 3) box corners
        self.centres = origin + 0.5 * edges.sum(1)
        # anchor-relative world -> the unit box (u, v, depth): rows edge / |edge|^2, origin moved to 0
        self.to_box = np.zeros((len(boards), 4, 4))
        self.to_box[:, :3, :3] = edges / np.einsum("bij,bij->bi", edges, edges)[..., None]
        self.to_box[:, :3, 3] = -np.einsum("bij,bj->bi", self.to_box[:, :3, :3], origin)
        self.to_box[:, 3, 3] = 1.0
        self.texel = np.array([max(b.size[0], b.size[1]) / res for b in boards])
        if instances is None:
            self._occupancy_boxes(bordered, origin, edges, res)
        # the pyramids (pyramid.texture_atlas, one layer each) and the bordered maps
        atlases = [pyramid.texture_atlas(m.pyramid) for m in bordered]
        self.level_origin = np.zeros((LEVELS, 2), np.int32)
        self.level_origin[:len(atlases[0][1])] = atlases[0][1]
        h, w = atlases[0][0].shape[:2]
        self.pyramids = ctx.texture_array((w, h, len(boards)), 4, np.stack([a for a, _ in atlases]).tobytes(), dtype="f4")
        self.pyramids.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.maps = ctx.texture_array((res + 2, res + 2, len(boards)), 4, np.stack([m.maps for m in bordered]).tobytes(),
                                      dtype="f4")
        self.maps.filter = (moderngl.LINEAR, moderngl.LINEAR)
        for t in (self.pyramids, self.maps):
            t.repeat_x = t.repeat_y = False
        self.albedo_maps = albedo_maps(ctx, bordered, boards if mipmaps else None)
        self.objects += [self.pyramids, self.maps, self.albedo_maps]
        self.hf = {"u_hf_cells": (res + 1, res + 1), "u_hf_top": bordered[0].pyramid.top}
        # the copies' quads hold every hit: the surface is within a texel or two of the model's sphere
        self.quad_radius = self.radius + 2.0 * float(self.texel.max())
        defines = (f"BOARDS {len(boards)}", f"MAX_ITER {4 * (res + 1)}", f"HF_START_LEVEL {OCCUPANCY_LEVEL}")
        defines += ("INSTANCED",) if instances is not None else ()
        stages = {"billboards": defines + (("OCCUPANCY",) if instances is None else ())
                  + (("COARSE_DEPTH",) if coarse is not None else ())
                  + (("ALBEDO_MAPS",) if self.albedo_maps is not None else ())
                  + (("MIPMAPS",) if self.albedo_maps is not None and mipmaps else ())}
        if shadow_mesh is None:
            stages["shadow billboards"] = defines + ("SHADOW",)
        for stage, d in stages.items():
            # the light's pass reads neither the maps (no shading) nor an occupancy pre-pass
            lack = ("u_maps", "u_occupancy", "u_board_texels") if "SHADOW" in d else ()
            if instances is None:
                prog = gl.program(ctx, "fullscreen.vert", "billboard_hier.frag", d, lack)
                self.draws[stage] = (prog, gl.vertex_array(ctx, prog, []))
            else:
                prog = gl.program(ctx, "bounding_quad.vert", "billboard_hier.frag", d, lack)
                self.draws[stage] = (prog, gl.vertex_array(ctx, prog, [(self.corners_quad, "2f", "in_corner"),
                                                                        (self.model, "16f/i", "in_model")]))

    def _occupancy_boxes(self, bordered, origin, edges, res: int) -> None:
        """Pass 3's geometry: per billboard the boxes of its occupied cells (pyramid.occupied_boxes), a
        quarter texel and 1e-4 depths larger than the cells (rounding must not start a ray past a surface)."""
        tris, self.occ_ranges = [], []
        for m, o, e in zip(bordered, origin, edges):
            box = pyramid.occupied_boxes(m.pyramid, OCCUPANCY_LEVEL).astype(np.float64)
            box[:, 0] -= (0.25, 0.25, 1e-4)
            box[:, 1] += (0.25, 0.25, 1e-4)
            box[..., :2] = (box[..., :2] - 0.5) / res                   # sample coordinates -> unit box
            box = np.clip(box, 0.0, 1.0)
            unit = box[:, None, 0] + CUBE[None].astype(np.float64) * (box[:, None, 1] - box[:, None, 0])
            self.occ_ranges.append((sum(len(t) for t in tris), 36 * len(box)))
            tris.append((o + unit.reshape(-1, 3) @ e).astype(np.float32))
        occ_vbo = self.ctx.buffer(np.concatenate(tris).tobytes())
        self.objects.append(occ_vbo)
        self.occ_prog = gl.program(self.ctx, "billboard_occupancy.vert", "billboard_occupancy.frag")
        self.occ_vao = gl.vertex_array(self.ctx, self.occ_prog, [(occ_vbo, "3f", "in_pos")])

    def place(self, instances) -> None:
        """Draw these copies (world matrices, at most as many as built with) from now on."""
        self.model.write(copies.model_columns(instances, self.centre, self.anchor))
        self.placed = len(instances)

    # ----------------------------------------------------------------------------------------- passes

    def passes(self, camera, target) -> list:
        """The frame's passes in order, as (name, callable): render runs them, the profile times each."""
        eye = camera.eye - self.anchor
        to_anchor = camera.view() @ translation(self.anchor)
        view_proj = camera.projection() @ to_anchor
        push = pushed(view_proj, self.behind, eye=eye, radius=self.radius, copies=self.model is not None)
        out = [("shadow", self._shadow)]
        if "coarse depth" in self.draws:
            out.append(("coarse depth", lambda: self._coarse_depth(push, target.size)))
        if self.count and self.model is not None:
            out.append(("billboards", lambda: self._frame(view_proj, eye, target, None)))
        elif self.count:
            state = {}
            out.append(("occupancy", lambda: state.update(occupancy=self._occupancy(
                camera, target.size, infinite_far(camera.projection()) @ to_anchor, eye))))
            out.append(("billboards", lambda: self._frame(view_proj, eye, target, state["occupancy"])))
        else:
            out.append(("clear", target.begin))
        if "coarse" in self.draws:
            out.append(("coarse", lambda: self._coarse(push, eye)))
        return out

    def _shadow(self) -> None:
        ctx = self.ctx
        self.shadow.begin()
        if "shadow mesh" in self.draws:
            prog, vao = self.draws["shadow mesh"]
            gl.set_uniforms(prog, **pushed(self.shadow.view_proj, self.behind, light=self.light.direction,
                                           copies=self.model is not None))
            ctx.polygon_offset = RasterPasses.POLYGON_OFFSET
            vao.render(instances=self.placed or 1)
            ctx.polygon_offset = (0.0, 0.0)
        elif self.count:   # the light's orthographic camera, nearest billboards to the light first
            self._boards("shadow billboards", self.shadow.view_proj, np.asarray(self.light.direction) * 4 * self.radius,
                         self.shadow.texture.size, None, None)

    def _coarse_depth(self, push: dict, size) -> None:
        ctx = self.ctx
        if self.depth is None or self.depth.size != size:
            if self.depth is not None:
                self.depth_fbo.release()
                self.depth.release()
            self.depth = ctx.depth_texture(size)
            self.depth.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.depth.compare_func = ""      # read as a value (u_coarse_depth), not compared
            self.depth_fbo = ctx.framebuffer(depth_attachment=self.depth)
        self.depth_fbo.use()
        ctx.viewport = (0, 0, *size)
        self.depth_fbo.clear(depth=1.0)
        prog, vao = self.draws["coarse depth"]
        gl.set_uniforms(prog, **push)
        vao.render(instances=self.placed or 1)

    def _occupancy(self, camera, size, raster, eye) -> tuple[np.ndarray, np.ndarray]:
        """Pass 3: per billboard, in its own tile of one R32F texture, the ray parameter t at which each
        pixel's ray enters its first occupied box (MIN blending; 1e30 where it enters none). Returns the
        tiles' origins and, per billboard, 1 where it has no tile: its box reaches the near plane (clipped
        boxes would lose entries; its rays start at its box instead) or the texture holds no more tiles."""
        ctx, (w, h) = self.ctx, size
        cols = max(1, min(self.count, MAX_TEXTURE // w))
        rows = max(1, min(-(-self.count // cols), MAX_TEXTURE // h))
        if self.occupancy is None or self.occupancy.size != (cols * w, rows * h):
            if self.occupancy is not None:
                self.occ_fbo.release()
                self.occupancy.release()
            self.occupancy = ctx.texture((cols * w, rows * h), 1, dtype="f4")
            self.occupancy.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.occ_fbo = ctx.framebuffer([self.occupancy])
        tiles = np.array([((k % cols) * w, (k // cols) * h) for k in range(self.count)], np.int32)
        fwd = -camera.basis()[2]                                                # the view direction
        depth = (self.corners - eye) @ fwd                                      # view depth of every box corner
        off = ((depth.min(1) <= camera.near * 1.001) | (np.arange(self.count) >= cols * rows)).astype(np.int32)
        self.occ_fbo.use()
        self.occ_fbo.clear(1e30, 0.0, 0.0, 0.0)
        # t = (view depth - near) / (far - near): 0 on the near plane, 1 on the far one (billboard_hier.frag)
        gl.set_uniforms(self.occ_prog, u_view_proj=raster, u_p0=tuple(eye + camera.near * fwd),
                        u_axis=tuple(fwd / (camera.far - camera.near)))
        ctx.disable(moderngl.DEPTH_TEST)
        ctx.enable(moderngl.BLEND | moderngl.CULL_FACE)
        ctx.blend_equation = moderngl.MIN
        for k, (first, n) in enumerate(self.occ_ranges):
            if not off[k]:
                ctx.viewport = (int(tiles[k, 0]), int(tiles[k, 1]), w, h)
                self.occ_vao.render(first=first, vertices=n)
        ctx.blend_equation = moderngl.FUNC_ADD
        ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        ctx.enable(moderngl.DEPTH_TEST)
        return tiles, off

    def _frame(self, view_proj, eye, target, occupancy) -> None:
        target.begin()
        prog, _ = self.draws["billboards"]
        if self.depth is not None and "u_coarse_depth" in prog:
            gl.bind_textures(prog, u_coarse_depth=self.depth)
        gl.set_shading(prog, self.light, self.material, self.albedo_maps is None)
        if self.albedo_maps is not None:
            gl.bind_textures(prog, u_albedo_maps=self.albedo_maps)
        self.shadow.bind(prog, normal_offset=NORMAL_OFFSET_TEXELS * self.shadow.texel)
        rect = self._rect(view_proj, target.size) if self.model is None else None
        self._boards("billboards", view_proj, eye, target.size, rect, occupancy,
                     u_eye=tuple(eye))

    def _coarse(self, push: dict, eye) -> None:
        prog, vao = self.draws["coarse"]
        gl.set_shading(prog, self.light, self.material, self.coarse.uniform_albedo)
        self.coarse.bind(prog)
        gl.set_uniforms(prog, **push, u_eye=tuple(eye))
        # known to within `behind` of the surface, it looks its shadow up that much further out
        self.shadow.bind(prog, normal_offset=NORMAL_OFFSET_TEXELS * self.shadow.texel + self.behind)
        vao.render(instances=self.placed or 1)

    def _boards(self, stage: str, view_proj, viewer, viewport, rect, occupancy, **uniforms) -> None:
        """Pass 4 (or its light version): the billboards in order of the distance of their box centres from
        `viewer` (the shader orders each pixel's billboards by cost, ties in this order), the screen
        triangle scissored to rect, or with copies a quad over each; occupancy: pass 3's (tiles, off)."""
        prog, vao = self.draws[stage]
        order = np.argsort(np.linalg.norm(self.centres - viewer, axis=1), kind="stable")
        gl.set_uniforms(prog, u_view_proj=view_proj,
                        u_inv_view_proj=np.linalg.inv(view_proj), u_viewport=tuple(float(x) for x in viewport),
                        u_board_texels=BOARD_TEXELS, **self.hf, **uniforms)
        arrays = {"u_level_origin": self.level_origin, "u_to_box": self.to_box[order].transpose(0, 2, 1),
                  "u_layer": order, "u_texel": self.texel[order]}
        if occupancy is not None:
            arrays.update(u_tile=occupancy[0][order], u_occ_off=occupancy[1][order])
            gl.bind_textures(prog, u_occupancy=self.occupancy)
        gl.set_uniforms(prog, **arrays)
        gl.bind_textures(prog, u_pyramids=self.pyramids, u_maps=self.maps)
        if self.model is not None:   # a quad over every copy's sphere (bounding_quad.vert)
            gl.set_uniforms(prog, u_radius=self.quad_radius)
            vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=self.placed)
            return
        self.ctx.scissor = rect
        vao.render(moderngl.TRIANGLES, vertices=3)
        self.ctx.scissor = None

    def _rect(self, view_proj, size):
        """The screen rectangle (x, y, w, h) holding every box corner; None (the whole viewport) when a
        corner lies behind the eye."""
        c = np.concatenate([self.corners.reshape(-1, 3), np.ones((self.corners.size // 3, 1))], 1) @ view_proj.T
        if (c[:, 3] <= 1e-9).any():
            return None
        xy = (c[:, :2] / c[:, 3:] * 0.5 + 0.5) * np.asarray(size)
        lo = np.clip(np.floor(xy.min(0)), 0, size).astype(int)
        hi = np.clip(np.ceil(xy.max(0)), 0, size).astype(int)
        return (int(lo[0]), int(lo[1]), int(max(hi[0] - lo[0], 0)), int(max(hi[1] - lo[1], 0)))

    def release(self) -> None:
        vaos = {id(vao): vao for _, vao in self.draws.values()}        # shared draws released once
        gl.release(*vaos.values(), getattr(self, "depth_fbo", None), self.depth, getattr(self, "occ_fbo", None),
                   self.occupancy, getattr(self, "occ_vao", None), *self.objects, self.shadow)
