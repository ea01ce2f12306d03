"""The min/max mip pyramid of a depth field (the hierarchical tracer's, vdmbake/common/pyramid.py)."""
from __future__ import annotations

from dataclasses import dataclass

from ...common import pyramid
from ...formats import exr
from ...schema import REQUIRED, Choice, Integer, setting
from .kind import PartKind, bad, channels, finite, need


def _pack_pyramid(p: pyramid.Pyramid):
    return exr.to_bytes(pyramid.to_parts(p)), {"mode": p.mode, "levels": p.top + 1}


def _unpack_pyramid(data, meta, origin):
    tables = channels(data, origin)
    need(tables, "samples", ["depth.Z"], origin)
    levels = sorted(k for k in tables if k.startswith("L"))
    if len(levels) != meta["levels"]:
        bad(origin, f"{len(levels)} levels where the manifest says {meta['levels']}")
    for k in levels:
        need(tables, k, ["min.Z", "max.Z"], origin)
    p = pyramid.from_parts(tables, meta["mode"])
    finite(origin, samples=p.samples)
    return p


@dataclass(frozen=True)
class PyramidMeta:
    mode: str = setting(REQUIRED, Choice(*pyramid.MODES), "addressing")
    levels: int = setting(REQUIRED, Integer(1, 64), "mip levels")


PYRAMID = PartKind("pyramid", ".exr", _pack_pyramid, _unpack_pyramid, PyramidMeta)
