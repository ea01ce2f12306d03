"""Octahedral impostor atlases (Brucks 2018; vdmbake/kernels/octahedral.py): one EXR, the frame in the manifest."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...formats import exr
from ...schema import REQUIRED, Boolean, Integer, Number, Vector, setting
from .kind import is_rotation, COUNT, Matrix, PartKind, albedo_channels, albedo_meta, bad, channels, check_shape, finite, need, unpack_albedo


@dataclass
class OctahedralAtlas:
    """N x N orthographic views of an object on the lattice of an octahedral map of directions (the full
    sphere, or the hemisphere above the map's z: hemi), R x R texels each, in one atlas of N R x N R
    texels: view (i, j) is the tile at rows j R.., columns i R.. (row 0 at v = 0). View k looks along
    -e_k over the square [-capture, capture]^2 of its frame (u_k, v_k) around `centre`; the frames and
    the map follow vdmbake/kernels/octahedral.py (`basis` turns world directions into the map's)."""
    views: int             # N
    hemi: bool
    basis: np.ndarray      # (3, 3) rows x, y, z of the map's frame (z: up)
    centre: np.ndarray     # (3,) world centre of the bounding sphere: every view's centre
    radius: float          # the bounding sphere's radius
    capture: float         # half side of every view's square, world units
    normal: np.ndarray     # (N R, N R, 2) float32 in [-1, 1]: the normal in its view's frame (u, v, e), octahedral code
    depth: np.ndarray      # (N R, N R) float32 in [0, 1] along -e_k over 2 capture, 1 where not covered
    coverage: np.ndarray   # (N R, N R) float32, 1 where a surface was hit, else 0
    rays: int              # rays the bake traced
    albedo: np.ndarray | None = None   # (N R, N R, 3) float32 linear RGB albedo of the surface (around silhouettes
                                       # the covered neighbours' mean); only for assets with their own colours

    @property
    def resolution(self) -> int:
        """R: texels per side of every view."""
        return self.depth.shape[0] // self.views


def _pack_octahedral(a: OctahedralAtlas):
    data = exr.to_bytes({"atlas": {"normal.U": a.normal[..., 0], "normal.V": a.normal[..., 1],
                                   "depth.Z": a.depth, "A": a.coverage, **albedo_channels(a.albedo)}})
    return data, {"views": a.views, "resolution": a.resolution, "hemi": a.hemi, "basis": np.asarray(a.basis).tolist(),
                  "centre": np.asarray(a.centre).tolist(), "radius": float(a.radius), "capture": float(a.capture),
                  "rays": int(a.rays), **albedo_meta([a.albedo])}


def _unpack_octahedral(data, meta, origin) -> OctahedralAtlas:
    tables = channels(data, origin)
    nu, nv, d, a = need(tables, "atlas", ["normal.U", "normal.V", "depth.Z", "A"], origin)
    side = int(meta["views"]) * int(meta["resolution"])
    for name, x in (("normal.U", nu), ("normal.V", nv), ("depth.Z", d), ("A", a)):
        check_shape(origin, f"atlas {name} (the manifest says {meta['views']} views of {meta['resolution']}^2)", x,
               (side, side))
    finite(origin, **{f"atlas {name}": x for name, x in (("normal.U", nu), ("normal.V", nv), ("depth.Z", d), ("A", a))})
    if not is_rotation(meta["basis"]):
        bad(origin, "basis not a right-handed orthonormal frame")
    return OctahedralAtlas(int(meta["views"]), bool(meta["hemi"]), np.asarray(meta["basis"], np.float64),
                           np.asarray(meta["centre"], np.float64), float(meta["radius"]), float(meta["capture"]),
                           np.stack([nu, nv], -1), d, a, int(meta["rays"]),
                           unpack_albedo(tables, "atlas", meta, (side, side), origin))


@dataclass(frozen=True)
class OctahedralMeta:
    views: int = setting(REQUIRED, Integer(2, 64), "N: views per side of the map")
    resolution: int = setting(REQUIRED, Integer(16, 4096), "R: texels per side of every view")
    hemi: bool = setting(REQUIRED, Boolean(), "the upper hemisphere only")
    basis: tuple = setting(REQUIRED, Matrix(3, 3), "rows x, y, z of the map's frame")
    centre: tuple = setting(REQUIRED, Vector(3), "the bounding sphere's centre")
    radius: float = setting(REQUIRED, Number(0.0, open_lo=True), "the bounding sphere's radius")
    capture: float = setting(REQUIRED, Number(0.0, open_lo=True), "half side of every view's square")
    rays: int = setting(REQUIRED, COUNT, "rays the bake traced")
    albedo: bool = setting(False, Boolean(), "the atlas has the surface's colour")


OCTAHEDRAL = PartKind("octahedral", ".exr", _pack_octahedral, _unpack_octahedral, OctahedralMeta)
