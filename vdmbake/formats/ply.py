"""Binary little-endian PLY for the bundle: meshes (vertex + face) and quadric lists (sphere,
cylinder elements), as MeshLab and trimesh read them.

Elements are numpy structured arrays; a sub-array field is written as a PLY list whose count
is the field before it (faces: n, vertex_indices). Positions are float64 ('double') so objects
far from the origin keep their precision. The writer is deterministic: same data, same bytes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..common.mesh import SurfaceFrame, TriMesh

_TYPES = {"<f8": "double", "<f4": "float", "|u1": "uchar", "<i4": "int"}
_DTYPES = {v: k for k, v in _TYPES.items()}
_FACE = np.dtype([("n", "u1"), ("vertex_indices", "<i4", (3,))])


def _properties(dt: np.dtype) -> str:
    lines = []
    for name in dt.names:
        field = dt.fields[name][0]
        if field.shape:  # a list: its count is the previous field
            count = lines.pop().split()[1]
            lines.append(f"property list {count} {_TYPES[field.base.str]} {name}")
        else:
            lines.append(f"property {_TYPES[field.str]} {name}")
    return "".join(line + "\n" for line in lines)


def elements_to_bytes(elements: dict[str, np.ndarray], comment: str) -> bytes:
    header = f"ply\nformat binary_little_endian 1.0\ncomment {comment}\n" + "".join(
        f"element {name} {len(a)}\n{_properties(a.dtype)}" for name, a in elements.items()) + "end_header\n"
    return header.encode("ascii") + b"".join(np.ascontiguousarray(a).tobytes() for a in elements.values())


def elements_from_bytes(data: bytes, origin: str) -> dict[str, np.ndarray]:
    """Read what elements_to_bytes wrote (lists are taken as triangles: 3 items each)."""
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0 or b"binary_little_endian" not in data[:end]:
        raise InputError(f"{origin}: not a binary PLY file written by vdmbake.")
    specs: list[tuple[str, int, list]] = []
    try:
        for line in data[:end].decode("ascii").splitlines():
            w = line.split()
            if w[0] == "element":
                specs.append((w[1], int(w[2]), []))
            elif w[0] == "property" and w[1] == "list":
                specs[-1][2].extend([("n", _DTYPES[w[2]]), (w[4], _DTYPES[w[3]], (3,))])
            elif w[0] == "property":
                specs[-1][2].append((w[2], _DTYPES[w[1]]))
    except (IndexError, KeyError, ValueError) as e:
        raise InputError(f"{origin}: malformed PLY header ({e}).") from None
    offset, out = end + len(b"end_header\n"), {}
    for name, count, fields in specs:
        dt = np.dtype(fields)
        if len(data) < offset + count * dt.itemsize:
            raise InputError(f"{origin}: PLY body shorter than its header says (truncated file?).")
        out[name] = np.frombuffer(data, dt, count, offset)
        offset += count * dt.itemsize
    if offset != len(data):
        raise InputError(f"{origin}: PLY body size does not match its header.")
    return out


def to_bytes(mesh: TriMesh) -> bytes:
    fields = [(n, "<f8") for n in "xyz"] + [(n, "<f4") for n in ("nx", "ny", "nz")]
    if mesh.uvs is not None:
        fields += [("texture_u", "<f4"), ("texture_v", "<f4")]
    if mesh.frame is not None:
        fields += [(n, "<f4") for n in _FRAME_NAMES]
    if mesh.colors is not None:
        fields += [(n, "<f4") for n in _COLOR_NAMES]
    v = np.zeros(len(mesh.vertices), fields)
    for k, name in enumerate("xyz"):
        v[name] = mesh.vertices[:, k]
        v["n" + name] = mesh.normals[:, k]
    if mesh.uvs is not None:
        v["texture_u"], v["texture_v"] = mesh.uvs[:, 0], mesh.uvs[:, 1]
    if mesh.frame is not None:
        for name, column in zip(_FRAME_NAMES, _frame_columns(mesh.frame)):
            v[name] = column
    if mesh.colors is not None:
        for name, column in zip(_COLOR_NAMES, mesh.colors.T):
            v[name] = column
    f = np.zeros(len(mesh.faces), _FACE)
    f["n"], f["vertex_indices"] = 3, mesh.faces
    return elements_to_bytes({"vertex": v, "face": f}, "vdmbake mesh")


def from_bytes(data: bytes, origin: str) -> TriMesh:
    e = elements_from_bytes(data, origin)
    if "vertex" not in e or "face" not in e:
        raise InputError(f"{origin}: PLY file lacks vertex or face elements.")
    v, f = e["vertex"], e["face"]
    uvs = np.stack([v["texture_u"], v["texture_v"]], 1).astype(np.float64) if "texture_u" in v.dtype.names else None
    frame = None
    if set(_FRAME_NAMES) <= set(v.dtype.names):
        col = {n: v[n].astype(np.float64) for n in _FRAME_NAMES}
        vec = lambda p: np.stack([col[f"{p}_x"], col[f"{p}_y"], col[f"{p}_z"]], 1)  # noqa: E731
        frame = SurfaceFrame(vec("dpdu"), vec("dpdv"), col["k1"], col["k2"], vec("d1"))
    colors = (np.stack([v[n] for n in _COLOR_NAMES], 1).astype(np.float64)
              if set(_COLOR_NAMES) <= set(v.dtype.names) else None)
    return TriMesh(np.stack([v["x"], v["y"], v["z"]], 1), f["vertex_indices"].astype(np.int64),
                   np.stack([v["nx"], v["ny"], v["nz"]], 1).astype(np.float64), uvs, frame, colors)


# The asset's per-vertex albedo (linear RGB in [0, 1], float), only when the asset has colours.
_COLOR_NAMES = ("red", "green", "blue")

# The surface frame (common.mesh.SurfaceFrame) as extra vertex properties, for VDM base meshes.
_FRAME_NAMES = tuple(f"{p}_{a}" for p in ("dpdu", "dpdv") for a in "xyz") + ("k1", "k2", "d1_x", "d1_y", "d1_z")


def _frame_columns(f: SurfaceFrame) -> list[np.ndarray]:
    return [*f.dpdu.T, *f.dpdv.T, f.k1, f.k2, *f.d1.T]


def write(path: Path, mesh: TriMesh) -> None:
    Path(path).write_bytes(to_bytes(mesh))
