"""Spheres and capped cylinders (Sigg2006's quadrics): binary PLY, one element per kind."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...kernels import quadrics
from ...schema import REQUIRED, setting
from .kind import COUNT, PartKind, bad, check_extent, finite


@dataclass(frozen=True)
class QuadricsMeta:
    spheres: int = setting(REQUIRED, COUNT, "spheres")
    cylinders: int = setting(REQUIRED, COUNT, "capped cylinders")


def _unpack_quadrics(data, meta, origin):
    q = quadrics.from_bytes(data, origin)
    if (len(q.spheres), len(q.cylinders)) != (meta["spheres"], meta["cylinders"]) or not len(q.spheres) + len(q.cylinders):
        bad(origin, f"{len(q.spheres)} spheres and {len(q.cylinders)} cylinders where the manifest says "
                     f"{meta['spheres']} and {meta['cylinders']} (and at least one is needed)")
    finite(origin, spheres=q.spheres, cylinders=q.cylinders)
    if (q.spheres[:, 3] <= 0).any() or (q.cylinders[:, 6] <= 0).any() or (
            np.linalg.norm(q.cylinders[:, 3:6] - q.cylinders[:, :3], axis=1) <= 0).any():
        bad(origin, "a sphere or cylinder has no volume (radius or length 0)")
    check_extent(origin, *q.bounding_sphere())
    return q


QUADRICS = PartKind("quadrics", ".ply",
                    lambda q: (quadrics.to_bytes(q), {"spheres": len(q.spheres), "cylinders": len(q.cylinders)}),
                    _unpack_quadrics, QuadricsMeta)
