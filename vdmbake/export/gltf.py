"""glTF 2.0 writing (Khronos glTF 2.0 specification): triangle meshes as LOD levels of one node (MSFT_lod, with
MSFT_screencoverage in the node's extras), in one .gltf beside one .bin and the base-colour texture as PNG.

Written from numpy alone: every attribute float32 and tightly packed (§3.6.2.2), indices uint32, each buffer
view 4-byte aligned (§3.6.2.4); POSITION with its min and max (§3.7.2.1: required); normals unit length;
TEXCOORD_0 with t = 1 - v, since a glTF image's first row is at t = 0 (§3.8.4.1) and the bundle's maps keep
row 0 at v = 0; COLOR_0 the asset's linear per-vertex colour (§3.7.2.1: linear, multiplying the texture); the scene's up turned
to glTF's +Y by every level node itself (§3.5.3), since MSFT_lod's lower levels are outside the scene's node tree and
no parent's transform reaches them."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from ..formats.gltf import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, UNSIGNED_INT


class Writer:
    """One glTF document being assembled: binary data appended to one buffer, accessors, meshes, nodes."""

    def __init__(self):
        self.doc = {"asset": {"version": "2.0", "generator": "vdmexport"}, "buffers": [], "bufferViews": [],
                    "accessors": [], "meshes": [], "nodes": [], "materials": [], "scenes": [], "scene": 0}
        self.blob = bytearray()

    def view(self, data: np.ndarray, target: int) -> int:
        self.blob += b"\0" * (-len(self.blob) % 4)
        raw = np.ascontiguousarray(data).tobytes()
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(raw),
                                        "target": target})
        self.blob += raw
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, data: np.ndarray, kind: str, indices: bool = False) -> int:
        data = np.asarray(data, np.uint32 if indices else np.float32)
        acc = {"bufferView": self.view(data, ELEMENT_ARRAY_BUFFER if indices else ARRAY_BUFFER),
               "componentType": UNSIGNED_INT if indices else FLOAT, "count": int(data.size if indices else len(data)),
               "type": kind}
        if kind == "VEC3" and not indices:   # bounds: required for POSITION, harmless elsewhere
            acc.update(min=data.min(0).astype(float).tolist(), max=data.max(0).astype(float).tolist())
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def material(self, name: str, texture_uri: str | None, albedo, colours: bool) -> int:
        """A rough dielectric coloured as the asset is: glTF multiplies baseColorFactor, the texture and COLOR_0
        (§3.9.2), so the factor is the scene material's `albedo` (linear RGB) only where the level has neither a
        texture nor colours of its own, else 1 (the default), so they are not multiplied again. A texture gets an
        image entry of its own per material: Babylon.js's MSFT_lod loader throws a TypeError on LOD materials that
        share one image entry (valid glTF, §3.8.3)."""
        pbr = {"metallicFactor": 0.0, "roughnessFactor": 0.6}
        if texture_uri is not None:
            if not self.doc.get("samplers"):
                self.doc["samplers"] = [{"magFilter": 9729, "minFilter": 9987}]
            self.doc.setdefault("images", []).append({"uri": texture_uri})
            self.doc.setdefault("textures", []).append({"source": len(self.doc["images"]) - 1, "sampler": 0})
            pbr["baseColorTexture"] = {"index": len(self.doc["textures"]) - 1}
        elif not colours:
            pbr["baseColorFactor"] = [*map(float, albedo), 1.0]
        self.doc["materials"].append({"name": safe(name), "pbrMetallicRoughness": pbr})
        return len(self.doc["materials"]) - 1

    def mesh(self, name: str, mesh, material: int) -> int:
        """A TriMesh (vdmbake.assets.meshes) as a mesh of one triangle primitive; returns its node."""
        attrs = {"POSITION": self.accessor(mesh.vertices, "VEC3"),
                 "NORMAL": self.accessor(unit(mesh.normals), "VEC3")}
        if mesh.uvs is not None and mesh.texture is not None:
            attrs["TEXCOORD_0"] = self.accessor(np.column_stack([mesh.uvs[:, 0], 1.0 - mesh.uvs[:, 1]]), "VEC2")
        if mesh.colors is not None:
            attrs["COLOR_0"] = self.accessor(mesh.colors, "VEC3")
        name = safe(name)
        self.doc["meshes"].append({"name": name, "primitives": [
            {"attributes": attrs, "indices": self.accessor(mesh.faces.ravel(), "SCALAR", indices=True),
             "material": material, "mode": 4}]})
        self.doc["nodes"].append({"name": name, "mesh": len(self.doc["meshes"]) - 1})
        return len(self.doc["nodes"]) - 1

    def lod(self, levels: list[int], coverage: list[float], up, notes: list[str] = ()) -> None:
        """Node levels[0] the finest level, the rest its lower levels (MSFT_lod), each shown down to its
        coverage; every level node turns `up` to +Y itself (MSFT_lod's lower levels are no node's children, so an
        importer that places them apart, as Blender does, still places them in the scene's orientation); the
        finest is the scene's only root. `notes`: what the export said about the chain (asset.extras)."""
        first = self.doc["nodes"][levels[0]]
        if len(levels) > 1:
            first["extensions"] = {"MSFT_lod": {"ids": levels[1:]}}
            self.doc["extensionsUsed"] = ["MSFT_lod"]
        first["extras"] = {"MSFT_screencoverage": [float(c) for c in coverage]}
        for n in levels:
            self.doc["nodes"][n]["rotation"] = up_to_y(up)
        self.doc["scenes"].append({"nodes": [levels[0]]})
        if notes:
            self.doc["asset"]["extras"] = {"vdmexport": list(notes)}

    def save(self, path: Path) -> None:
        """PATH.gltf and PATH.bin (its one buffer)."""
        bin_path = path.with_suffix(".bin")
        self.doc["buffers"] = [{"uri": bin_path.name, "byteLength": len(self.blob)}]
        bin_path.write_bytes(bytes(self.blob))
        path.write_text(json.dumps({k: v for k, v in self.doc.items() if v != []}, indent=1) + "\n")


def safe(name: str) -> str:
    """A name importers keep as it is: Blender reads '.' as its own duplicate suffix (it renamed "coarse@0.03"),
    three.js turns spaces, '.' and other characters to '_'; so '.' becomes 'p' (0.03: 0p03), anything outside
    A-Z a-z 0-9 _ - becomes '_'."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", name.replace(".", "p"))


def unit(v: np.ndarray) -> np.ndarray:
    """Rows scaled to unit length in float32 (the validator checks |n| = 1 within 0.0005); zero rows stay +Z."""
    v = np.asarray(v, np.float64)
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(n > 0, v / np.where(n > 0, n, 1.0), [0.0, 0.0, 1.0]).astype(np.float32)


def up_to_y(up) -> list[float]:
    """The unit quaternion [x, y, z, w] of the shortest rotation taking `up` to +Y (half-way vector form, stable
    but for up = -Y, where any half turn about a horizontal axis will do)."""
    u = np.asarray(up, float) / np.linalg.norm(up)
    h = u + [0.0, 1.0, 0.0]
    if np.linalg.norm(h) < 1e-9:
        return [1.0, 0.0, 0.0, 0.0]
    h /= np.linalg.norm(h)
    axis = np.cross(u, h)
    q = [*axis, float(np.dot(u, h))]
    return [float(x) / math.sqrt(sum(c * c for c in q)) for x in q]
