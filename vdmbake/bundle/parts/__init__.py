"""The bundle's part kinds: what each file holds, packed (bake) and unpacked (render) side by side.

Each kind turns a value into a file's bytes plus the metadata the manifest records beside the
part's checksum, and back. docs/bundle.md describes the same layouts for readers that do not use
this package. PLY parts are binary little-endian (vdmbake.formats.ply); EXR parts are zip-compressed,
float32, one EXR part per named table, data channels with dotted names (vdmbake.formats.exr).
"""
from __future__ import annotations

from .albedo_map import ALBEDO_MAP
from .billboards import BILLBOARDS, Billboard
from .bordered import BORDERED, BorderedMaps
from .kind import PartKind
from .mesh import MESH, MeshMeta
from .mesostructure import MESOSTRUCTURE, MesostructureMaps
from .octahedral import OCTAHEDRAL, OctahedralAtlas
from .pyramid import PYRAMID
from .quadrics import QUADRICS
from .vdm import VDM, VDMTables
from .viewer_mesh import VIEWER_MESH

__all__ = ["KINDS", "PartKind", "stored", "MeshMeta",   # the kinds, and the values they hold
           "MESH", "QUADRICS", "VIEWER_MESH", "ALBEDO_MAP", "MESOSTRUCTURE", "VDM", "BILLBOARDS", "BORDERED",
           "PYRAMID", "OCTAHEDRAL", "MesostructureMaps", "VDMTables", "Billboard", "BorderedMaps", "OctahedralAtlas"]


KINDS = {k.name: k for k in (MESH, QUADRICS, VIEWER_MESH, ALBEDO_MAP, MESOSTRUCTURE, VDM, BILLBOARDS, BORDERED, PYRAMID,
                             OCTAHEDRAL)}


def stored(kind: PartKind, value):
    """`value` as a reader of the bundle sees it (float32 rounding included): a part kind's round trip
    without a bundle (the bake takes it from BundleWriter.add_read, which reads back what it writes)."""
    data, meta = kind.pack(value)
    return kind.unpack(data, meta, f"stored {kind.name}")
