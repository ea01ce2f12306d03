"""A quadric set's triangle mesh with vertex colours, for viewers and the raster peer."""
from __future__ import annotations

from ...kernels import quadric_mesh
from .kind import PartKind, bad, finite
from .mesh import MeshMeta


def _unpack_viewer_mesh(data, meta, origin):
    m, rgb = quadric_mesh.from_bytes(data, origin)
    if (len(m.vertices), len(m.faces)) != (meta["vertices"], meta["faces"]):
        bad(origin, f"{len(m.vertices)} vertices and {len(m.faces)} faces where the manifest says "
                     f"{meta['vertices']} and {meta['faces']}")
    if m.faces.size and (m.faces.min() < 0 or m.faces.max() >= len(m.vertices)):
        bad(origin, f"face indices span [{m.faces.min()}, {m.faces.max()}] over {len(m.vertices)} vertices")
    finite(origin, vertices=m.vertices, normals=m.normals)
    return m, rgb


VIEWER_MESH = PartKind("viewer-mesh", ".ply",
                       lambda mc: (quadric_mesh.to_bytes(*mc), {"vertices": len(mc[0].vertices), "faces": len(mc[0].faces)}),
                       _unpack_viewer_mesh, MeshMeta)
