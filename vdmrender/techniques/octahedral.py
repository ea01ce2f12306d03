"""Technique `octahedral`: octahedral impostors, the render side (Brucks 2018, "Octahedral Impostors";
Unreal's impostor baker as used in Fortnite, Amplify Impostors).

The bake (vdmbake.kernels.octahedral) holds N x N orthographic views of the object, on the lattice of an
octahedral map of directions (full sphere or upper hemisphere), in one atlas of normal, depth and
coverage. Each object is drawn as ONE screen-aligned quad over its bounding sphere (bounding_quad.vert).
Per pixel (octahedral.frag, shaders/include/octahedral.glsl): the ray's direction picks the lattice
triangle it falls in, i.e. three views and their barycentric weights; every view is intersected with
the pixel's ray in its own frame, by
  "march"   a ray / depth-map search over the ray's chord of the bounding sphere: a step per atlas
            texel that the ray's projection crosses (short, since the view looks nearly along the ray),
            a hit where the ray passes behind the map where it is covered, bisection and a secant step;
  "virtual" Amplify's single parallax step: the ray meets the view's middle plane, the depth read there
            moves it to that depth, where it is read again;
and the hits are blended by weight over the views that hit (the pixel is covered if they weigh at least
1/2). The blended hit writes its exact gl_FragDepth and is shaded with the shared model and the shadow map.
Unlike Brucks' and Amplify's per-object choice of views, every pixel picks its own, so close-ups and
wide fields of view need no special case; a camera inside the bounding sphere needs none either (the
ray starts on the near plane), but what the views never saw from outside (the inside of a concavity
the eye sits in) cannot be shown.

Shadows: the shadow map holds the impostor drawn from the light's orthographic camera (the light's
direction picks its own three views), so the technique's shadows carry its own errors and nothing of
the full mesh. Lookups move along the normal by the shadow map's normal offset plus ATLAS_TEXELS atlas
texels (the surface is known to about a texel, and the light's views are not the eye's).

Texture: one 2-D texture, RGBA16 unorm by default (rg: the normal's octahedral code in its view's
frame, b: depth, a: coverage), linear filtering, no mipmaps; the bake extrapolated the empty texels near
covered ones from them (vdmbake.kernels.octahedral.to_part), so filtering at a silhouette follows the surface. The
bake leaves EMPTY empty rings around every tile, so nothing crosses from one view into another.
For an asset with its own colours, a second texture of the same layout holds the surface's linear albedo
(RGB16F, as the bundle stores it), read at each view's hit and blended like the normal (ALBEDO_ATLAS);
otherwise the colour is the material's albedo.
"""
from __future__ import annotations

import moderngl
import numpy as np

from vdmbake.bundle import parts
from vdmbake.common import instances as copies
from vdmbake.errors import InputError

from ..gpu import gl
from ..passes.boards import covered_colours
from ..passes.raster import Passes
from ..passes.shadowmap import ShadowMap, translation

METHODS = ("march", "virtual")
TEXTURE_DTYPES = {"nu2": 2, "f4": 4}   # RGBA16 unorm (default), RGBA32F: bytes per channel
NORMAL_OFFSET_TEXELS = 0.7   # shadow lookups move this far along the normal, in shadow-map texels (as impostors) ...
ATLAS_TEXELS = 0.5           # ... plus this many atlas texels (the surface is known to about half a texel)
# The albedo atlas's last mip level under render.mipmaps: its tiles share one texture and keep EMPTY = 3 rings of
# empty texels (vdmbake.kernels.octahedral); at level 2 a bilinear read near a tile's edge reaches at most a
# quarter-weighted texel of the next tile, at level 3 a whole one (the next view's colours bleed in).
MAX_LEVEL = 2
CLIP_TEXELS = 2.0            # rays are clipped to the bounding sphere grown by this many atlas texels (less than
                             # the bake's EMPTY rings), so that every search starts strictly in front of the surface


def atlas_texels(a) -> np.ndarray:
    """(N R, N R, 4) float32 in [0, 1]: normal code / 2 + 1/2, depth, coverage (the bake extrapolated
    code and depth around the silhouettes: vdmbake.kernels.octahedral.to_part)."""
    return np.clip(np.concatenate([np.asarray(a.normal, np.float32) * 0.5 + 0.5, np.asarray(a.depth, np.float32)[..., None],
                                   np.asarray(a.coverage, np.float32)[..., None]], -1), 0.0, 1.0)


class Octahedral(Passes):
    def __init__(self, ctx, atlas, light, material, shadow_size: int, method: str = "march",
                 steps_per_texel: float = 1.0, dtype: str = "nu2", instances=None, mipmaps: bool = False):
        """atlas: vdmbake.bundle.parts.OctahedralAtlas; method: "march" or "virtual"; steps_per_texel: the
        march's step density; dtype: the atlas texture's channel type ("nu2": 16-bit unorm, "f4":
        float32); instances: (N, 4, 4) world matrices of the object's copies (vdmbake.common.instances), one
        quad each in one instanced draw (INSTANCED), the shadow map covering them all; mipmaps: the albedo atlas
        mip-mapped (the scene's render.mipmaps: passes/boards.py covered_colours, up to MAX_LEVEL)."""
        if method not in METHODS:
            raise InputError(f"octahedral: method '{method}' is unknown; use one of {', '.join(METHODS)}.")
        if dtype not in TEXTURE_DTYPES:
            raise InputError(f"octahedral: texture type '{dtype}' is unknown; use one of {', '.join(TEXTURE_DTYPES)}.")
        if not steps_per_texel > 0:
            raise InputError(f"octahedral: steps_per_texel = {steps_per_texel}; it must be > 0.")
        self.ctx, self.light, self.material = ctx, light, material
        self.views, self.steps_per_texel = int(atlas.views), float(steps_per_texel)
        self.anchor, self.radius, self.capture = np.asarray(atlas.centre, np.float64), float(atlas.radius), float(atlas.capture)
        self.basis = np.asarray(atlas.basis, np.float64)
        self.faces = None
        texels = atlas_texels(atlas)
        side = texels.shape[0]
        self.clip = self.radius + CLIP_TEXELS * 2.0 * self.capture * self.views / side
        data = (np.round(texels * 65535).astype(np.uint16) if dtype == "nu2" else texels.astype(np.float32))
        self.texture = ctx.texture((side, side), 4, data.tobytes(), dtype=dtype)
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = False
        self.texture_bytes = side * side * 4 * TEXTURE_DTYPES[dtype]
        self.albedo = None
        if atlas.albedo is not None and mipmaps:
            self.albedo = covered_colours(ctx, np.asarray(atlas.albedo, np.float32), np.asarray(atlas.coverage), MAX_LEVEL)
            self.texture_bytes += int(side * side * 4 * 2 * sum(4 ** -k for k in range(MAX_LEVEL + 1)))
        elif atlas.albedo is not None:
            self.albedo = ctx.texture((side, side), 3, np.asarray(atlas.albedo, np.float16).tobytes(), dtype="f2")
            self.albedo.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.albedo.repeat_x = self.albedo.repeat_y = False
            self.texture_bytes += side * side * 3 * 2
        self.corners = gl.quad_corners(ctx)
        layout, reach, self.count, self.model = [(self.corners, "2f", "in_corner")], self.radius, 1, None
        self.centre = self.anchor   # the atlas's frame; with copies the GPU space is about them (instances.enclosing)
        if instances is not None:
            self.anchor, reach = copies.enclosing(instances, self.centre, self.radius)
            self.model = ctx.buffer(reserve=len(instances) * 64)
            layout.append((self.model, "16f/i", "in_model"))
            self.place(instances)
        self.shadow = ShadowMap(ctx, shadow_size, light.direction, reach)
        defines = (method.upper(),) + (("HEMI",) if atlas.hemi else ()) + (("INSTANCED",) if instances is not None else ())
        may_lack = ("u_steps_per_texel",) if method == "virtual" else ()   # the single parallax step
        self.draws = {}
        shaded = ("ALBEDO_ATLAS",) + (("MIPMAPS",) if mipmaps else ()) if self.albedo is not None else ()
        for stage, extra in (("shadow", ("SHADOW",)), ("frame", shaded)):
            prog = gl.program(ctx, "bounding_quad.vert", "octahedral.frag", defines + extra, may_lack)
            self.draws[stage] = (prog, gl.vertex_array(ctx, prog, layout))

    def place(self, instances) -> None:
        """Draw these copies (world matrices, at most as many as built with) from now on."""
        self.model.write(copies.model_columns(instances, self.centre, self.anchor))
        self.count = len(instances)

    def _draw(self, stage: str, view_proj, viewport, **uniforms) -> None:
        prog, vao = self.draws[stage]
        gl.bind_textures(prog, u_atlas=self.texture)
        gl.set_uniforms(prog, u_views=self.views, u_capture=self.capture, u_radius=self.clip,
                        u_steps_per_texel=self.steps_per_texel, u_view_proj=view_proj,
                        u_inv_view_proj=np.linalg.inv(view_proj), u_viewport=tuple(float(x) for x in viewport),
                        u_basis=self.basis.T, **uniforms)   # GLSL mat3 is column-major: M = basis (map = M world)
        vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=self.count)

    def passes(self, camera, target) -> list:
        """The frame's passes in order, as (name, callable): the impostor into the light's map, then the frame."""
        def shadow():
            self.shadow.begin()
            self._draw("shadow", self.shadow.view_proj, self.shadow.texture.size)

        def frame():
            target.begin()
            prog = self.draws["frame"][0]
            gl.set_shading(prog, self.light, self.material, self.albedo is None)
            if self.albedo is not None:
                gl.bind_textures(prog, u_albedo_atlas=self.albedo)
            self.shadow.bind(prog, normal_offset=NORMAL_OFFSET_TEXELS * self.shadow.texel)
            self._draw("frame", camera.projection() @ camera.view() @ translation(self.anchor), target.size,
                       u_eye=tuple(camera.eye - self.anchor), u_atlas_texels=ATLAS_TEXELS)
        return [("shadow", shadow), ("frame", frame)]

    def release(self) -> None:
        gl.release(*(vao for _, vao in self.draws.values()), self.texture, self.albedo, self.corners, self.model,
                   self.shadow)


def shadow_size(resolution: int, scale: float, scene_size: int) -> int:
    """The shadow map's side: `scale` texels per atlas texel of a view (resolution R), at most the
    scene's. The impostor resolves nothing finer than its views' texels, and the shadow pass, which
    searches every view-texel's worth of the map, costs in proportion to the map's area."""
    return int(min(scene_size, max(16, round(scale * resolution))))


def build(ctx, src, variant):
    """One LAYOUT-NxR-METHOD variant (vdmbake.techniques.octahedral.Variant); its methods share the atlas."""
    atlas = src.bundle.read(src.part[variant.atlas], parts.OCTAHEDRAL)
    placed = src.instances   # the shadow map spans every copy: as many texels per atlas texel of the smallest copy,
    spread = 1.0 if placed is None else (    # up to the scene's
        copies.enclosing(placed, atlas.centre, atlas.radius)[1] / (atlas.radius * copies.scales(placed).min()))
    return Octahedral(ctx, atlas, src.scene.light, src.obj.material,
                      shadow_size(variant.resolution, src.options.shadow_scale * spread, src.shadow_map),
                      variant.method, instances=placed, mipmaps=src.mipmaps)
