"""A bundle reader written from docs/bundle.md alone, and checks that what it reads means what the
specification says it means.

The reader (`SpecReader` and the helpers around it) uses only the standard library, numpy and the
OpenEXR package. `vdmbake` is imported for two things only: baking the scenes (its CLI, in-process)
and, in `test_reader_agrees_with_project_unpacking` and `test_albedo_lookup_agrees_with_project`, the
project's own unpacking to compare with.

Where the specification left something open, the tests follow what the bytes contain and say so
("found by experiment") next to the check.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import pathlib
import shutil

import numpy as np
import OpenEXR
import pytest

# --------------------------------------------------------------------------------------------------
# Scenes (syntax: README's Scenes section and configs/*.toml). Tiny, so that both bakes take ~1 s.
# --------------------------------------------------------------------------------------------------

HEAD = """\
[render]
resolution = [32, 32]
repeats = 1
warmup = 0
shadow_map = 256

[camera]
orbit = { count = 1 }
"""

TORUS = dict(major=1.0, minor=0.35, segments=24, rings=12)
TORUS_MESO = dict(size=16, depth=0.06, tiling=(4, 2), phi=8, theta=4, curvatures=3)
PLANE_MESO = dict(size=16, depth=0.05, tiling=(2, 2), phi=8, theta=4)
FLAT = dict(major=1.0, minor=0.35, segments=16, rings=8)
FLAT_TRANSFORM = dict(scale=0.5, rotate_deg=(90.0, 0.0, 30.0), translate=(3.0, 0.0, 0.0))
FLAT_MESO = dict(size=8, depth=0.05, tiling=(4, 2), phi=4, theta=4, curvatures=2)

MESO_SCENE = HEAD + f"""
[[objects]]
name = "torus"
primitive = "torus"
params = {{ major = {TORUS['major']}, minor = {TORUS['minor']}, segments = {TORUS['segments']}, rings = {TORUS['rings']} }}

[objects.mesostructure]
height = "bricks"
size = {TORUS_MESO['size']}
depth = {TORUS_MESO['depth']}
tiling = [{TORUS_MESO['tiling'][0]}, {TORUS_MESO['tiling'][1]}]
phi = {TORUS_MESO['phi']}
theta = {TORUS_MESO['theta']}
curvatures = {TORUS_MESO['curvatures']}

[objects.techniques]
mesh = {{}}
coarse = {{ ratios = [0.5, 0.25] }}
vdm = {{ k = [2, "all"] }}
displaced = {{ levels = [1, 2] }}
bump = {{}}

[[objects]]
name = "plane"
primitive = "plane"
params = {{ size = 2.0, segments = 4 }}

[objects.mesostructure]
height = "bricks"
size = {PLANE_MESO['size']}
depth = {PLANE_MESO['depth']}
tiling = [{PLANE_MESO['tiling'][0]}, {PLANE_MESO['tiling'][1]}]
phi = {PLANE_MESO['phi']}
theta = {PLANE_MESO['theta']}

[objects.techniques]
vdm = {{ k = ["all"] }}

[[objects]]
name = "flat"
primitive = "torus"
params = {{ major = {FLAT['major']}, minor = {FLAT['minor']}, segments = {FLAT['segments']}, rings = {FLAT['rings']} }}
transform = {{ scale = {FLAT_TRANSFORM['scale']}, rotate_deg = [90, 0, 30], translate = [3, 0, 0] }}

[objects.mesostructure]
height = "flat"
size = {FLAT_MESO['size']}
depth = {FLAT_MESO['depth']}
tiling = [{FLAT_MESO['tiling'][0]}, {FLAT_MESO['tiling'][1]}]
phi = {FLAT_MESO['phi']}
theta = {FLAT_MESO['theta']}
curvatures = {FLAT_MESO['curvatures']}

[objects.techniques]
vdm = {{ k = [4] }}
"""

BALL = dict(radius=0.8, centre=(0.5, -1.0, 2.0), segments=24, rings=12, resolution=16, views=5, view_resolution=24)
SPHERES = [[0, 0, 0, 1.0], [2, 0, 0, 0.5], [5, 5, 5, 0.0]]  # the last has no volume
CYLINDERS = [[0, 0, 0, 2, 0, 0, 0.2], [0, 0, 0, 0, 0, 1.5, 0.1],
             [1, 1, 1, 1, 1, 1, 0.3], [1, 1, 1, 2, 2, 2, 0.0]]  # the last two have no volume
ATOMS_ALBEDO = (0.2, 0.4, 0.6)

SHAPES_SCENE = HEAD + f"""
[[objects]]
name = "ball"
primitive = "sphere"
params = {{ radius = {BALL['radius']}, segments = {BALL['segments']}, rings = {BALL['rings']} }}
transform = {{ translate = [{BALL['centre'][0]}, {BALL['centre'][1]}, {BALL['centre'][2]}] }}
techniques = {{ mesh = {{}}, billboards = {{ variants = ["greedy-improved+coarse", "greedy-hier", "axis-hit0.01"], resolution = {BALL['resolution']}, coarse_ratio = 0.25 }}, octahedral = {{ variants = ["full-{BALL['views']}x{BALL['view_resolution']}-march", "full-{BALL['views']}x{BALL['view_resolution']}-virtual"] }} }}

[[objects]]
name = "atoms"
spheres = {json.dumps(SPHERES)}
cylinders = {json.dumps(CYLINDERS)}
material = {{ albedo = [{ATOMS_ALBEDO[0]}, {ATOMS_ALBEDO[1]}, {ATOMS_ALBEDO[2]}] }}
techniques = {{ impostor = {{}} }}
"""


TILE = (6, 4)   # the colour tile's picture: width, height
ALBEDO_SCENE = HEAD + """
[[objects]]
name = "wall"
primitive = "plane"
params = { size = 2.0, segments = 2 }

[objects.mesostructure]
height = "bricks"
albedo = "tile.png"
size = 8
tiling = [2, 3]

[objects.techniques]
displaced = { levels = [0, 1] }
"""


def tile_picture() -> np.ndarray:
    """The colour tile's pixels (rows top first, as written to tile.png): every texel different."""
    h, w = TILE[1], TILE[0]
    r, c = np.mgrid[0:h, 0:w]
    return np.stack([40 * c + 10, 50 * r + 20, 7 * (r * w + c) + 3], -1).astype(np.uint8)


# A vertex-coloured mesh file (PLY red/green/blue, 8-bit sRGB): an icosphere coloured by its direction, with
# billboards and an octahedral atlas, whose parts then carry colour maps (spec: only for assets with colours).
PAINTED = dict(subdivisions=3, resolution=16, views=5, view_resolution=24)

PAINTED_SCENE = HEAD + f"""
[[objects]]
name = "painted"
mesh = "painted.ply"
techniques = {{ billboards = {{ variants = ["greedy-hier+coarse"], resolution = {PAINTED['resolution']}, coarse_ratio = 0.25 }}, octahedral = {{ variants = ["full-{PAINTED['views']}x{PAINTED['view_resolution']}-march"] }} }}
"""


def painted_rgb8(d: np.ndarray) -> np.ndarray:
    """The painted sphere's 8-bit sRGB colour in direction d (unit rows)."""
    return np.round(255 * (0.5 + 0.45 * d)).astype(np.uint8)


def _bake(tmp: pathlib.Path, name: str, text: str) -> pathlib.Path:
    from click.testing import CliRunner

    from vdmbake.cli import main as bake_main  # baking only

    scene, bundle = tmp / f"{name}.toml", tmp / f"{name}.bundle"
    scene.write_text(text)
    result = CliRunner().invoke(bake_main, [str(scene), "-o", str(bundle)])
    assert result.exit_code == 0, result.output
    return bundle


@pytest.fixture(scope="module")
def meso_bundle(tmp_path_factory) -> pathlib.Path:
    return _bake(tmp_path_factory.mktemp("meso"), "meso", MESO_SCENE)


@pytest.fixture(scope="module")
def shapes_bundle(tmp_path_factory) -> pathlib.Path:
    return _bake(tmp_path_factory.mktemp("shapes"), "shapes", SHAPES_SCENE)


@pytest.fixture(scope="module")
def albedo(tmp_path_factory):
    from PIL import Image   # writing the scene's input picture only

    tmp = tmp_path_factory.mktemp("albedo")
    Image.fromarray(tile_picture(), "RGB").save(tmp / "tile.png")
    return SpecReader(_bake(tmp, "albedo", ALBEDO_SCENE))


@pytest.fixture(scope="module")
def painted_bundle(tmp_path_factory) -> pathlib.Path:
    import trimesh   # writes the input asset only; the reader below does not use it

    tmp = tmp_path_factory.mktemp("painted")
    sphere = trimesh.creation.icosphere(PAINTED["subdivisions"])
    rgb = painted_rgb8(unit_rows(np.asarray(sphere.vertices)))
    sphere.visual = trimesh.visual.ColorVisuals(sphere, vertex_colors=np.concatenate([rgb, np.full((len(rgb), 1), 255, np.uint8)], 1))
    sphere.export(tmp / "painted.ply")
    return _bake(tmp, "painted", PAINTED_SCENE)


@pytest.fixture(scope="module")
def painted(painted_bundle):
    return SpecReader(painted_bundle)


@pytest.fixture(scope="module")
def meso(meso_bundle):
    return SpecReader(meso_bundle)


@pytest.fixture(scope="module")
def shapes(shapes_bundle):
    return SpecReader(shapes_bundle)


# --------------------------------------------------------------------------------------------------
# The reader, from docs/bundle.md only.
# --------------------------------------------------------------------------------------------------


class BundleError(ValueError):
    """The bundle is not what the specification describes."""


class ChecksumError(BundleError):
    """A part's bytes do not match the sha256 (or size) the manifest records for it."""


# PLY scalar types (the spec uses double, float, uchar, int; the rest are the PLY standard's).
PLY_TYPES = {
    "char": "i1", "uchar": "u1", "short": "<i2", "ushort": "<u2", "int": "<i4", "uint": "<u4",
    "float": "<f4", "double": "<f8", "int8": "i1", "uint8": "u1", "int16": "<i2", "uint16": "<u2",
    "int32": "<i4", "uint32": "<u4", "float32": "<f4", "float64": "<f8",
}

MESH_PROPS = (
    [("x", "double"), ("y", "double"), ("z", "double"), ("nx", "float"), ("ny", "float"), ("nz", "float")],
    [("texture_u", "float"), ("texture_v", "float")],
    [(f"dpdu_{a}", "float") for a in "xyz"] + [(f"dpdv_{a}", "float") for a in "xyz"]
    + [("k1", "float"), ("k2", "float")] + [(f"d1_{a}", "float") for a in "xyz"],
)
SPHERE_PROPS = [(a, "double") for a in ("x", "y", "z", "radius")] + [(c, "float") for c in ("red", "green", "blue")]
CYLINDER_PROPS = ([(a, "double") for a in ("x0", "y0", "z0", "x1", "y1", "z1", "radius")]
                  + [(c, "float") for c in ("red", "green", "blue")])


class PlyFile:
    def __init__(self, comments, elements, schema):
        self.comments = comments        # ["vdmbake mesh"]
        self.elements = elements        # {name: structured array}
        self.schema = schema            # {name: [(property, type) or (property, "list", count type, item type)]}


class ExrPart:
    def __init__(self, name, channels, header, channel_types):
        self.name = name
        self.channels = channels        # {channel name: 2-D float32 array [row, column]}
        self.header = header
        self.channel_types = channel_types


class SpecReader:
    """Reads a `vdm-bundle` (format version 2) following docs/bundle.md."""

    def __init__(self, root):
        self.root = pathlib.Path(root)
        if not (self.root / "manifest.json").is_file():
            raise BundleError(f"{self.root}: no manifest.json, not a bundle")
        self.manifest = json.loads((self.root / "manifest.json").read_text())
        if self.manifest.get("format") != "vdm-bundle" or self.manifest.get("format_version") != 2:
            raise BundleError(f"{self.root}: format {self.manifest.get('format')!r} "
                              f"version {self.manifest.get('format_version')!r}, want vdm-bundle 2")

    # ---- bytes -----------------------------------------------------------------------------------
    def part_bytes(self, rel: str, kind: str | None = None) -> bytes:
        entry = self.manifest["parts"].get(rel)
        if entry is None:
            raise BundleError(f"{rel}: not listed in the manifest")
        if kind is not None and entry["kind"] != kind:
            raise BundleError(f"{rel}: kind {entry['kind']!r}, want {kind!r}")
        pure = pathlib.PurePosixPath(rel)
        if pure.is_absolute() or ".." in pure.parts or "\\" in rel:
            raise BundleError(f"{rel}: leaves the bundle folder")
        data = (self.root / pure).read_bytes()
        if len(data) != entry["bytes"] or hashlib.sha256(data).hexdigest() != entry["sha256"]:
            raise ChecksumError(f"{rel}: sha256/size differ from the manifest")
        return data

    # ---- PLY ---------------------------------------------------------------------------------------
    def ply(self, rel: str, kind: str | None = None) -> PlyFile:
        data = self.part_bytes(rel, kind)
        marker = b"end_header\n"
        end = data.index(marker) + len(marker)
        lines = data[:end].decode("ascii").splitlines()
        if lines[0] != "ply" or lines[1] != "format binary_little_endian 1.0":
            raise BundleError(f"{rel}: not a binary little-endian PLY: {lines[:2]}")
        comments, order, schema, counts = [], [], {}, {}
        for line in lines[2:-1]:
            w = line.split()
            if w[0] == "comment":
                comments.append(line[len("comment "):])
            elif w[0] == "element":
                order.append(w[1])
                counts[w[1]] = int(w[2])
                schema[w[1]] = []
            elif w[0] == "property" and w[1] == "list":
                schema[order[-1]].append((w[4], "list", w[2], w[3]))
            elif w[0] == "property":
                schema[order[-1]].append((w[2], w[1]))
            else:
                raise BundleError(f"{rel}: unexpected header line {line!r}")
        elements, offset = {}, end
        for name in order:
            count, props = counts[name], schema[name]
            if any(p[1] == "list" for p in props):
                arr, offset = _read_list_element(data, offset, count, props)
            else:
                dt = np.dtype([(p, PLY_TYPES[t]) for p, t in props])
                arr = np.frombuffer(data, dt, count, offset)
                offset += count * dt.itemsize
            elements[name] = arr
        if offset != len(data):
            raise BundleError(f"{rel}: {len(data) - offset} bytes after the last element")
        return PlyFile(comments, elements, schema)

    # ---- EXR ---------------------------------------------------------------------------------------
    def exr(self, rel: str, kind: str | None = None) -> dict[str, ExrPart]:
        data = self.part_bytes(rel, kind)
        out = {}
        with OpenEXR.File(io.BytesIO(data), separate_channels=True) as f:
            for p in f.parts:
                chans = {c: np.array(ch.pixels) for c, ch in p.channels.items()}
                types = {c: str(ch.type()) for c, ch in p.channels.items()}
                out[p.name()] = ExrPart(p.name(), chans, dict(p.header), types)
        return out

    # ---- part kinds ---------------------------------------------------------------------------------
    def albedo_map(self, rel: str) -> np.ndarray:
        """(H, W, 3) linear albedo, row 0 at v = 0 (the PNG's bottom row)."""
        from PIL import Image

        img = Image.open(io.BytesIO(self.part_bytes(rel, "albedo-map")))
        meta = self.manifest["parts"][rel]
        assert img.format == "PNG" and img.mode == "RGB" and img.size == (meta["width"], meta["height"])
        c = np.asarray(img, np.float64)[::-1] / 255.0
        return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)

    def mesh(self, rel: str) -> dict:
        ply = self.ply(rel, "mesh")
        v, f = ply.elements["vertex"], ply.elements["face"]
        out = {
            "comments": ply.comments,
            "props": [p[0] for p in ply.schema["vertex"]],
            "vertices": np.stack([v[a] for a in "xyz"], 1),
            "normals": np.stack([v[a] for a in ("nx", "ny", "nz")], 1),
            "faces": f["vertex_indices"],
            "face_sizes": f["vertex_indices__count"],
        }
        if "texture_u" in v.dtype.names:
            out["uvs"] = np.stack([v["texture_u"], v["texture_v"]], 1)
        if "red" in v.dtype.names:
            out["colors"] = np.stack([v[c] for c in ("red", "green", "blue")], 1)
        if "dpdu_x" in v.dtype.names:
            out["dpdu"] = np.stack([v[f"dpdu_{a}"] for a in "xyz"], 1)
            out["dpdv"] = np.stack([v[f"dpdv_{a}"] for a in "xyz"], 1)
            out["k1"], out["k2"] = np.array(v["k1"]), np.array(v["k2"])
            out["d1"] = np.stack([v[f"d1_{a}"] for a in "xyz"], 1)
        return out

    def quadrics(self, rel: str) -> dict:
        ply = self.ply(rel, "quadrics")
        s, c = ply.elements["sphere"], ply.elements["cylinder"]
        return {
            "comments": ply.comments, "schema": ply.schema,
            "spheres": np.stack([s[a] for a in ("x", "y", "z", "radius")], 1).reshape(-1, 4),
            "sphere_rgb": np.stack([s[a] for a in ("red", "green", "blue")], 1).reshape(-1, 3),
            "cylinders": np.stack([c[a] for a in ("x0", "y0", "z0", "x1", "y1", "z1", "radius")], 1).reshape(-1, 7),
            "cylinder_rgb": np.stack([c[a] for a in ("red", "green", "blue")], 1).reshape(-1, 3),
        }

    def mesostructure(self, rel: str) -> dict:
        x = self.exr(rel, "mesostructure")
        return {"heights": x["height"].channels["h"],
                "normals": np.stack([x["normal"].channels[f"normal.{c}"] for c in "XYZ"], -1)}

    def vdm(self, rel: str) -> dict:
        x = self.exr(rel, "vdm")
        meta = self.manifest["parts"][rel]
        k, n_phi = meta["k"], meta["n_phi"]
        w = np.stack([x["W"].channels[f"W.{i:03d}"] for i in range(k)], -1)     # (n_phi*N, N, k)
        if meta["storage"] == "uint8":                  # codes: weight = code * scale + offset per eigenfunction
            w = w.astype(np.float32) * x["W_dequant"].channels["scale"][0] + x["W_dequant"].channels["offset"][0]
        n = w.shape[1]
        if w.shape[0] != n_phi * n:
            raise BundleError(f"{rel}: W has {w.shape[0]} rows, want n_phi * N = {n_phi * n}")
        return {
            "W": w.reshape(n_phi, n, n, k),                                                    # [phi, y, x, i]
            "E_vdm": np.stack([x["E_vdm"].channels[f"E.{i:03d}"] for i in range(k)], 0),   # [i, c, theta]
            "E_mvm": np.stack([x["E_mvm"].channels[f"E.{i:03d}"] for i in range(k)], 0)[:, 0, :],  # [i, c]
        }

    def billboards(self, rel: str) -> list[dict]:
        x = self.exr(rel, "billboards")
        boards = self.manifest["parts"][rel]["boards"]
        coloured = self.manifest["parts"][rel].get("albedo", False)
        names = [f"bb{i:03d}" for i in range(len(boards))]
        if sorted(x) != names:
            raise BundleError(f"{rel}: EXR parts {sorted(x)}, want {names}")
        out = []
        for name, box in zip(names, boards):
            ch = x[name].channels
            out.append({
                "A": ch["A"], "depth": ch["depth.Z"],
                "normal": np.stack([ch[f"normal.{c}"] for c in "XYZ"], -1),
                "origin": np.array(box["origin"], float), "axes": np.array(box["axes"], float),
                "size": np.array(box["size"], float),
                **({"albedo": np.stack([ch[f"albedo.{c}"] for c in "RGB"], -1)} if coloured else {}),
            })
        return out

    def octahedral(self, rel: str) -> dict:
        x = self.exr(rel, "octahedral")
        if sorted(x) != ["atlas"]:
            raise BundleError(f"{rel}: EXR parts {sorted(x)}, want ['atlas']")
        ch, meta = x["atlas"].channels, self.manifest["parts"][rel]
        colour = {"albedo": np.stack([ch[f"albedo.{c}"] for c in "RGB"], -1)} if meta.get("albedo", False) else {}
        return {"A": ch["A"], "depth": ch["depth.Z"], "code": np.stack([ch["normal.U"], ch["normal.V"]], -1), **colour,
                **{k: meta[k] for k in ("views", "resolution", "hemi", "radius", "capture", "rays")},
                "basis": np.array(meta["basis"], float), "centre": np.array(meta["centre"], float)}


def _read_list_element(data, offset, count, props):
    """An element with list properties. The spec promises three indices per face, so the common case
    is one structured read; anything else is read row by row."""
    fields = []
    for p in props:
        if p[1] == "list":
            fields += [(p[0] + "__count", PLY_TYPES[p[2]]), (p[0], PLY_TYPES[p[3]], (3,))]
        else:
            fields.append((p[0], PLY_TYPES[p[1]]))
    dt = np.dtype(fields)
    if offset + count * dt.itemsize <= len(data):
        arr = np.frombuffer(data, dt, count, offset)
        if all((arr[p[0] + "__count"] == 3).all() for p in props if p[1] == "list"):
            return arr, offset + count * dt.itemsize
    raise BundleError("faces that are not triangles (the spec says three indices each)")


def vdm_reconstruct(t: dict):
    """The spec's formulas: d[phi, y, x, c, theta] and theta_MVM[phi, y, x, c]."""
    d = np.einsum("pyxi,ict->pyxct", t["W"].astype(np.float64), t["E_vdm"].astype(np.float64))
    mvm = np.einsum("pyxi,ic->pyxc", t["W"].astype(np.float64), t["E_mvm"].astype(np.float64))
    return d, mvm


def bilinear(img: np.ndarray, u, v):
    """Periodic bilinear interpolation of a mesostructure map at tile coordinates (u, v): texel
    [i, j] centred at ((j + 0.5) / N, (i + 0.5) / N)."""
    n = img.shape[0]
    x, y = np.asarray(u, float) * n - 0.5, np.asarray(v, float) * n - 0.5
    j0, i0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - j0, y - i0
    if img.ndim == 3:
        fx, fy = fx[..., None], fy[..., None]
    g = lambda i, j: img[i % n, j % n].astype(np.float64)  # noqa: E731
    return (g(i0, j0) * (1 - fx) * (1 - fy) + g(i0, j0 + 1) * fx * (1 - fy)
            + g(i0 + 1, j0) * (1 - fx) * fy + g(i0 + 1, j0 + 1) * fx * fy)


def rotation(rotate_deg) -> np.ndarray:
    """Rotations about X, then Y, then Z (README/spec: scale, rotations about X, Y, Z, translation)."""
    ax, ay, az = np.radians(rotate_deg)
    rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
    return rz @ ry @ rx


def torus_frame(p, major, minor):
    """For points near the z-axis torus: tube-circle point, outward normal, ring and tube tangents,
    tube angle cosine."""
    rho = np.hypot(p[:, 0], p[:, 1])
    ring = np.stack([p[:, 0] / rho, p[:, 1] / rho, np.zeros_like(rho)], 1)
    c = major * ring
    n = (p - c) / np.linalg.norm(p - c, axis=1)[:, None]
    e_ring = np.stack([-ring[:, 1], ring[:, 0], np.zeros_like(rho)], 1)
    e_tube = np.cross(n, e_ring)
    cos_v = np.sum(n * ring, 1)
    return c, n, e_ring, e_tube, cos_v


def unit_rows(a):
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def nearest(points: np.ndarray, cloud: np.ndarray):
    """Index in `cloud` of each point's nearest neighbour, and the distance."""
    d2 = np.sum(points ** 2, 1)[:, None] + np.sum(cloud ** 2, 1)[None, :] - 2 * points @ cloud.T
    idx = d2.argmin(1)
    return idx, np.linalg.norm(cloud[idx] - points, axis=1)


def tangent_jacobian(mesh, tiling):
    """J = [dpdu / tiling_u, dpdv / tiling_v] projected into the tangent plane, and s_n (spec, mesostructure)."""
    n = mesh["normals"].astype(np.float64)
    proj = lambda a: a - np.sum(a * n, 1)[:, None] * n  # noqa: E731
    ju = proj(mesh["dpdu"].astype(np.float64) / tiling[0])
    jv = proj(mesh["dpdv"].astype(np.float64) / tiling[1])
    s_n = np.sqrt(np.linalg.norm(np.cross(ju, jv), axis=1))
    return ju, jv, s_n


# --------------------------------------------------------------------------------------------------
# Manifest, files, checksums
# --------------------------------------------------------------------------------------------------


def test_manifest_lists_every_part_with_checksum(meso, shapes):
    """format/version; every file but manifest.json and timing.json is a part with the right size
    and sha256; part paths are relative POSIX paths inside the folder; stats add up; object entries
    point at parts of the right kind; timing.json has the documented keys."""
    for r in (meso, shapes):
        m = r.manifest
        assert (m["format"], m["format_version"]) == ("vdm-bundle", 2)
        assert len(m["input_hash"]) == 64 and int(m["input_hash"], 16) >= 0
        on_disk = {p.relative_to(r.root).as_posix() for p in r.root.rglob("*") if p.is_file()}
        # "parts: every file of the bundle": in fact every file except manifest.json and timing.json.
        assert on_disk - set(m["parts"]) == {"manifest.json", "timing.json"}
        assert set(m["parts"]) <= on_disk
        for rel, entry in m["parts"].items():
            assert not rel.startswith("/") and ".." not in rel.split("/") and "\\" not in rel
            assert entry["kind"] in {"mesh", "quadrics", "mesostructure", "vdm", "billboards", "bordered-billboards", "octahedral"}
            r.part_bytes(rel, entry["kind"])  # checksum and size
        assert m["stats"]["objects"] == len(m["objects"])
        assert m["stats"]["parts"] == len(m["parts"])
        assert m["stats"]["bytes"] == sum(e["bytes"] for e in m["parts"].values())
        for name, obj in m["objects"].items():
            assert obj["kind"] in {"surface", "quadrics"}
            assert len(obj["centre"]) == 3 and obj["radius"] > 0
            if obj["kind"] == "surface":
                assert m["parts"][obj["mesh"]]["kind"] == "mesh"
            else:
                assert m["parts"][obj["quadrics"]]["kind"] == "quadrics"
            if "mesostructure" in obj:
                assert m["parts"][obj["mesostructure"]]["kind"] == "mesostructure"
        timing = json.loads((r.root / "timing.json").read_text())
        assert timing["bake_s"] >= 0 and set(timing["objects_s"]) == set(m["objects"])
    t = meso.manifest["objects"]["torus"]["techniques"]
    # techniques that need nothing beyond the object's parts have no entry
    assert set(t) == {"coarse", "vdm", "displaced"}
    assert meso.manifest["objects"]["plane"]["techniques"].keys() == {"vdm"}
    assert shapes.manifest["objects"]["atoms"]["techniques"] == {}


def test_corrupted_or_misplaced_part_is_refused(meso_bundle, tmp_path):
    bad = tmp_path / "bad.bundle"
    shutil.copytree(meso_bundle, bad)
    r = SpecReader(bad)
    mesh_rel = r.manifest["objects"]["torus"]["mesh"]
    exr_rel = r.manifest["objects"]["torus"]["mesostructure"]
    r.mesh(mesh_rel), r.mesostructure(exr_rel)  # fine before
    for rel in (mesh_rel, exr_rel):
        path = bad / rel
        data = bytearray(path.read_bytes())
        data[len(data) // 2] ^= 0x01                # one bit in the payload
        path.write_bytes(bytes(data))
    with pytest.raises(ChecksumError):
        r.mesh(mesh_rel)
    with pytest.raises(ChecksumError):
        r.mesostructure(exr_rel)
    # truncated part
    coarse_rel = r.manifest["objects"]["torus"]["techniques"]["coarse"]["meshes"][0]["mesh"]
    (bad / coarse_rel).write_bytes((bad / coarse_rel).read_bytes()[:-4])
    with pytest.raises(ChecksumError):
        r.mesh(coarse_rel)
    # a part of the wrong kind, a path leaving the folder
    with pytest.raises(BundleError):
        r.mesostructure(r.manifest["objects"]["torus"]["techniques"]["vdm"]["tables"])
    r.manifest["parts"]["../escape.ply"] = dict(r.manifest["parts"][mesh_rel])
    with pytest.raises(BundleError):
        r.part_bytes("../escape.ply")
    # a folder without manifest.json is not a bundle; a wrong version is refused
    (bad / "manifest.json").rename(bad / "m.json")
    with pytest.raises(BundleError):
        SpecReader(bad)
    m = json.loads((bad / "m.json").read_text())
    m["format_version"] = 3
    (bad / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(BundleError):
        SpecReader(bad)


# --------------------------------------------------------------------------------------------------
# PLY parts
# --------------------------------------------------------------------------------------------------


def test_ply_headers_follow_the_spec(meso, shapes):
    """Comment lines, property names, order and types of every mesh and quadrics part, and the
    presence of texture coordinates / surface frame exactly where the spec says."""
    base, uv, frame = MESH_PROPS
    for r in (meso, shapes):
        for rel, entry in r.manifest["parts"].items():
            if entry["kind"] == "mesh":
                ply = r.ply(rel)
                assert ply.comments == ["vdmbake mesh"]
                props = ply.schema["vertex"]
                owner = [n for n, o in r.manifest["objects"].items() if o.get("mesh") == rel]
                is_full = bool(owner)
                has_meso = is_full and "mesostructure" in r.manifest["objects"][owner[0]]
                # Found by experiment: a built-in primitive's full mesh carries the surface frame even
                # without a mesostructure (the spec: "only with a surface frame: objects with a
                # mesostructure"); the sphere "ball" here has none and still has dpdu ... d1.
                is_primitive = is_full and "primitive" in next(
                    o for o in r.manifest["scene"]["objects"] if o["name"] == owner[0])
                want = base + (uv if is_full else []) + (frame if has_meso or is_primitive else [])
                assert props == want, rel
                assert ply.schema["face"] == [("vertex_indices", "list", "uchar", "int")]
                assert list(ply.elements) == ["vertex", "face"]
                assert len(ply.elements["vertex"]) == entry["vertices"]
                assert len(ply.elements["face"]) == entry["faces"]
            elif entry["kind"] == "quadrics":
                ply = r.ply(rel)
                assert ply.comments == ["vdmbake quadrics"]
                assert ply.schema == {"sphere": SPHERE_PROPS, "cylinder": CYLINDER_PROPS}
                assert len(ply.elements["sphere"]) == entry["spheres"]
                assert len(ply.elements["cylinder"]) == entry["cylinders"]


def _check_mesh_basics(r, rel):
    mesh = r.mesh(rel)
    meta = r.manifest["parts"][rel]
    v, f = mesh["vertices"], mesh["faces"]
    assert v.dtype == np.float64 and mesh["normals"].dtype == np.float32
    assert v.shape == (meta["vertices"], 3) and f.shape == (meta["faces"], 3)
    assert (mesh["face_sizes"] == 3).all()
    assert f.min() >= 0 and f.max() < len(v)
    assert np.allclose(np.linalg.norm(mesh["normals"], axis=1), 1, atol=1e-5)
    assert np.isfinite(v).all()
    return mesh


def test_full_torus_mesh(meso):
    """Counts equal the manifest; indices in range; unit normals; inside the bounding sphere whose
    centre is the bounding box's; every vertex on the torus (default transform) with its analytic
    outward normal; faces counter-clockwise seen from outside."""
    obj = meso.manifest["objects"]["torus"]
    mesh = _check_mesh_basics(meso, obj["mesh"])
    v, f, n = mesh["vertices"], mesh["faces"], mesh["normals"].astype(np.float64)
    R, r = TORUS["major"], TORUS["minor"]
    centre, radius = np.array(obj["centre"]), obj["radius"]
    assert np.linalg.norm(v - centre, axis=1).max() <= radius * (1 + 1e-9)
    assert np.linalg.norm(v - centre, axis=1).max() >= radius * (1 - 1e-6)     # tight
    assert np.allclose(centre, (v.min(0) + v.max(0)) / 2, atol=1e-9)
    assert radius == pytest.approx(R + r)
    rho = np.hypot(v[:, 0], v[:, 1])
    assert np.abs((rho - R) ** 2 + v[:, 2] ** 2 - r ** 2).max() < 1e-9
    _, n_true, *_ = torus_frame(v, R, r)
    assert np.abs(n - n_true).max() < 1e-5
    face_n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert (np.sum(face_n * n[f].mean(1), 1) > 0).all()
    assert len(f) == 2 * TORUS["segments"] * TORUS["rings"]


def test_surface_frame_of_the_torus(meso):
    """texture coordinates in [0, 1]; dpdu, dpdv are the derivatives of position along (u, v) (checked
    against each face's finite differences, and exactly against the torus once the UVs are seen to be
    the ring and tube angles); k1, k2 are the normal curvatures along d1 and normal x d1, positive where
    the surface bends away from its normal (sphere-like outer equator: both positive)."""
    mesh = meso.mesh(meso.manifest["objects"]["torus"]["mesh"])
    v, f, n = mesh["vertices"], mesh["faces"], mesh["normals"].astype(np.float64)
    uv = mesh["uvs"].astype(np.float64)
    assert uv.min() >= 0 and uv.max() <= 1
    dpdu, dpdv = mesh["dpdu"].astype(np.float64), mesh["dpdv"].astype(np.float64)
    # finite differences per face: [p1 - p0, p2 - p0] = [dpdu dpdv] [uv1 - uv0, uv2 - uv0]
    e = np.stack([v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]], 2)
    d = np.stack([uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]], 2)
    g_face = e @ np.linalg.inv(d)
    g_vert = np.stack([dpdu, dpdv], 2)[f].mean(1)
    cos = np.sum(unit_rows(np.moveaxis(g_face, 2, 1)) * unit_rows(np.moveaxis(g_vert, 2, 1)), -1)
    assert cos.min() > 0.97
    ratio = np.linalg.norm(g_face, axis=1) / np.linalg.norm(g_vert, axis=1)
    assert np.abs(ratio - 1).max() < 0.15
    # the torus's own parametrisation, seen in the data: u = ring angle / 2 pi, v = tube angle / 2 pi
    R, r = TORUS["major"], TORUS["minor"]
    _, n_true, e_ring, e_tube, cos_v = torus_frame(v, R, r)
    ring_angle = np.arctan2(v[:, 1], v[:, 0]) / (2 * np.pi)
    tube_angle = np.arctan2(v[:, 2], np.hypot(v[:, 0], v[:, 1]) - R) / (2 * np.pi)
    wrap = lambda a: (a + 0.5) % 1 - 0.5  # noqa: E731
    assert np.abs(wrap(uv[:, 0] - ring_angle)).max() < 1e-6
    assert np.abs(wrap(uv[:, 1] - tube_angle)).max() < 1e-6
    rho = np.hypot(v[:, 0], v[:, 1])
    assert np.abs(dpdu - 2 * np.pi * rho[:, None] * e_ring).max() < 1e-5
    assert np.abs(dpdv - 2 * np.pi * r * e_tube).max() < 1e-5
    # principal curvatures
    d1 = mesh["d1"].astype(np.float64)
    assert np.allclose(np.linalg.norm(d1, axis=1), 1, atol=1e-5)
    assert np.abs(np.sum(d1 * n, 1)).max() < 1e-5
    k_ring, k_tube = cos_v / (R + r * cos_v), 1 / r
    second = lambda a: k_ring * np.sum(a * e_ring, 1) ** 2 + k_tube * np.sum(a * e_tube, 1) ** 2  # noqa: E731
    assert np.abs(mesh["k1"] - second(d1)).max() < 1e-4
    assert np.abs(mesh["k2"] - second(np.cross(n, d1))).max() < 1e-4
    outer = cos_v > 0.999
    assert outer.any() and (mesh["k1"][outer] > 0).all() and (mesh["k2"][outer] > 0).all()
    inner = cos_v < -0.999
    assert (np.minimum(mesh["k1"], mesh["k2"])[inner] < 0).all()       # saddle on the inside


def test_transform_scale_then_xyz_rotations_then_translation(meso):
    """The 'flat' torus has scale 0.5, rotate_deg [90, 0, 30], translate [3, 0, 0]: its vertices are
    on the torus placed in that order (and not in the reverse rotation order), its curvatures are in
    1 / world units (scaled by 1 / 0.5), its bounding sphere is centred at the translation."""
    obj = meso.manifest["objects"]["flat"]
    mesh = _check_mesh_basics(meso, obj["mesh"])
    v, n = mesh["vertices"], mesh["normals"].astype(np.float64)
    s, t = FLAT_TRANSFORM["scale"], np.array(FLAT_TRANSFORM["translate"])
    rot = rotation(FLAT_TRANSFORM["rotate_deg"])
    local = (v - t) @ rot / s                      # R^T (p - t) / s
    rho = np.hypot(local[:, 0], local[:, 1])
    assert np.abs((rho - FLAT["major"]) ** 2 + local[:, 2] ** 2 - FLAT["minor"] ** 2).max() < 1e-9
    _, n_local, *_ = torus_frame(local, FLAT["major"], FLAT["minor"])
    assert np.abs(n - n_local @ rot.T).max() < 1e-5
    ax, ay, az = np.radians(FLAT_TRANSFORM["rotate_deg"])
    wrong = np.eye(3)  # becomes Rx @ Ry @ Rz: Z first, then Y, then X (the wrong order)
    for m in (np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]]),
              np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]]),
              np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])):
        wrong = wrong @ m
    lw = (v - t) @ wrong / s
    assert np.abs((np.hypot(lw[:, 0], lw[:, 1]) - FLAT["major"]) ** 2 + lw[:, 2] ** 2 - FLAT["minor"] ** 2).max() > 0.01
    assert np.allclose(obj["centre"], t, atol=1e-9)
    assert obj["radius"] == pytest.approx(s * (FLAT["major"] + FLAT["minor"]))
    assert max(mesh["k1"].max(), mesh["k2"].max()) == pytest.approx(1 / (s * FLAT["minor"]), rel=1e-4)


def test_coarse_meshes(meso):
    """One mesh per ratio in the scene's order, about ratio x the full mesh's faces, no UVs, normals
    equal to the area-weighted normals of the faces around each corner's position within 60 degrees of
    the corner's face, recomputed from the coarse mesh itself; close to the torus."""
    obj = meso.manifest["objects"]["torus"]
    full_faces = meso.manifest["parts"][obj["mesh"]]["faces"]
    entries = obj["techniques"]["coarse"]["meshes"]
    assert [e["ratio"] for e in entries] == [0.5, 0.25]
    for e in entries:
        mesh = _check_mesh_basics(meso, e["mesh"])
        assert "uvs" not in mesh and "dpdu" not in mesh
        assert abs(len(mesh["faces"]) - e["ratio"] * full_faces) <= max(2, 0.05 * e["ratio"] * full_faces)
        v, f = mesh["vertices"], mesh["faces"]
        face_n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])   # |.| = 2 x area
        unit_f = unit_rows(face_n)
        _, point = np.unique(v, axis=0, return_inverse=True)
        point = point.ravel()
        around = {}
        for face, corners in enumerate(f):
            for c in corners:
                around.setdefault(point[c], []).append(face)
        for face, corners in enumerate(f):
            for c in corners:
                group = [g for g in around[point[c]] if unit_f[g] @ unit_f[face] >= math.cos(math.radians(60)) - 1e-9]
                want = unit_rows(face_n[group].sum(0)[None])[0]
                assert np.abs(want - mesh["normals"][c]).max() < 1e-4, (face, c)
        rho = np.hypot(v[:, 0], v[:, 1])
        dev = np.abs(np.hypot(rho - TORUS["major"], v[:, 2]) - TORUS["minor"])
        assert dev.max() < 0.1 * TORUS["minor"] * 2
        assert np.linalg.norm(v - obj["centre"], axis=1).max() <= obj["radius"] * (1 + 1e-6)


def test_displaced_meshes(meso):
    """level-times midpoint subdivision (4^level x faces), no UVs, unit normals; every base vertex
    appears displaced inward by depth * s_n * (1 - h(T)) with T = (s, t) * tiling, h bilinear and
    periodic; no vertex is displaced outward or deeper than depth * s_n."""
    obj = meso.manifest["objects"]["torus"]
    base = meso.mesh(obj["mesh"])
    maps = meso.mesostructure(obj["mesostructure"])
    depth, tiling = TORUS_MESO["depth"], TORUS_MESO["tiling"]
    n = base["normals"].astype(np.float64)
    _, _, s_n = tangent_jacobian(base, tiling)
    t_u = base["uvs"][:, 0].astype(np.float64) * tiling[0]
    t_v = base["uvs"][:, 1].astype(np.float64) * tiling[1]
    want = base["vertices"] - (depth * s_n * (1 - bilinear(maps["heights"], t_u, t_v)))[:, None] * n
    entries = obj["techniques"]["displaced"]["meshes"]
    assert [e["level"] for e in entries] == [1, 2]
    for e in entries:
        mesh = _check_mesh_basics(meso, e["mesh"])
        assert "uvs" not in mesh
        assert len(mesh["faces"]) == len(base["faces"]) * 4 ** e["level"]
        _, dist = nearest(want, mesh["vertices"])
        assert dist.max() < 1e-6
        v = mesh["vertices"]
        rho = np.hypot(v[:, 0], v[:, 1])
        inward = TORUS["minor"] - np.hypot(rho - TORUS["major"], v[:, 2])
        sag = TORUS["minor"] * (1 - math.cos(math.pi / TORUS["rings"])) + (TORUS["major"] + TORUS["minor"]) * (
            1 - math.cos(math.pi / TORUS["segments"]))
        # midpoints sit on chords: inside the torus across the tube, outside it along the inner ring
        assert inward.min() > -sag and inward.max() < depth * s_n.max() + sag


def test_displaced_normals_are_the_mesostructure_shading_normals(meso):
    """Found by experiment (the spec does not say how a texture-space normal goes to world space):
    at the base vertices, the displaced mesh's normal is the bilinearly interpolated normal map
    (n_x, n_y, n_z), renormalised, mapped as n_z * N + s_n * (n_x * J_u / |J_u|^2 + n_y * J_v / |J_v|^2),
    i.e. the normal of the surface displaced by depth * s_n * (1 - h); mapping with the unit frame
    (n_x e_u + n_y e_v + n_z N) is measurably different on this torus, whose |J_u| != |J_v|."""
    obj = meso.manifest["objects"]["torus"]
    base = meso.mesh(obj["mesh"])
    maps = meso.mesostructure(obj["mesostructure"])
    depth, tiling = TORUS_MESO["depth"], TORUS_MESO["tiling"]
    n = base["normals"].astype(np.float64)
    ju, jv, s_n = tangent_jacobian(base, tiling)
    t_u = base["uvs"][:, 0].astype(np.float64) * tiling[0]
    t_v = base["uvs"][:, 1].astype(np.float64) * tiling[1]
    want_p = base["vertices"] - (depth * s_n * (1 - bilinear(maps["heights"], t_u, t_v)))[:, None] * n
    nt = unit_rows(bilinear(maps["normals"], t_u, t_v))
    au, av = np.sum(ju * ju, 1)[:, None], np.sum(jv * jv, 1)[:, None]
    scaled = unit_rows(nt[:, 2:3] * n + s_n[:, None] * (nt[:, 0:1] * ju / au + nt[:, 1:2] * jv / av))
    unit_frame = unit_rows(nt[:, 2:3] * n + nt[:, 0:1] * unit_rows(ju) + nt[:, 1:2] * unit_rows(jv))
    mesh = meso.mesh(obj["techniques"]["displaced"]["meshes"][0]["mesh"])
    idx, dist = nearest(want_p, mesh["vertices"])
    assert dist.max() < 1e-6
    got = mesh["normals"][idx].astype(np.float64)
    assert np.abs(got - scaled).max() < 1e-5
    assert np.abs(got - unit_frame).max() > 10 * np.abs(got - scaled).max()


def test_quadrics_match_the_inline_lists(shapes):
    """Spheres and capped cylinders as written, minus those without volume (counted as dropped),
    coloured with the object's albedo; the bounding sphere encloses every quadric."""
    obj = shapes.manifest["objects"]["atoms"]
    assert obj["kind"] == "quadrics"
    q = shapes.quadrics(obj["quadrics"])
    keep_s = [s for s in SPHERES if s[3] > 0]
    keep_c = [c for c in CYLINDERS if c[6] > 0 and c[:3] != c[3:6]]
    assert q["spheres"].dtype == np.float64 and q["sphere_rgb"].dtype == np.float32
    np.testing.assert_array_equal(q["spheres"], np.array(keep_s, float))
    np.testing.assert_array_equal(q["cylinders"], np.array(keep_c, float))
    assert obj["spheres_dropped"] == len(SPHERES) - len(keep_s)
    assert obj["cylinders_dropped"] == len(CYLINDERS) - len(keep_c)
    np.testing.assert_allclose(q["sphere_rgb"], np.tile(ATOMS_ALBEDO, (len(keep_s), 1)), atol=1e-7)
    np.testing.assert_allclose(q["cylinder_rgb"], np.tile(ATOMS_ALBEDO, (len(keep_c), 1)), atol=1e-7)
    assert (q["sphere_rgb"] >= 0).all() and (q["sphere_rgb"] <= 1).all()
    centre, radius = np.array(obj["centre"]), obj["radius"]
    reach = [np.linalg.norm(s[:3] - centre) + s[3] for s in q["spheres"]]
    for c in q["cylinders"]:  # any capped cylinder lies within the spheres of radius r at its ends
        reach += [np.linalg.norm(c[:3] - centre) + c[6], np.linalg.norm(c[3:6] - centre) + c[6]]
    assert max(reach) <= radius * (1 + 1e-9)
    # Found by experiment: the tight value, and a box in which each cylinder counts as its two
    # end spheres (z extent 1.6 from the cylinder ending at z = 1.5 with r = 0.1).
    assert radius == pytest.approx(max(reach), rel=1e-9)
    lo = np.min([s[:3] - s[3] for s in q["spheres"]] + [c[:3] - c[6] for c in q["cylinders"]]
                + [c[3:6] - c[6] for c in q["cylinders"]], 0)
    hi = np.max([s[:3] + s[3] for s in q["spheres"]] + [c[:3] + c[6] for c in q["cylinders"]]
                + [c[3:6] + c[6] for c in q["cylinders"]], 0)
    np.testing.assert_allclose(centre, (lo + hi) / 2, atol=1e-9)


# --------------------------------------------------------------------------------------------------
# EXR parts
# --------------------------------------------------------------------------------------------------


def _window_size(win):
    lo, hi = np.asarray(win[0]), np.asarray(win[1])
    return lo, (hi - lo + 1)


def test_exr_files_layout(meso, shapes, painted):
    """Every EXR: the named parts and channels of its kind, FLOAT channels (colour maps: HALF), scanline, zip;
    colour channels (albedo.R, .G, .B) exactly where the metadata says `albedo` (the painted mesh file), none
    for the primitives, which have no colours of their own; each
    part's dataWindow is its own size starting at (0, 0); all parts share one displayWindow, the union
    of the part sizes; arrays are [row, column] of the dataWindow's size."""
    want_parts = {
        "mesostructure": {"height": ["h"], "normal": ["normal.X", "normal.Y", "normal.Z"]},
        "vdm": None, "billboards": None, "octahedral": {"atlas": ["A", "depth.Z", "normal.U", "normal.V"]},
    }
    seen, colour = set(), ["albedo.B", "albedo.G", "albedo.R"]
    for r in (meso, shapes, painted):
        for rel, entry in r.manifest["parts"].items():
            if not rel.endswith(".exr"):
                continue
            seen.add(entry["kind"])
            x = r.exr(rel)
            coloured = entry.get("albedo", False)
            assert coloured == (r is painted) and entry.get("albedo", None) in (None, True)  # the key only when true
            if entry["kind"] == "octahedral":
                assert {k: sorted(p.channels) for k, p in x.items()} == {"atlas": sorted(want_parts["octahedral"]["atlas"]
                                                                                         + colour * coloured)}
            elif entry["kind"] == "mesostructure":
                assert {k: sorted(p.channels) for k, p in x.items()} == want_parts[entry["kind"]]
            elif entry["kind"] == "vdm":
                assert sorted(x) == ["E_mvm", "E_vdm", "W"] + (["W_dequant"] if entry["storage"] == "uint8" else [])
                assert sorted(x["W"].channels) == [f"W.{i:03d}" for i in range(entry["k"])]
                assert sorted(x["E_vdm"].channels) == [f"E.{i:03d}" for i in range(entry["k"])]
                assert sorted(x["E_mvm"].channels) == [f"E.{i:03d}" for i in range(entry["k"])]
            elif entry["kind"] == "billboards":
                assert sorted(x) == [f"bb{i:03d}" for i in range(len(entry["boards"]))]
                for p in x.values():
                    assert sorted(p.channels) == ["A"] + colour * coloured + ["depth.Z", "normal.X", "normal.Y", "normal.Z"]
            else:
                names = [f"bb{i:03d}" for i in range(entry["boards"])]
                assert sorted(k for k in x if "." not in k) == names
                for k, p in x.items():
                    want = (colour * coloured + ["depth.Z", "normal.X", "normal.Y", "normal.Z"] if "." not in k else
                            ["depth.Z"] if k.endswith(".samples") else ["max.Z", "min.Z"])
                    assert sorted(p.channels) == want, k
                assert any("." in k for k in x) == entry["pyramids"]
            sizes = []
            for p in x.values():
                assert "ZIP_COMPRESSION" in str(p.header["compression"])
                assert "scanline" in str(p.header["type"]).lower()
                lo, size = _window_size(p.header["dataWindow"])
                assert (lo == 0).all()
                sizes.append(size)
                for c, a in p.channels.items():
                    if entry["kind"] == "vdm" and c.startswith("W.") and entry["storage"] != "float32":
                        assert {"uint8": "UINT", "float16": "HALF"}[entry["storage"]] in p.channel_types[c]
                    elif c.startswith("albedo."):
                        assert "HALF" in p.channel_types[c] and a.dtype == np.float16
                    else:
                        assert "FLOAT" in p.channel_types[c] and a.dtype == np.float32
                    assert a.shape == (size[1], size[0])
            union = np.max(sizes, 0)
            for p in x.values():
                lo, size = _window_size(p.header["displayWindow"])
                assert (lo == 0).all() and (size == union).all(), rel
    assert seen == {"mesostructure", "vdm", "billboards", "bordered-billboards", "octahedral"}


def test_mesostructure_maps(meso):
    """N x N of the manifest's size; heights in [0, 1]; unit normals with positive z; the normal map
    is the height field's normal with X along u (columns), Y along v (rows), slopes in tile units
    scaled by depth: (-depth dh/du, -depth dh/dv, 1) normalised (central differences agree, the
    swapped reading does not). The 'flat' pattern is h = 1, n = (0, 0, 1)."""
    for name, meso_cfg in (("torus", TORUS_MESO), ("plane", PLANE_MESO), ("flat", FLAT_MESO)):
        rel = meso.manifest["objects"][name]["mesostructure"]
        maps = meso.mesostructure(rel)
        h, nrm = maps["heights"], maps["normals"]
        n = meso.manifest["parts"][rel]["size"]
        assert n == meso_cfg["size"] and h.shape == (n, n) and nrm.shape == (n, n, 3)
        assert h.min() >= 0 and h.max() <= 1
        assert np.allclose(np.linalg.norm(nrm, axis=-1), 1, atol=1e-5) and nrm[..., 2].min() > 0
        if name == "flat":
            assert (h == 1).all() and np.allclose(nrm, [0, 0, 1], atol=1e-6)
            continue
        depth = meso_cfg["depth"]
        dhdu = (np.roll(h, -1, 1) - np.roll(h, 1, 1)) * n / 2
        dhdv = (np.roll(h, -1, 0) - np.roll(h, 1, 0)) * n / 2
        g = unit_rows(np.stack([-depth * dhdu, -depth * dhdv, np.ones_like(h)], -1))
        corr = lambda a, b: np.corrcoef(a.ravel(), b.ravel())[0, 1]  # noqa: E731
        assert corr(nrm[..., 0], g[..., 0]) > 0.95 and corr(nrm[..., 1], g[..., 1]) > 0.95
        assert abs(corr(nrm[..., 0], g[..., 1])) < 0.3
        assert np.median(np.abs(nrm - g)) < 1e-3


def _vdm_case(r, name):
    t_entry = r.manifest["objects"][name]["techniques"]["vdm"]
    t = r.vdm(t_entry["tables"])
    d, mvm = vdm_reconstruct(t)
    h = r.mesostructure(r.manifest["objects"][name]["mesostructure"])["heights"]
    return t_entry, t, d, mvm, h


def test_vdm_tables_shapes_and_ranges(meso):
    """Shapes follow the manifest and the scene (n_phi, N, k, n_c, n_theta); curvature samples ascend;
    the reconstructed d and theta_MVM are finite, theta_MVM in [0, pi/2]; where theta > theta_MVM the
    entry holds theta_MVM; elsewhere d >= 0 and at the smallest theta d is about the straight-down
    distance depth * (1 - h) / cos(theta)."""
    for name, cfg in (("torus", TORUS_MESO), ("plane", PLANE_MESO), ("flat", FLAT_MESO)):
        t_entry, t, d, mvm, h = _vdm_case(meso, name)
        meta = meso.manifest["parts"][t_entry["tables"]]
        n, k = cfg["size"], t_entry["k"]
        assert meta["n_phi"] == cfg["phi"] and meta["k"] == k and 1 <= k <= t_entry["rank"]
        assert t["W"].shape == (cfg["phi"], n, n, k)
        curv = t_entry["curvatures"]
        assert curv == sorted(curv)
        n_c = len(curv)
        assert t["E_vdm"].shape == (k, n_c, cfg["theta"]) and t["E_mvm"].shape == (k, n_c)
        assert set(t_entry["errors"]) == ({"2", str(k)} if name == "torus" else {str(k)})
        assert np.isfinite(d).all() and np.isfinite(mvm).all()
        assert mvm.min() >= -1e-3 and mvm.max() <= np.pi / 2 + 1e-2
        if name == "torus":
            assert n_c == cfg["curvatures"] and k == t_entry["rank"]      # "all"
        if name == "plane":
            assert curv == [0.0]                                          # a plane: one sample
        n_t = cfg["theta"]
        theta = (np.arange(n_t) + 0.5) / n_t * np.pi / 2
        miss = theta > mvm[..., None] + 1e-4
        hit = theta < mvm[..., None] - 1e-4
        mvm_b = np.broadcast_to(mvm[..., None], d.shape)
        if miss.any():
            assert np.abs(d[miss] - mvm_b[miss]).max() < 1e-3
        assert d[hit].min() > -1e-3
        straight = cfg["depth"] * (1 - h.astype(np.float64)) / math.cos(theta[0])
        assert np.abs(d[..., 0] - straight[None, :, :, None]).max() < 0.2 * cfg["depth"]
    # curved torus: convex samples lose grazing views, the concave one does not
    t_entry, t, d, mvm, h = _vdm_case(meso, "torus")
    curv = np.array(t_entry["curvatures"])
    assert curv[0] < 0 < curv[-1]
    assert mvm[..., 0].min() > np.pi / 2 - 1e-3 and mvm[..., -1].min() < np.pi / 2 - 0.1


def test_vdm_plane_matches_an_independent_ray_march(meso):
    """On the plane (one curvature sample, k = rank, so the tables are exact) d equals an independent
    march of V = (sin t cos p, sin t sin p, cos t) from the entry point T = texel centre into the
    bilinear height field at -depth * (1 - h): phi from +u toward +v, W rows phi * N + y, column x.
    The transposed table reading, phi toward -v, and T' = T + d V_xy all disagree."""
    t_entry, t, d, mvm, h = _vdm_case(meso, "plane")
    n_phi, n = t["W"].shape[:2]
    n_t = t["E_vdm"].shape[2]
    depth = PLANE_MESO["depth"]
    phis = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    thetas = (np.arange(n_t) + 0.5) / n_t * np.pi / 2
    steps = np.linspace(0.0, 2.0, 4001)

    def march(u, v, phi, theta, sign_v=1.0, sign_d=1.0):
        vx, vy, vz = math.sin(theta) * math.cos(phi), sign_v * math.sin(theta) * math.sin(phi), math.cos(theta)
        pu, pv = u - sign_d * steps * vx, v - sign_d * steps * vy
        below = -steps * vz <= -depth * (1 - bilinear(h, pu, pv))
        return steps[np.argmax(below)] if below.any() else np.nan

    rng = np.random.default_rng(1)
    samples = [(rng.integers(n_phi), rng.integers(n), rng.integers(n), rng.integers(1, n_t)) for _ in range(80)]
    errs = {"spec": [], "transposed": [], "phi toward -v": [], "T + dV": []}
    for p, y, x, ti in samples:
        u, v = (x + 0.5) / n, (y + 0.5) / n
        errs["spec"].append(d[p, y, x, 0, ti] - march(u, v, phis[p], thetas[ti]))
        errs["transposed"].append(d[p, x, y, 0, ti] - march(u, v, phis[p], thetas[ti]))
        errs["phi toward -v"].append(d[p, y, x, 0, ti] - march(u, v, phis[p], thetas[ti], sign_v=-1))
        errs["T + dV"].append(d[p, y, x, 0, ti] - march(u, v, phis[p], thetas[ti], sign_d=-1))
    assert np.isfinite(errs["spec"]).all()  # every ray meets the plane's mesostructure
    p90 = {k: np.nanquantile(np.abs(e), 0.9) for k, e in errs.items()}
    assert p90["spec"] < 2e-3, p90
    for k in ("transposed", "phi toward -v", "T + dV"):
        assert p90[k] > 5 * p90["spec"] and p90[k] > 5e-3, p90


def test_vdm_flat_mesostructure(meso):
    """height = 'flat' (h = 1): every view ray hits where it enters, d = 0, theta_MVM = pi/2, for
    every curvature sample (even on a curved, transformed torus)."""
    t_entry, t, d, mvm, h = _vdm_case(meso, "flat")
    assert len(t_entry["curvatures"]) == FLAT_MESO["curvatures"]
    assert np.abs(d).max() < 1e-4
    assert np.abs(mvm - np.pi / 2).max() < 1e-4


def test_vdm_curvature_samples(meso):
    """Found by experiment (the spec gives the unit, 1 / texture units, but not the conversion from
    the mesh's k1, k2 in 1 / world units, nor which range is sampled): the samples are
    linspace(min, max, n_c) over the vertices and azimuths of c(phi) = II(J a, J a) / s_n, a = (cos phi,
    sin phi), II the second fundamental form from k1, k2, d1, J the projected [dpdu / tiling_u,
    dpdv / tiling_v]; not k * s_n, which spans a different range."""
    for name, cfg in (("torus", TORUS_MESO), ("flat", FLAT_MESO), ("plane", PLANE_MESO)):
        obj = meso.manifest["objects"][name]
        mesh = meso.mesh(obj["mesh"])
        ju, jv, s_n = tangent_jacobian(mesh, cfg["tiling"])
        n = mesh["normals"].astype(np.float64)
        d1 = mesh["d1"].astype(np.float64)
        d2 = np.cross(n, d1)
        k1, k2 = mesh["k1"].astype(np.float64), mesh["k2"].astype(np.float64)
        cs, ks = [], []
        for phi in np.linspace(0, np.pi, 361):
            w = math.cos(phi) * ju + math.sin(phi) * jv
            second = k1 * np.sum(w * d1, 1) ** 2 + k2 * np.sum(w * d2, 1) ** 2
            cs.append(second / s_n)
            ks.append(second / np.sum(w * w, 1) * s_n)
        curv = obj["techniques"]["vdm"]["curvatures"]
        if name == "plane":
            assert curv == [0.0] and np.abs(cs).max() < 1e-9
            continue
        want = np.linspace(np.min(cs), np.max(cs), len(curv))
        np.testing.assert_allclose(curv, want, atol=1e-5)
        assert abs(np.max(ks) - curv[-1]) > 0.1


# --------------------------------------------------------------------------------------------------
# Billboards
# --------------------------------------------------------------------------------------------------


def test_billboards_reproject_onto_the_sphere(shapes):
    """Per variant: parts bb000.. match the boards listed; face counts add up with the leftovers to
    the full mesh's faces; axes right-handed orthonormal; A is 0/1; depth in [0, 1], 1 where A = 0;
    normals 0 where A = 0, unit and facing the viewer (n . w < 0) where A = 1; covered texels
    reprojected with the spec's formula lie inside the box and on the sphere (within a few texel
    sizes), and the normals are the sphere's. Reading rows as u instead fails on some board."""
    obj = shapes.manifest["objects"]["ball"]
    centre, radius = np.array(BALL["centre"]), BALL["radius"]
    np.testing.assert_allclose(obj["centre"], centre, atol=1e-9)
    assert obj["radius"] == pytest.approx(radius)
    full_faces = shapes.manifest["parts"][obj["mesh"]]["faces"]
    bb = obj["techniques"]["billboards"]
    assert set(bb) == {"greedy", "axis", "coarse"}
    assert shapes.manifest["parts"][bb["greedy"]["bordered"]]["pyramids"]          # greedy-hier
    assert not shapes.manifest["parts"][bb["axis"]["bordered"]]["pyramids"]
    worst_transposed = 0.0
    for variant in ("greedy", "axis"):
        entry = bb[variant]
        boards = shapes.billboards(entry["maps"])
        assert len(boards) == len(entry["faces"]) >= 1
        assert sum(entry["faces"]) + sum(entry["leftover"].values()) == full_faces
        for b in boards:
            a, depth, nrm, axes = b["A"], b["depth"].astype(np.float64), b["normal"].astype(np.float64), b["axes"]
            res = a.shape[0]
            assert a.shape == (res, res) == (BALL["resolution"],) * 2
            assert np.allclose(axes @ axes.T, np.eye(3), atol=1e-9) and np.linalg.det(axes) == pytest.approx(1)
            assert set(np.unique(a)) <= {0.0, 1.0} and a.any()
            cov = a == 1
            assert (depth[~cov] == 1).all() and (nrm[~cov] == 0).all()
            assert depth[cov].min() >= 0 and depth[cov].max() <= 1
            i, j = np.nonzero(cov)
            su, sv, sw = b["size"]

            def reproject(ii, jj):
                return (b["origin"] + ((jj + 0.5) / res * su)[:, None] * axes[0]
                        + ((ii + 0.5) / res * sv)[:, None] * axes[1] + (depth[i, j] * sw)[:, None] * axes[2])

            p = reproject(i, j)
            texel = max(su, sv) / res
            off = np.abs(np.linalg.norm(p - centre, axis=1) - radius)
            assert off.max() < 0.25 * texel + 0.02, (variant, off.max(), texel)
            local = (p - b["origin"]) @ axes.T
            assert (local >= -1e-9).all() and (local <= b["size"] * (1 + 1e-9)).all()
            n_cov = nrm[cov]
            assert np.allclose(np.linalg.norm(n_cov, axis=1), 1, atol=1e-5)
            assert (n_cov @ axes[2] < 0).all()
            assert np.abs(n_cov - unit_rows(p - centre)).max() < 0.1
            worst_transposed = max(worst_transposed,
                                   np.abs(np.linalg.norm(reproject(j, i) - centre, axis=1) - radius).max())
    assert worst_transposed > 0.1
    coarse = _check_mesh_basics(shapes, bb["coarse"])
    assert "uvs" not in coarse
    assert 0.5 * 0.25 * full_faces < len(coarse["faces"]) < 1.5 * 0.25 * full_faces


# --------------------------------------------------------------------------------------------------
# Octahedral impostors
# --------------------------------------------------------------------------------------------------


def oct_decode(g, hemi):
    """The spec's octahedral map, inverted: map points (..., 2) -> unit directions (..., 3)."""
    g = np.asarray(g, float)
    if hemi:
        g = np.stack([(g[..., 0] + g[..., 1]) / 2, (g[..., 0] - g[..., 1]) / 2], -1)
    z = 1 - np.abs(g).sum(-1)
    s = np.where(g >= 0, 1.0, -1.0)
    xy = np.where(z[..., None] < 0, (1 - np.abs(g[..., ::-1])) * s, g)
    return unit_rows(np.concatenate([xy, z[..., None]], -1))


def test_octahedral_atlas_reprojects_onto_the_sphere(shapes):
    """One atlas for the two methods; with the spec's lattice, frames and texel formula every covered
    texel lies on the ball and its decoded normal is the ball's; uncovered texels far from covered ones
    have depth 1 and code 0, those near them are extrapolated; the
    views' directions, each at the map point of its tile, cover the sphere (full layout)."""
    obj = shapes.manifest["objects"]["ball"]
    entry = obj["techniques"]["octahedral"]
    n, res = BALL["views"], BALL["view_resolution"]
    assert list(entry) == [f"full-{n}x{res}"]
    a = shapes.octahedral(entry[f"full-{n}x{res}"])
    assert (a["views"], a["resolution"], a["hemi"]) == (n, res, False)
    assert a["A"].shape == (n * res, n * res) and set(np.unique(a["A"])) == {0.0, 1.0}
    near = np.zeros(a["A"].shape, bool)    # within 2 texels of a covered one: extrapolated
    for di in range(-2, 3):
        for dj in range(-2, 3):
            near |= np.roll(np.roll(a["A"] == 1, di, 0), dj, 1)
    assert (a["depth"][~near] == 1).all() and (a["code"][~near] == 0).all() and (a["depth"][near] < 1).all()
    assert a["depth"].min() >= 0 and np.abs(a["code"]).max() <= 1 and a["rays"] >= n * n * res * res
    centre, cap, basis = a["centre"], a["capture"], a["basis"]
    np.testing.assert_allclose(centre, BALL["centre"], atol=1e-9)
    assert np.allclose(basis @ basis.T, np.eye(3))
    dirs = []
    for j in range(n):
        for i in range(n):
            g = np.array([-1 + 2 * i / (n - 1), -1 + 2 * j / (n - 1)])
            e = oct_decode(g, False)
            sg = 1.0 if abs(2 * i - n + 1) + abs(2 * j - n + 1) <= n - 1 else -1.0
            q = -1 / (sg + e[2])
            b = e[0] * e[1] * q
            u = np.array([1 + sg * e[0] ** 2 * q, sg * b, -sg * e[0]])
            v = np.array([b, sg + e[1] ** 2 * q, -e[1]])
            e, u, v = e @ basis, u @ basis, v @ basis
            assert np.allclose(np.cross(u, v), e)
            dirs.append(e)
            tile = np.s_[j * res:(j + 1) * res, i * res:(i + 1) * res]
            cov, depth, code = a["A"][tile] == 1, a["depth"][tile].astype(float), a["code"][tile].astype(float)
            assert cov.any()
            rb, ra = np.nonzero(cov)
            p = (centre + cap * e + (((ra + 0.5) / res * 2 - 1) * cap)[:, None] * u
                 + (((rb + 0.5) / res * 2 - 1) * cap)[:, None] * v - (depth[rb, ra] * 2 * cap)[:, None] * e)
            off = np.abs(np.linalg.norm(p - centre, axis=1) - BALL["radius"])
            assert off.max() < 0.02, (i, j, off.max())
            local = oct_decode(code[rb, ra], False)
            nrm = local[:, :1] * u + local[:, 1:2] * v + local[:, 2:] * e
            assert np.abs(nrm - unit_rows(p - centre)).max() < 0.1
    dirs = np.array(dirs)
    assert (dirs @ dirs.T).min() < -0.99 and np.abs(dirs).max(0).min() > 0.99   # opposite views, every axis


def test_sphere_mesh_in_its_bounding_sphere(shapes):
    obj = shapes.manifest["objects"]["ball"]
    mesh = _check_mesh_basics(shapes, obj["mesh"])
    r = np.linalg.norm(mesh["vertices"] - np.array(BALL["centre"]), axis=1)
    assert np.abs(r - BALL["radius"]).max() < 1e-9 and r.max() <= obj["radius"] * (1 + 1e-9)
    assert np.abs(mesh["normals"] - unit_rows(mesh["vertices"] - np.array(BALL["centre"]))).max() < 1e-5


# --------------------------------------------------------------------------------------------------
# Both readings agree
# --------------------------------------------------------------------------------------------------


def test_reader_agrees_with_project_unpacking(meso, shapes):
    import vdmbake.bundle.parts as parts
    from vdmbake.bundle.directory import Bundle

    torus = meso.manifest["objects"]["torus"]
    ours, theirs = meso.mesh(torus["mesh"]), Bundle(meso.root).read(torus["mesh"], parts.MESH)
    np.testing.assert_array_equal(ours["vertices"], theirs.vertices)
    np.testing.assert_array_equal(ours["faces"], theirs.faces)
    np.testing.assert_allclose(ours["normals"], theirs.normals, atol=1e-7)
    np.testing.assert_allclose(ours["uvs"], theirs.uvs, atol=1e-7)
    for key in ("dpdu", "dpdv", "k1", "k2", "d1"):
        np.testing.assert_allclose(ours[key], getattr(theirs.frame, key), atol=1e-6)
    coarse_rel = torus["techniques"]["coarse"]["meshes"][0]["mesh"]
    np.testing.assert_array_equal(meso.mesh(coarse_rel)["faces"], Bundle(meso.root).read(coarse_rel, parts.MESH).faces)

    ours, theirs = meso.mesostructure(torus["mesostructure"]), Bundle(meso.root).read(torus["mesostructure"], parts.MESOSTRUCTURE)
    np.testing.assert_array_equal(ours["heights"], theirs.heights)
    np.testing.assert_array_equal(ours["normals"], theirs.normals)

    rel = torus["techniques"]["vdm"]["tables"]
    ours, theirs = meso.vdm(rel), Bundle(meso.root).read(rel, parts.VDM)
    np.testing.assert_array_equal(ours["W"], theirs.W.astype(np.float32) * theirs.scale + theirs.offset)
    for key in ("E_vdm", "E_mvm"):
        np.testing.assert_array_equal(ours[key], getattr(theirs, key))

    atoms = shapes.manifest["objects"]["atoms"]
    ours, theirs = shapes.quadrics(atoms["quadrics"]), Bundle(shapes.root).read(atoms["quadrics"], parts.QUADRICS)
    for key in ("spheres", "cylinders", "sphere_rgb", "cylinder_rgb"):
        np.testing.assert_array_equal(ours[key], getattr(theirs, key))

    rel = shapes.manifest["objects"]["ball"]["techniques"]["billboards"]["greedy"]["maps"]
    ours, theirs = shapes.billboards(rel), Bundle(shapes.root).read(rel, parts.BILLBOARDS)
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs):
        np.testing.assert_array_equal(a["A"], b.alpha)
        np.testing.assert_array_equal(a["depth"], b.depth)
        np.testing.assert_array_equal(a["normal"], b.normal)
        np.testing.assert_allclose(a["origin"], b.origin)
        np.testing.assert_allclose(a["axes"], b.axes)
        np.testing.assert_allclose(a["size"], b.size)

    rel = next(iter(shapes.manifest["objects"]["ball"]["techniques"]["octahedral"].values()))
    ours, theirs = shapes.octahedral(rel), Bundle(shapes.root).read(rel, parts.OCTAHEDRAL)
    np.testing.assert_array_equal(ours["A"], theirs.coverage)
    np.testing.assert_array_equal(ours["depth"], theirs.depth)
    np.testing.assert_array_equal(ours["code"], theirs.normal)
    np.testing.assert_array_equal(ours["basis"], theirs.basis)
    assert (ours["views"], ours["capture"]) == (theirs.views, theirs.capture)

def test_bordered_billboards_as_documented(shapes):
    """bordered-billboards, read from the spec alone: bordered texel [i, j] is map texel [i - 1, j - 1]
    wherever that is covered; the pyramid (greedy, for hier) has (R + 1)^2 level-0 cells, empty ones
    [1e30, -1e30]; a cell with a covered corner is not empty unless steeper than 6 texels of depth per
    texel; a cell with no covered corner is empty; each level's interval holds its children's."""
    bb = shapes.manifest["objects"]["ball"]["techniques"]["billboards"]["greedy"]
    boards = shapes.billboards(bb["maps"])
    x = shapes.exr(bb["bordered"], "bordered-billboards")
    for k, b in enumerate(boards):
        name, res = f"bb{k:03d}", b["A"].shape[0]
        ch = x[name].channels
        assert ch["depth.Z"].shape == (res + 2, res + 2)
        cov = b["A"] == 1
        np.testing.assert_array_equal(ch["depth.Z"][1:-1, 1:-1][cov], b["depth"][cov])
        for a, c in enumerate("XYZ"):
            np.testing.assert_array_equal(ch[f"normal.{c}"][1:-1, 1:-1][cov], b["normal"][..., a][cov])
        samples = x[f"{name}.samples"].channels["depth.Z"]
        levels = sorted(k2 for k2 in x if k2.startswith(name + ".L"))
        lo, hi = (x[levels[0]].channels[c] for c in ("min.Z", "max.Z"))
        assert lo.shape == (res + 1, res + 1)
        empty = lo >= 1e30
        assert (hi[empty] <= -1e30).all()
        c = np.pad(cov, 1, mode="edge")
        any_corner = c[:-1, :-1] | c[:-1, 1:] | c[1:, :-1] | c[1:, 1:]
        assert empty[~any_corner].all()
        corners = np.stack([samples[:-1, :-1], samples[:-1, 1:], samples[1:, :-1], samples[1:, 1:]], -1)
        limit = 6.0 * max(b["size"][0], b["size"][1]) / res / b["size"][2]
        full = ~empty
        np.testing.assert_allclose(lo[full], corners.min(-1)[full], rtol=0, atol=1e-7)
        np.testing.assert_allclose(hi[full], corners.max(-1)[full], rtol=0, atol=1e-7)
        assert (empty[any_corner] == (np.ptp(corners, -1) > limit)[any_corner]).all()
        for a_name, b_name in zip(levels, levels[1:]):
            clo, chi = (x[a_name].channels[c] for c in ("min.Z", "max.Z"))
            plo, phi = (x[b_name].channels[c] for c in ("min.Z", "max.Z"))
            for i in range(clo.shape[0]):
                for j in range(clo.shape[1]):
                    if clo[i, j] < 1e30:
                        assert plo[i // 2, j // 2] <= clo[i, j] and phi[i // 2, j // 2] >= chi[i, j]


def test_albedo_map_as_documented(tmp_path):
    """A textured OBJ (a quad, its map a 3x2 picture): the object's `albedo_map` PNG holds the picture as it
    was, top row first; the full mesh keeps the OBJ's UVs, the coarse mesh carries UVs too; reading the map at
    the documented texel centres gives the picture's pixels decoded from sRGB."""
    from PIL import Image

    picture = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255]],          # top row: v = 1
                        [[10, 20, 30], [128, 128, 128], [250, 200, 100]]], np.uint8)
    Image.fromarray(picture).save(tmp_path / "card.png")
    (tmp_path / "card.mtl").write_text("newmtl card\nKd 0.6 0.6 0.6\nmap_Kd card.png\n")
    (tmp_path / "quad.obj").write_text(
        "mtllib card.mtl\nusemtl card\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 0.1\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 5/5/1\nf 2/2/1 3/3/1 5/5/1\nf 3/3/1 4/4/1 5/5/1\nf 4/4/1 1/1/1 5/5/1\n")
    r = SpecReader(_bake(tmp_path, "card", HEAD + """
[[objects]]
name = "card"
mesh = "quad.obj"
techniques = { mesh = {}, coarse = { ratios = [0.5] } }
"""))
    obj = r.manifest["objects"]["card"]
    linear = r.albedo_map(obj["albedo_map"])
    c = picture[::-1] / 255.0
    np.testing.assert_allclose(linear, np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4))
    mesh = r.mesh(obj["mesh"])
    np.testing.assert_allclose(mesh["uvs"], mesh["vertices"][:, :2])   # the OBJ's UVs are its x, y
    coarse = r.mesh(obj["techniques"]["coarse"]["meshes"][0]["mesh"])
    assert "uvs" in coarse and len(coarse["uvs"]) == len(coarse["vertices"])
    # the quad's UVs are its x, y: the transfer keeps that on the coarse corners
    np.testing.assert_allclose(coarse["uvs"], coarse["vertices"][:, :2], atol=1e-6)


# --------------------------------------------------------------------------------------------------
# The mesostructure's colour tile
# --------------------------------------------------------------------------------------------------


def tile_albedo(linear: np.ndarray, s, t) -> np.ndarray:
    """The documented lookup of an albedo map (linear, row 0 at v = 0, as SpecReader.albedo_map gives it) at
    texture coordinates (s, t): texel [i, j] centred at ((j + 0.5) / W, (i + 0.5) / H), bilinear, wrapping."""
    h, w = linear.shape[:2]
    x, y = np.asarray(s, float) * w - 0.5, np.asarray(t, float) * h - 0.5
    j0, i0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - j0)[..., None], (y - i0)[..., None]
    g = lambda i, j: linear[i % h, j % w]  # noqa: E731
    return (g(i0, j0) * (1 - fx) * (1 - fy) + g(i0, j0 + 1) * fx * (1 - fy)
            + g(i0 + 1, j0) * (1 - fx) * fy + g(i0 + 1, j0 + 1) * fx * fy)


def test_mesostructure_albedo_part(albedo):
    """mesostructure_albedo names an albedo-map part holding the scene's picture as it was (top row first:
    v = 1), width and height in the metadata; the object's other parts are a mesostructure's."""
    m = albedo.manifest
    obj = m["objects"]["wall"]
    rel = obj["mesostructure_albedo"]
    assert m["parts"][rel]["kind"] == "albedo-map"
    assert (m["parts"][rel]["width"], m["parts"][rel]["height"]) == TILE
    c = tile_picture()[::-1] / 255.0
    np.testing.assert_allclose(albedo.albedo_map(rel), np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4))
    assert m["scene"]["objects"][0]["mesostructure"]["albedo"] == "tile.png"
    assert {p["kind"] for p in m["parts"].values()} == {"mesh", "mesostructure", "albedo-map"}


def test_displaced_meshes_carry_the_base_texture_coordinates(albedo):
    """With a mesostructure albedo the displaced meshes carry texture coordinates: level 0 the base mesh's own,
    level 1 those and each edge's midpoint's."""
    obj = albedo.manifest["objects"]["wall"]
    base = albedo.mesh(obj["mesh"])
    level = {e["level"]: albedo.mesh(e["mesh"]) for e in obj["techniques"]["displaced"]["meshes"]}
    np.testing.assert_array_equal(level[0]["uvs"], base["uvs"])
    uv1 = level[1]["uvs"].astype(np.float64)
    f = base["faces"]
    want = np.concatenate([base["uvs"], *(0.5 * (base["uvs"][f[:, a]] + base["uvs"][f[:, b]])
                                          for a, b in ((0, 1), (1, 2), (2, 0)))]).astype(np.float64)
    assert len(uv1) == len(np.unique(np.round(want, 6), axis=0))
    _, dist = nearest(uv1, want)
    assert dist.max() < 1e-6


def test_albedo_lookup_agrees_with_project(albedo):
    """The project's unpacking and lookup (vdmbake.common.texture.sample, what the reference reads) give the spec's
    albedo at the displaced vertices' tile coordinates T = uv * tiling."""
    import vdmbake.bundle.parts as parts
    from vdmbake.bundle.directory import Bundle
    from vdmbake.common.texture import sample

    obj = albedo.manifest["objects"]["wall"]
    T = albedo.mesh(obj["techniques"]["displaced"]["meshes"][1]["mesh"])["uvs"].astype(np.float64) * (2, 3)
    ours = tile_albedo(albedo.albedo_map(obj["mesostructure_albedo"]), T[:, 0], T[:, 1])
    theirs = sample(Bundle(albedo.root).read(obj["mesostructure_albedo"], parts.ALBEDO_MAP), T)
    np.testing.assert_allclose(ours, theirs, atol=1e-12)


# --------------------------------------------------------------------------------------------------
# Colour maps (billboards, bordered billboards, octahedral) of an asset with its own colours
# --------------------------------------------------------------------------------------------------


def sphere_albedo(mesh, centre, points):
    """The spec's albedo at points of a convex mesh around `centre`: the face the ray from the centre
    through each point meets, its vertex colours interpolated by the point's barycentric weights."""
    tri = mesh["vertices"][mesh["faces"]] - centre                      # (F, 3 corners, 3)
    x = np.einsum("nj,fjk->nfk", points - centre, np.linalg.inv(tri))   # points = x @ tri, per face
    face = np.argmax(x.min(-1), 1)                                      # all weights >= 0 on the face it meets
    w = x[np.arange(len(points)), face]
    w /= w.sum(1, keepdims=True)
    return np.einsum("nk,nkc->nc", w, mesh["colors"].astype(np.float64)[mesh["faces"][face]])


def fill_rings(values, covered, rings=2):
    """The spec's border of a colour map: ring by ring, each empty texel next to covered (or already
    filled) ones takes the mean of those 8-neighbours; the rest 0."""
    v = np.where(covered[..., None], values.astype(np.float64), 0.0)
    ok = covered.copy()
    for _ in range(rings):
        vp, op = np.pad(v, ((1, 1), (1, 1), (0, 0))), np.pad(ok, 1)
        h, w = ok.shape
        acc, cnt = np.zeros_like(v), np.zeros(ok.shape)
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                if di or dj:
                    o = op[1 + di:1 + di + h, 1 + dj:1 + dj + w]
                    acc += o[..., None] * vp[1 + di:1 + di + h, 1 + dj:1 + dj + w]
                    cnt += o
        fill = ~ok & (cnt > 0)
        v[fill] = acc[fill] / cnt[fill, None]
        ok = ok | fill
    return v


def test_colour_maps_show_the_assets_colours(painted):
    """The painted sphere (a PLY with 8-bit sRGB vertex colours): its mesh part carries them as linear
    albedo; each billboard's colour map holds, at every covered texel, the albedo (interpolated vertex
    colours) of the surface point the spec's formula reprojects it to, 0 where A = 0; the bordered maps
    hold it at texel [i + 1, j + 1] with the ring-filled border; the octahedral atlas likewise per view.
    Reading the billboard maps transposed puts colours far off."""
    obj = painted.manifest["objects"]["painted"]
    mesh = painted.mesh(obj["mesh"])
    centre = np.array(obj["centre"])
    d = unit_rows(mesh["vertices"] - centre)
    srgb = painted_rgb8(d) / 255.0
    np.testing.assert_allclose(mesh["colors"], np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4),
                               atol=1e-6)    # linear albedo (sRGB decoded)
    bb = obj["techniques"]["billboards"]["greedy"]
    assert painted.manifest["parts"][bb["maps"]]["albedo"] and painted.manifest["parts"][bb["bordered"]]["albedo"]
    boards = painted.billboards(bb["maps"])
    bordered = painted.exr(bb["bordered"], "bordered-billboards")
    worst, worst_transposed = 0.0, 0.0
    for k, b in enumerate(boards):
        a, depth, albedo, axes = b["A"], b["depth"].astype(np.float64), b["albedo"].astype(np.float64), b["axes"]
        res, cov = a.shape[0], b["A"] == 1
        assert albedo.shape == (res, res, 3) and (albedo[~cov] == 0).all()
        i, j = np.nonzero(cov)

        def reproject(ii, jj):
            return (b["origin"] + ((jj + 0.5) / res * b["size"][0])[:, None] * axes[0]
                    + ((ii + 0.5) / res * b["size"][1])[:, None] * axes[1] + (depth[i, j] * b["size"][2])[:, None] * axes[2])

        worst = max(worst, np.abs(albedo[i, j] - sphere_albedo(mesh, centre, reproject(i, j))).max())
        worst_transposed = max(worst_transposed, np.abs(albedo[i, j] - sphere_albedo(mesh, centre, reproject(j, i))).max())
        ch = bordered[f"bb{k:03d}"].channels
        border = np.stack([ch[f"albedo.{c}"] for c in "RGB"], -1).astype(np.float64)
        assert border.shape == (res + 2, res + 2, 3)
        np.testing.assert_array_equal(border[1:-1, 1:-1][cov], albedo[cov])
        np.testing.assert_allclose(border, fill_rings(np.pad(albedo, ((1, 1), (1, 1), (0, 0))), np.pad(cov, 1)), atol=1e-3)
    # measured: 0.00024 (HALF's rounding, at most 2^-12 below 1); transposed 0.71
    assert worst < 0.001 and worst_transposed > 0.1, (worst, worst_transposed)

    rel = next(iter(obj["techniques"]["octahedral"].values()))
    x = painted.octahedral(rel)
    n, res, cap = x["views"], x["resolution"], x["capture"]
    cov = x["A"] == 1
    albedo = x["albedo"].astype(np.float64)
    np.testing.assert_allclose(albedo, fill_rings(albedo, cov), atol=1e-3)      # the ring-filled border, 0 beyond
    worst = 0.0
    for jv in range(n):
        for iv in range(n):
            e = oct_decode(np.array([-1 + 2 * iv / (n - 1), -1 + 2 * jv / (n - 1)]), False)
            s = 1.0 if abs(2 * iv - n + 1) + abs(2 * jv - n + 1) <= n - 1 else -1.0
            q = -1 / (s + e[2])
            bq = e[0] * e[1] * q
            u, v = np.array([1 + s * e[0] ** 2 * q, s * bq, -s * e[0]]), np.array([bq, s + e[1] ** 2 * q, -e[1]])
            e, u, v = e @ x["basis"], u @ x["basis"], v @ x["basis"]
            tile = np.s_[jv * res:(jv + 1) * res, iv * res:(iv + 1) * res]
            rb, ra = np.nonzero(cov[tile])
            p = (x["centre"] + cap * e + (((ra + 0.5) / res * 2 - 1) * cap)[:, None] * u
                 + (((rb + 0.5) / res * 2 - 1) * cap)[:, None] * v - (x["depth"][tile][rb, ra] * 2.0 * cap)[:, None] * e)
            worst = max(worst, np.abs(albedo[tile][rb, ra] - sphere_albedo(mesh, centre, p)).max())
    assert worst < 0.001, worst   # measured: 0.00024 (HALF's rounding)


def test_colour_maps_agree_with_project_unpacking(painted):
    import vdmbake.bundle.parts as parts
    from vdmbake.bundle.directory import Bundle

    obj = painted.manifest["objects"]["painted"]
    bundle = Bundle(painted.root)
    np.testing.assert_array_equal(painted.mesh(obj["mesh"])["colors"], bundle.read(obj["mesh"], parts.MESH).colors)
    bb = obj["techniques"]["billboards"]["greedy"]
    for ours, theirs in zip(painted.billboards(bb["maps"]), bundle.read(bb["maps"], parts.BILLBOARDS)):
        np.testing.assert_array_equal(ours["albedo"], theirs.albedo)
    x = painted.exr(bb["bordered"], "bordered-billboards")
    for k, theirs in enumerate(bundle.read(bb["bordered"], parts.BORDERED)):
        np.testing.assert_array_equal(np.stack([x[f"bb{k:03d}"].channels[f"albedo.{c}"] for c in "RGB"], -1), theirs.albedo)
    rel = next(iter(obj["techniques"]["octahedral"].values()))
    np.testing.assert_array_equal(painted.octahedral(rel)["albedo"], bundle.read(rel, parts.OCTAHEDRAL).albedo)
