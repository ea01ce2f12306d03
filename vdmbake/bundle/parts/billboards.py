"""Enhanced billboards (Vichitvejpaisal2005 §3.1): each box's frame in the manifest, its maps in one EXR."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...formats import exr
from ...schema import REQUIRED, Boolean, Tables, Vector, setting
from .kind import is_rotation, Matrix, PartKind, albedo_channels, albedo_meta, bad, channels, finite, need, unpack_albedo


@dataclass
class Billboard:
    """One enhanced billboard (Vichitvejpaisal2005 §3.1): a box looking along w at part of the model, and its
    R x R maps; texel [row, col] = (v, u), row 0 at v = 0."""
    origin: np.ndarray   # (3,) world corner of the box at texel (0, 0), depth 0
    axes: np.ndarray     # (3, 3) rows u, v, w (w = view direction into the model), right-handed
    size: np.ndarray     # (3,) world extent of the box along u, v, w
    alpha: np.ndarray    # (R, R) float32 coverage 0/1
    depth: np.ndarray    # (R, R) float32 in [0, 1] along w (0 = box front), 1 where alpha is 0
    normal: np.ndarray   # (R, R, 3) float32 world unit shading normal facing -w, 0 where alpha is 0
    albedo: np.ndarray | None = None   # (R, R, 3) the colour map (Vichitvejpaisal2005 §3.1): linear RGB albedo, 0 where alpha
                                       # is 0; only for assets with their own colours (texture.has_albedo)


def _pack_billboards(boards: list[Billboard]):
    data = exr.to_bytes({f"bb{i:03d}": {"A": b.alpha, "depth.Z": b.depth,
                                        **{f"normal.{a}": b.normal[..., k] for k, a in enumerate("XYZ")},
                                        **albedo_channels(b.albedo)}
                         for i, b in enumerate(boards)})
    return data, {"boards": [{"origin": b.origin.tolist(), "axes": b.axes.tolist(), "size": b.size.tolist()}
                             for b in boards], **albedo_meta(b.albedo for b in boards)}


def _unpack_billboards(data, meta, origin) -> list[Billboard]:
    parts = channels(data, origin) if meta["boards"] else {}
    out = []
    for i, b in enumerate(meta["boards"]):
        a, d, nx, ny, nz = need(parts, f"bb{i:03d}", ["A", "depth.Z", "normal.X", "normal.Y", "normal.Z"], origin)
        axes = np.asarray(b["axes"], np.float64)
        finite(origin, **{f"bb{i:03d}": np.stack([a, d, nx, ny, nz])})
        if not is_rotation(axes) or (np.asarray(b["size"]) <= 0).any():
            bad(origin, f"billboard {i}: axes not a right-handed orthonormal frame or a size not positive")
        out.append(Billboard(np.asarray(b["origin"], np.float64), axes,
                             np.asarray(b["size"], np.float64), a, d, np.stack([nx, ny, nz], -1),
                             unpack_albedo(parts, f"bb{i:03d}", meta, a.shape, origin)))
    return out


@dataclass(frozen=True)
class BoardMeta:
    origin: tuple = setting(REQUIRED, Vector(3), "world corner of the box")
    axes: tuple = setting(REQUIRED, Matrix(3, 3), "rows u, v, w")
    size: tuple = setting(REQUIRED, Vector(3, 0.0), "extent along u, v, w")


@dataclass(frozen=True)
class BillboardsMeta:
    boards: tuple = setting(REQUIRED, Tables(BoardMeta), "each billboard's box")
    albedo: bool = setting(False, Boolean(), "every billboard has a colour map")


BILLBOARDS = PartKind("billboards", ".exr", _pack_billboards, _unpack_billboards, BillboardsMeta)
