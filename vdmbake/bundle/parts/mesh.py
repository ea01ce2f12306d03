"""Meshes (the full mesh, coarse and displaced ones): binary PLY with the optional surface frame."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...formats import ply
from ...schema import REQUIRED, Integer, setting
from .kind import PartKind, bad, check_extent, finite


@dataclass(frozen=True)
class MeshMeta:
    vertices: int = setting(REQUIRED, Integer(3, 2**31 - 1), "vertices")
    faces: int = setting(REQUIRED, Integer(1, 2**31 - 1), "triangles")


def _unpack_mesh(data, meta, origin):
    m = ply.from_bytes(data, origin)
    if not len(m.faces):
        bad(origin, "the mesh has no face")
    if (len(m.vertices), len(m.faces)) != (meta["vertices"], meta["faces"]):
        bad(origin, f"{len(m.vertices)} vertices and {len(m.faces)} faces where the manifest says "
                     f"{meta['vertices']} and {meta['faces']}")
    if m.faces.size and (m.faces.min() < 0 or m.faces.max() >= len(m.vertices)):
        bad(origin, f"face indices span [{m.faces.min()}, {m.faces.max()}] over {len(m.vertices)} vertices")
    f = m.frame
    finite(origin, vertices=m.vertices, normals=m.normals, uvs=m.uvs,
            frame=None if f is None else np.concatenate([f.dpdu, f.dpdv, f.k1[:, None], f.k2[:, None], f.d1], 1))
    check_extent(origin, *m.bounding_sphere())
    return m


MESH = PartKind("mesh", ".ply",
                lambda m: (ply.to_bytes(m), {"vertices": len(m.vertices), "faces": len(m.faces)}),
                _unpack_mesh, MeshMeta)
