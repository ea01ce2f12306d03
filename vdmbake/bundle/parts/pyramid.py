"""The min/max mip pyramid of a depth field (the hierarchical tracer's, vdmbake/common/pyramid.py)."""
from __future__ import annotations

from dataclasses import dataclass

from ...common import pyramid
from ...formats import exr
from ...schema import REQUIRED, Choice, Integer, setting
from .kind import PartKind, bad, channels, finite, need


def _pack_pyramid(p: pyramid.Pyramid):
    return exr.to_bytes(pyramid.to_parts(p)), {"mode": p.mode, "levels": p.top + 1}


def read(tables: dict, mode: str, origin: str, empties: bool = False) -> pyramid.Pyramid:
    """A pyramid from its EXR parts (`samples`, `L00`, ...), refused unless its levels are the ones its samples
    make in `mode` and hold their surface (vdmbake.common.pyramid.from_parts): the relief part, and each
    billboard's in a bordered part (`empties`: with its uncovered cells marked)."""
    need(tables, "samples", ["depth.Z"], origin)
    try:
        p = pyramid.from_parts(tables, mode, empties)
    except ValueError as e:
        bad(origin, str(e))
    finite(origin, samples=p.samples, **{f"L{L:02d}": a for L, a in enumerate(p.levels)})
    return p


def _unpack_pyramid(data, meta, origin):
    p = read(channels(data, origin), meta["mode"], origin)
    if p.top + 1 != meta["levels"]:
        bad(origin, f"{p.top + 1} levels where the manifest says {meta['levels']}")
    return p


@dataclass(frozen=True)
class PyramidMeta:
    mode: str = setting(REQUIRED, Choice(*pyramid.MODES), "addressing")
    levels: int = setting(REQUIRED, Integer(1, 64), "mip levels")


PYRAMID = PartKind("pyramid", ".exr", _pack_pyramid, _unpack_pyramid, PyramidMeta)
