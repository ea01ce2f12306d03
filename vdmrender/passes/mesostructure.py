"""The per-pixel mesostructure techniques' common pass (vdm, pom, bump: VDM, Wang et al. 2003, and
its peers): the base mesh with its interpolated surface frame, the mesostructure's height field and
normal map, the shared shading and the base mesh's shadow map for shadows cast across the object.
The mesostructure's maps and geometry as data are in vdmrender.common.mesostructure."""
from __future__ import annotations

import moderngl
import numpy as np

from vdmbake.bundle import parts

from ..common.mesostructure import maps, tile_albedo
from ..gpu import gl
from .raster import RasterPasses


def back_faces(mesh) -> str | None:
    """Which faces a stage that discards fragments seen from behind (V . N <= 0, N the interpolated normal)
    can leave to the rasteriser to cull: "back" when every face's winding agrees with its vertex normals,
    "front" when every one disagrees, None for a mixed mesh."""
    v, f = mesh.vertices, mesh.faces
    g = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    agree = np.einsum("ij,ij->i", g, mesh.normals[f].sum(1))
    return "back" if (agree >= 0).all() else "front" if (agree <= 0).all() else None


def texture(tex, repeat: bool, mipmaps: bool):
    tex.repeat_x = tex.repeat_y = repeat
    if mipmaps:
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    else:
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    return tex


class MesostructurePass(RasterPasses):
    """The base mesh with its frame, drawn by one mesostructure fragment stage."""

    NORMAL_OFFSET_TEXELS = 1.5   # the lookups are at the base surface, which the shadow map also holds

    def __init__(self, ctx, src, frag: str, heights: bool = True, curvature: bool = False, cull: bool = True,
                 defines: tuple = (), **uniforms):
        """heights: the stage marches the height field (u_height, u_depth; bump reads only normals).
        curvature: the stage reads the curvature frame (in_curv, in_d1); one vertex layout serves every
        stage, and the others compile those attributes away. cull: the stage discards the base surface
        seen from behind, so the frame pass lets the rasteriser cull those faces (back_faces: on llvmpipe
        a discard at the top of a stage still costs about the whole stage). defines: of the stage, e.g.
        ("FLAT",) for relief's straight rays. The albedo is the material's (u_albedo), or the tile albedo read
        at the hit's tile coordinate where the mesostructure has one (TILE_ALBEDO, mesostructure.glsl).
        The scene's render.mipmaps (MIPMAPS): the normal map and the colour tile mip-mapped and read at the pixel's
        footprint (mesostructure.glsl); the searches keep their own levels (below)."""
        mesh = src.bundle.read(src.entry["mesh"], parts.MESH)
        if src.mipmaps:
            defines = (*defines, "MIPMAPS")
        tile = tile_albedo(src)
        if tile is not None:
            defines, self.UNIFORM_ALBEDO = (*defines, "TILE_ALBEDO"), False
        anchor, radius = mesh.bounding_sphere()
        super().__init__(ctx, src.scene.light, src.obj.material, anchor, radius, src.shadow_map)
        self.faces = len(mesh.faces)
        m = src.obj.mesostructure
        f = mesh.frame
        cols = [mesh.vertices - anchor, mesh.normals, mesh.uvs, f.dpdu, f.dpdv, np.stack([f.k1, f.k2], 1), f.d1]
        vbo = ctx.buffer(np.ascontiguousarray(np.concatenate(cols, 1), "f4").tobytes())
        ibo = ctx.buffer(np.ascontiguousarray(mesh.faces, "i4").tobytes())
        self.cull_face = back_faces(mesh) if cull else None
        self.add("mesostructure.vert", defines, [vbo, ibo],
                 [(vbo, "3f 3f 2f 3f 3f 2f 3f", "in_pos", "in_normal", "in_uv", "in_dpdu", "in_dpdv", "in_curv",
                   "in_d1")],
                 ibo, frag=frag, depth_vertex="mesh.vert",
                 may_lack=() if curvature else ("in_curv", "in_d1"))
        meso = maps(src)
        h, n = meso.heights, meso.normals
        # Height fields are indexed [v, u] with row 0 at v = 0 (vdmbake.assets.heightfields); GL's first row is
        # t = 0, so the arrays go up as they are and texture(T) reads h at T = (u, v). The normals are mip-mapped
        # only under render.mipmaps (their mean, unnormalised, is the footprint's mean diffuse term:
        # mesostructure.glsl); the heights always are: pom's search reads them at the footprint's level (what a
        # minified march sees), the others (relief's pyramid, vdm's depth_at_lod0) at level 0, which the ray's
        # hit needs.
        self.textures = {
            "u_normals": texture(ctx.texture(h.shape[::-1], 3, n.astype("f4").tobytes(), dtype="f4"), True,
                                 src.mipmaps)}
        if tile is not None:
            self.textures["u_albedo_map"] = gl.albedo_texture(ctx, tile, src.mipmaps)
        self.uniforms = {"u_tiling": tuple(m.tiling), **uniforms}
        if heights:
            self.textures["u_height"] = texture(ctx.texture(h.shape[::-1], 1, h.astype("f4").tobytes(), dtype="f4"),
                                                True, True)
            self.uniforms["u_depth"] = m.depth

    def bind_frame(self, prog, camera) -> None:
        gl.bind_textures(prog, **self.textures)
        gl.set_uniforms(prog, **self.uniforms)

    def release(self) -> None:
        super().release()
        gl.release(*self.textures.values())
