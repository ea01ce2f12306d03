"""The mesostructure tile (Wang2003 §3): its height field and normal map, one EXR."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...formats import exr
from ...schema import REQUIRED, Integer, setting
from .kind import PartKind, channels, check_shape, finite, need


@dataclass
class MesostructureMaps:
    """One tile of the mesostructure (Wang2003 §3), N x N texels, row 0 at tile v = 0 (image order:
    [row, column] = [v, u]). heights in [0, 1] (1 = the reference surface); normals: unit
    texture-space normals of the displaced height field (z along the surface normal, the depth in
    tile units), the shading normals of every mesostructure technique and of the reference."""
    heights: np.ndarray   # (N, N) float32
    normals: np.ndarray   # (N, N, 3) float32


def _pack_mesostructure(m: MesostructureMaps):
    data = exr.to_bytes({"height": {"h": m.heights},
                         "normal": {f"normal.{a}": m.normals[..., i] for i, a in enumerate("XYZ")}})
    return data, {"size": int(m.heights.shape[0])}


def _unpack_mesostructure(data, meta, origin) -> MesostructureMaps:
    parts = channels(data, origin)
    (h,) = need(parts, "height", ["h"], origin)
    n = np.stack(need(parts, "normal", ["normal.X", "normal.Y", "normal.Z"], origin), -1)
    size = meta["size"]
    check_shape(origin, "height", h, (size, size))
    check_shape(origin, "normal", n, (size, size, 3))
    finite(origin, height=h, normal=n)
    return MesostructureMaps(h, n)


@dataclass(frozen=True)
class MesostructureMeta:
    size: int = setting(REQUIRED, Integer(4, 1024), "texels per tile side")


MESOSTRUCTURE = PartKind("mesostructure", ".exr", _pack_mesostructure, _unpack_mesostructure, MesostructureMeta)
