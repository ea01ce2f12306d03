"""The billboards' maps as the renderers sample them: bordered, with optional pyramids and colour."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...common import pyramid
from ...formats import exr
from ...schema import REQUIRED, Boolean, Choice, setting
from .kind import COUNT, PartKind, albedo_channels, albedo_meta, bad, channels, finite, need, unpack_albedo
from .pyramid import read as read_pyramid


@dataclass
class BorderedMaps:
    """One billboard's maps as its renderers sample them (vdmbake/kernels/billboard_maps.py): normal (xyz) and
    depth (w) with a one-texel border, the border and the empty texels near covered ones extrapolated;
    and, for the hierarchical march only, the min/max pyramid of its depth surface (empty cells marked);
    for an asset with colours, its colour map with the same border (the empty texels near covered ones
    hold their covered neighbours' mean)."""
    maps: np.ndarray                       # (R+2, R+2, 4) float32
    pyramid: pyramid.Pyramid | None = None
    albedo: np.ndarray | None = None       # (R+2, R+2, 3) float32 linear RGB


def _pack_bordered(boards: list[BorderedMaps]):
    tables = {}
    for i, b in enumerate(boards):
        tables[f"bb{i:03d}"] = {**{f"normal.{a}": b.maps[..., k] for k, a in enumerate("XYZ")}, "depth.Z": b.maps[..., 3],
                                **albedo_channels(b.albedo)}
        if b.pyramid is not None:
            tables.update({f"bb{i:03d}.{k}": v for k, v in pyramid.to_parts(b.pyramid).items()})
    traced = [b.pyramid is not None for b in boards]
    return exr.to_bytes(tables), {"boards": len(boards), "pyramids": bool(traced) and all(traced),
                                  "mode": pyramid.CLAMP, **albedo_meta(b.albedo for b in boards)}


def _unpack_bordered(data, meta, origin) -> list[BorderedMaps]:
    tables = channels(data, origin) if meta["boards"] else {}
    out = []
    for i in range(meta["boards"]):
        name = f"bb{i:03d}"
        maps = np.stack(need(tables, name, ["normal.X", "normal.Y", "normal.Z", "depth.Z"], origin), -1)
        pyr = None
        if meta["pyramids"]:
            sub = {k[len(name) + 1:]: v for k, v in tables.items() if k.startswith(name + ".")}
            pyr = read_pyramid(sub, meta["mode"], f"{origin} ({name})", empties=True)
            if pyr.samples.shape != maps.shape[:2]:
                bad(origin, f"{name}'s pyramid samples {pyr.samples.shape} where its maps are {maps.shape[:2]}")
        finite(origin, **{name: maps})
        out.append(BorderedMaps(maps.astype(np.float32), pyr, unpack_albedo(tables, name, meta, maps.shape[:2], origin)))
    return out


@dataclass(frozen=True)
class BorderedMeta:
    boards: int = setting(REQUIRED, COUNT, "billboards")
    pyramids: bool = setting(REQUIRED, Boolean(), "every billboard has its pyramid")
    mode: str = setting(REQUIRED, Choice(pyramid.CLAMP), "the pyramids' addressing")
    albedo: bool = setting(False, Boolean(), "every billboard has a colour map")


BORDERED = PartKind("bordered-billboards", ".exr", _pack_bordered, _unpack_bordered, BorderedMeta)
