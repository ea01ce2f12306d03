"""Enhanced billboards, the render side (Vichitvejpaisal2005 §3.3, §3.4, §4.1).

Each billboard of the bake (vdmbake.kernels.billboards: origin, axes u v w, size, alpha, depth and normal
maps) is drawn as its bounding box (Vichitvejpaisal2005 §3.3 step 1), all of them once per copy of the object
by one instanced draw (issue 23: an instance per copy; an object drawn once is one copy). Only the box's back
faces are rasterised: they cover its screen footprint whether the eye is outside or inside the box, and
near-plane clipping removes only box parts whose whole ray segment lies before the near plane; the
raster matrix has its far plane at infinity, so no box face is lost behind the far plane. Per pixel,
the ray from the near plane to the far plane is clipped to the box (slab test in u, v, w) and marches
the depth map as a height field (shaders/include/billboard.glsl, Vichitvejpaisal2005 §3.3 step 2.2):
  "thesis"   100 fixed steps of sqrt(2)/100 in the unit depth-map box, a hit where |ray depth - map
             depth| < e (hit_range; 0.01 in Vichitvejpaisal2005 §4.1, 0.02 to fill holes in §3.4), texel coverage;
  "improved" a step per texel crossed by the ray's projection on the map, a hit where the ray passes
             behind the map, 5 bisections and a secant step, then coverage: any texel of the bilinear
             footprint covered (so neighbouring billboards overlap by up to a texel instead of leaving
             cracks; docs/tuning.md has the comparison with nearest-texel coverage).
A camera inside a box needs no special case: the ray starts on the near plane, like the reference's.
The hit is shaded with the shared model (normal map, shadow map) and writes its exact gl_FragDepth.

Texture layout: two texture arrays, one layer per billboard. RGBA32F normal (world, xyz) + depth (w),
(R+2)^2 with a one-texel border, linear filtering; the border and the empty texels near covered ones are
linearly extrapolated from them in the bake (vdmbake/kernels/billboard_maps.py), so filtering at a map's edge or
silhouette follows the surface's slope. R8 alpha, R^2, read per texel (texelFetch, textureGather). For an
asset with its own colours, a third: the colour maps (Vichitvejpaisal2005 §3.1), RGB16F linear albedo with the same border
(albedo_maps), read at the hit (Vichitvejpaisal2005 §3.3 step 2.3); otherwise the colour is the material's albedo.

Passes per frame: the shadow map, then the frame. The shadow map holds what the frame draws: the
billboards ray-marched with the same method from the light's orthographic camera (gl_FragDepth), plus
the coarse mesh when there is one. Each method's shadows thus carry its own errors and nothing of the
full mesh, which only the reference uses. Shadow lookups from a billboard hit move along the normal by
the shadow map's normal offset plus BOARD_TEXELS of the billboard's map texels (plus 2 e box depths for
"thesis", whose hits lie up to e off the surface in both passes).

Hole filling (Vichitvejpaisal2005 §3.4): a coarse mesh, if given, is drawn in both passes (mesh.vert, mesh.frag,
depth.frag) and depth-tested with the billboards, but as if COARSE_BEHIND farther from the eye (and from
the light) than it is: it fills the pixels where no billboard is hit (the thesis: "the coarse mesh fills
the pixels that are not rendered by the enhanced billboards") instead of poking through them.

Coordinates are anchor-relative (float64 on the CPU, float32 on the GPU), as in the other techniques.
The method `hier` (exact hierarchical traces, one screen pass) is techniques/billboards_hier.py.
"""
from __future__ import annotations

import moderngl
import numpy as np

from vdmbake.bundle import parts
from vdmbake.common import instances as copies
from vdmbake.errors import InputError

from .billboards_hier import HierBillboards
from ..gpu import gl
from ..passes.boards import (
    BOARD_TEXELS, COARSE_BEHIND, CORNERS, CUBE, NORMAL_OFFSET_TEXELS, albedo_maps, coarse_draws, infinite_far,
    pushed)
from ..passes.raster import Passes, RasterPasses
from ..passes.shadowmap import ShadowMap, translation

METHODS = ("thesis", "improved")


def surface_points(b) -> np.ndarray:
    """(covered texels, 3) world positions of a billboard's covered texel centres at their depth."""
    res = np.asarray(b.alpha).shape[0]
    i, j = np.nonzero(np.asarray(b.alpha) > 0.5)
    s = np.stack([(j + 0.5) / res, (i + 0.5) / res, np.asarray(b.depth, np.float64)[i, j]], -1)
    return np.asarray(b.origin, np.float64) + (s * np.asarray(b.size, np.float64)) @ np.asarray(b.axes, np.float64)


class Billboards(Passes):
    def __init__(self, ctx, boards, bordered, light, material, shadow_size: int, method: str = "improved",
                 hit_range: float = 0.01, coarse=None, bounds=None, instances=None, mipmaps: bool = False):
        """boards: vdmbake.bundle.parts.Billboard (origin, axes, size, alpha, depth, normal maps); bordered: their
        vdmbake.bundle.parts.BorderedMaps; coarse: an optional TriMesh drawn with them; bounds: (centre, radius) of
        the model, which fits the shadow map (default: the box of the covered texels' points, and of the
        coarse mesh); instances: (N, 4, 4) world matrices of the object's copies (vdmbake.common.instances),
        every copy in one instanced draw per pass, the shadow map covering them all (None: drawn once); mipmaps: the
        colour maps and the coarse mesh's albedo map mip-mapped (the scene's render.mipmaps)."""
        if method not in METHODS:
            raise InputError(f"billboards: method '{method}' is unknown; use one of {', '.join(METHODS)}.")
        if not hit_range > 0:
            raise InputError(f"billboards: hit_range = {hit_range}; it must be > 0.")
        boards = list(boards)
        sizes = {np.asarray(b.alpha).shape for b in boards}
        if len(sizes) > 1 or any(s[0] != s[1] for s in sizes):
            raise InputError(f"billboards: the maps must all be square and of one size; got {sorted(sizes)}.")
        self.ctx, self.light, self.material, self.method = ctx, light, material, method
        self.hit_range = float(hit_range)
        self.faces = len(coarse.faces) if coarse is not None else 0
        if bounds is None:
            pts = [surface_points(b) for b in boards] + ([coarse.vertices] if coarse is not None else [])
            pts = np.concatenate(pts + [np.zeros((0, 3))])
            if not len(pts):
                raise InputError("billboards: nothing to draw (no covered texel and no coarse mesh).")
            lo, hi = pts.min(0), pts.max(0)
            centre = 0.5 * (lo + hi)
            texel = max((np.linalg.norm(b.size) / np.asarray(b.alpha).shape[0] for b in boards), default=0.0)
            bounds = (centre, float(np.linalg.norm(pts - centre, axis=1).max()) + texel)
        self.centre, radius = np.asarray(bounds[0], np.float64), float(bounds[1])   # the data is about the centre
        self.radius = radius
        self.behind = COARSE_BEHIND * radius
        placed = np.eye(4)[None] if instances is None else np.asarray(instances, np.float64)
        self.instanced = instances is not None
        # the GPU space about the copies (instances.enclosing; drawn once: the object's own sphere)
        self.anchor, reach = copies.enclosing(placed, self.centre, radius)
        self.shadow = ShadowMap(ctx, shadow_size, light.direction, reach)
        self.model = ctx.buffer(reserve=len(placed) * 64)   # the copies' matrices (place)
        self.objects, self.draws = [self.model], []         # GL objects to release; (pass, program, vao, kind)
        self.place(placed)
        self.albedo_maps = self.coarse = None

        defines = ("THESIS",) if method == "thesis" else ("IMPROVED",)
        self.shadow_squeeze = np.eye(4)   # the light's raster matrix is this times the shadow map's
        if boards:
            o = np.array([np.asarray(b.origin, np.float64) - self.centre for b in boards])
            edges = np.array([np.asarray(b.axes, np.float64) * np.asarray(b.size, np.float64)[:, None]
                              for b in boards])
            # per vertex: the unit-cube corner, its box (origin, edges) and its layer (billboard.vert)
            box = np.concatenate([o, edges.reshape(-1, 9)], 1).astype(np.float32)
            vertices = np.concatenate([np.repeat(CUBE[None], len(boards), 0), np.repeat(box[:, None], 36, 1)], 2)
            layers = np.repeat(np.arange(len(boards), dtype=np.int32), 36)
            # The light's raster matrix: the shadow map's, its depth range widened to hold every copy's box
            # corners (also in a composite's map of the whole scene, which holds this object's bounding sphere).
            far = max(np.linalg.norm(o[:, None] + CORNERS[None] @ edges, axis=2).max(), radius)
            self.shadow_squeeze = np.diag([1.0, 1.0, min(1.0, reach / copies.enclosing(placed, self.centre, far)[1]), 1.0])
            res = np.asarray(boards[0].alpha).shape[0]
            maps = np.stack([np.asarray(m.maps, np.float32) for m in bordered])
            covered = [np.asarray(b.alpha) > 0.5 for b in boards]
            self.maps = ctx.texture_array((res + 2, res + 2, len(boards)), 4, maps.tobytes(), dtype="f4")
            self.maps.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.alpha = ctx.texture_array((res, res, len(boards)), 1,
                                           (np.stack(covered) * 255).astype(np.uint8).tobytes(), dtype="f1")
            self.alpha.filter = (moderngl.NEAREST, moderngl.NEAREST)
            for t in (self.maps, self.alpha):
                t.repeat_x = t.repeat_y = False
            vbuf = ctx.buffer(np.ascontiguousarray(vertices, np.float32).tobytes())
            lbuf = ctx.buffer(layers.tobytes())
            self.albedo_maps = albedo_maps(ctx, bordered, boards if mipmaps else None)
            self.objects += [self.maps, self.alpha, vbuf, lbuf, self.albedo_maps]
            shaded = ("ALBEDO_MAPS",) + (("MIPMAPS",) if mipmaps else ()) if self.albedo_maps is not None else ()
            for stage, extra in (("shadow", ("SHADOW",)), ("frame", shaded)):
                prog = gl.program(ctx, "billboard.vert", "billboard.frag", defines + extra)
                vao = gl.vertex_array(ctx, prog, [
                    (vbuf, "3f 3f 3f 3f 3f", "in_corner", "in_origin", "in_u", "in_v", "in_w"),
                    (lbuf, "1i", "in_layer"), (self.model, "16f/i", "in_model")])
                self.draws.append((stage, prog, vao, "boards"))
        if coarse is not None:   # Vichitvejpaisal2005 §3.4: the coarse mesh, in both passes
            draws, self.coarse = coarse_draws(ctx, coarse, self.centre, None if instances is None else self.model,
                                              mipmaps)
            self.objects.append(self.coarse)
            self.draws += [("shadow", *draws["depth"], "mesh"), ("frame", *draws["shaded"], "mesh")]

    def place(self, instances) -> None:
        """Draw these copies (world matrices, at most as many as built with) from now on."""
        self.model.write(copies.model_columns(instances, self.centre, self.anchor))
        self.count = len(instances)

    def _draw(self, stage: str, view_proj, raster, viewport, push: dict, **uniforms) -> None:
        """One pass. raster: the billboards' box matrix (wider depth range than view_proj); push: the coarse
        mesh's matrix uniforms, pushed back (passes.boards.pushed)."""
        ctx = self.ctx
        for name, prog, vao, kind in self.draws:
            if name != stage:
                continue
            if stage == "frame":   # the material's albedo where neither the maps nor the coarse mesh have colour
                gl.set_shading(prog, self.light, self.material, self.albedo_maps is None if kind == "boards"
                               else self.coarse.uniform_albedo)
                # The coarse mesh, known to within `behind` of the surface, looks its shadow up that much further out.
                offset = NORMAL_OFFSET_TEXELS * self.shadow.texel + (self.behind if kind == "mesh" else 0.0)
                self.shadow.bind(prog, normal_offset=offset)
            if kind == "boards":
                gl.bind_textures(prog, u_maps=self.maps, u_alpha=self.alpha)
                march = {"u_hit_range": self.hit_range} if self.method == "thesis" else {}
                if stage == "frame":   # the frame's shadow lookup offset (billboard.frag)
                    march.update(u_board_texels=BOARD_TEXELS,
                                 u_tolerance=2 * self.hit_range if self.method == "thesis" else 0.0)
                    if self.albedo_maps is not None:
                        gl.bind_textures(prog, u_albedo_maps=self.albedo_maps)
                gl.set_uniforms(prog, u_raster=raster, **march, u_view_proj=view_proj,
                                u_inv_view_proj=np.linalg.inv(view_proj),
                                u_viewport=tuple(float(x) for x in viewport), **uniforms)
                ctx.enable(moderngl.CULL_FACE)
                ctx.cull_face = "front"       # back faces only (billboard.vert)
                vao.render(instances=self.count)
                ctx.cull_face = "back"
                ctx.disable(moderngl.CULL_FACE)
            else:
                if stage == "frame":
                    self.coarse.bind(prog)
                gl.set_uniforms(prog, **push, **uniforms)
                ctx.polygon_offset = RasterPasses.POLYGON_OFFSET if stage == "shadow" else (0.0, 0.0)
                vao.render(instances=self.count)
                ctx.polygon_offset = (0.0, 0.0)

    def passes(self, camera, target) -> list:
        """The frame's passes in order, as (name, callable): render runs them, a profile times each."""
        eye = camera.eye - self.anchor
        to_anchor = camera.view() @ translation(self.anchor)

        def shadow():
            self.shadow.begin()
            self._draw("shadow", self.shadow.view_proj, self.shadow_squeeze @ self.shadow.view_proj,
                       self.shadow.texture.size,
                       pushed(self.shadow.view_proj, self.behind, light=self.light.direction, copies=self.instanced))

        def frame():
            target.begin()
            view_proj = camera.projection() @ to_anchor
            self._draw("frame", view_proj, infinite_far(camera.projection()) @ to_anchor, target.size,
                       pushed(view_proj, self.behind, eye=eye, radius=self.radius, copies=self.instanced), u_eye=tuple(eye))
        return [("shadow", shadow), ("frame", frame)]

    def release(self) -> None:
        gl.release(*(vao for _, _, vao, _ in self.draws), *self.objects, self.shadow)


def build(ctx, src, variant):
    """One PROJECTION-METHOD[+coarse] variant (vdmbake.techniques.billboards.Variant)."""
    part = src.part
    projection = part[variant.projection]
    boards = src.bundle.read(projection["maps"], parts.BILLBOARDS)
    bordered = src.bundle.read(projection["bordered"], parts.BORDERED)
    # the coarse mesh with the asset's colours (per vertex in the part; its albedo map where it has UVs)
    coarse = src.bundle.surface(src.entry, part["coarse"]) if variant.coarse or variant.method == "hier" else None
    bounds = (np.asarray(src.entry["centre"]), src.entry["radius"])
    if variant.method == "hier":
        return HierBillboards(ctx, boards, bordered, src.scene.light, src.obj.material, src.shadow_map,
                              coarse if variant.coarse else None, bounds, shadow_mesh=coarse, instances=src.instances,
                              mipmaps=src.mipmaps)
    method = "thesis" if variant.hit_range is not None else "improved"
    return Billboards(ctx, boards, bordered, src.scene.light, src.obj.material, src.shadow_map, method,
                      variant.hit_range or 0.01, coarse, bounds, src.instances, src.mipmaps)
