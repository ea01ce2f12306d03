"""Binary PLY for the bundle's meshes: positions, normals and optional UVs, as MeshLab reads them.

Positions are float64 ('double'), so objects far from the origin keep their precision;
normals and UVs are float32. The writer is deterministic: same mesh, same bytes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InputError
from .meshes import TriMesh

_POS = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
_NRM = [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")]
_UV = [("texture_u", "<f4"), ("texture_v", "<f4")]
_PLY_TYPES = {"<f8": "double", "<f4": "float"}
_FACE = np.dtype([("n", "u1"), ("i", "<i4", (3,))])


def _vertex_dtype(with_uv: bool) -> np.dtype:
    return np.dtype(_POS + _NRM + (_UV if with_uv else []))


def to_bytes(mesh: TriMesh) -> bytes:
    dt = _vertex_dtype(mesh.uvs is not None)
    v = np.zeros(len(mesh.vertices), dt)
    for k, name in enumerate("xyz"):
        v[name] = mesh.vertices[:, k]
        v["n" + name] = mesh.normals[:, k]
    if mesh.uvs is not None:
        v["texture_u"], v["texture_v"] = mesh.uvs[:, 0], mesh.uvs[:, 1]
    f = np.zeros(len(mesh.faces), _FACE)
    f["n"], f["i"] = 3, mesh.faces
    props = "".join(f"property {_PLY_TYPES[dt.fields[n][0].str]} {n}\n" for n in dt.names)
    header = (f"ply\nformat binary_little_endian 1.0\ncomment vdmbake mesh\n"
              f"element vertex {len(v)}\n{props}"
              f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    return header.encode("ascii") + v.tobytes() + f.tobytes()


def from_bytes(data: bytes, origin: str) -> TriMesh:
    """Read back what to_bytes wrote (the bundle's own layout only)."""
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise InputError(f"{origin}: not a PLY file written by vdmbake.")
    lines = data[:end].decode("ascii").splitlines()
    try:
        nv = next(int(line.split()[2]) for line in lines if line.startswith("element vertex"))
        nf = next(int(line.split()[2]) for line in lines if line.startswith("element face"))
    except StopIteration:
        raise InputError(f"{origin}: PLY header lacks vertex or face counts.") from None
    dt = _vertex_dtype(any(line.endswith("texture_u") for line in lines))
    body = end + len(b"end_header\n")
    if len(data) != body + nv * dt.itemsize + nf * _FACE.itemsize:
        raise InputError(f"{origin}: PLY body size does not match its header (truncated file?).")
    v = np.frombuffer(data, dt, nv, body)
    f = np.frombuffer(data, _FACE, nf, body + nv * dt.itemsize)
    uvs = np.stack([v["texture_u"], v["texture_v"]], 1).astype(np.float64) if "texture_u" in dt.names else None
    return TriMesh(np.stack([v["x"], v["y"], v["z"]], 1),
                   f["i"].astype(np.int64),
                   np.stack([v["nx"], v["ny"], v["nz"]], 1).astype(np.float64), uvs)


def write(path: Path, mesh: TriMesh) -> None:
    Path(path).write_bytes(to_bytes(mesh))
