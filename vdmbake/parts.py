"""The bundle's part kinds: what each file holds, packed (bake) and unpacked (render) side by side.

Each kind turns a value into a file's bytes plus the metadata the manifest records beside the
part's checksum, and back. docs/bundle.md describes the same layouts for readers that do not use
this package. PLY parts are binary little-endian (vdmbake.ply); EXR parts are zip-compressed,
float32, one EXR part per named table, data channels with dotted names (vdmbake.exr).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from . import exr, ply, pyramid, quadric_mesh, quadrics, texture
from .errors import InputError
from .schema import REQUIRED, Boolean, Choice, Integer, Invalid, Number, Tables, Type, Vector, setting

COUNT = Integer(0, 2**31 - 1)   # element counts: PLY and EXR index with 32-bit integers


@dataclass(frozen=True)
class PartKind:
    name: str
    suffix: str
    pack: Callable[[Any], tuple[bytes, dict]]        # value -> (file bytes, manifest metadata)
    unpack: Callable[[bytes, dict, str], Any]        # (file bytes, manifest metadata, origin) -> value;
                                                     # checks the value against the metadata, finite numbers
                                                     # and index ranges, raising InputError
    meta: type | None = None                         # the metadata's schema (vdmbake.schema dataclass)


def _channels(data: bytes, origin: str) -> dict[str, dict[str, np.ndarray]]:
    try:
        exr.check_size(data)
        return exr.read(data)
    except Exception as e:  # the binding raises RuntimeError and others for malformed files
        raise InputError(f"{origin}: unreadable EXR ({e}).") from None


def _bad(origin: str, what: str):
    raise InputError(f"{origin}: {what}; the part does not match its manifest entry. Re-bake with vdmbake --force.")


def _finite(origin: str, **arrays) -> None:
    for name, a in arrays.items():
        if a is not None and not np.isfinite(a).all():
            _bad(origin, f"{name} holds NaN or Inf")


def _shape(origin: str, name: str, a: np.ndarray, shape: tuple) -> None:
    if a.shape != shape:
        _bad(origin, f"{name} has shape {a.shape}, expected {shape}")


def _need(parts: dict, part: str, channels, origin: str) -> list[np.ndarray]:
    if part not in parts or any(c not in parts[part] for c in channels):
        raise InputError(f"{origin}: EXR part {part!r} with channels {', '.join(channels)} is missing.")
    return [parts[part][c] for c in channels]


# --- meshes: full, coarse, displaced ----------------------------------------------------------------

@dataclass(frozen=True)
class MeshMeta:
    vertices: int = setting(REQUIRED, Integer(3, 2**31 - 1), "vertices")
    faces: int = setting(REQUIRED, Integer(1, 2**31 - 1), "triangles")


def _unpack_mesh(data, meta, origin):
    m = ply.from_bytes(data, origin)
    if not len(m.faces):
        _bad(origin, "the mesh has no face")
    if (len(m.vertices), len(m.faces)) != (meta["vertices"], meta["faces"]):
        _bad(origin, f"{len(m.vertices)} vertices and {len(m.faces)} faces where the manifest says "
                     f"{meta['vertices']} and {meta['faces']}")
    if m.faces.size and (m.faces.min() < 0 or m.faces.max() >= len(m.vertices)):
        _bad(origin, f"face indices span [{m.faces.min()}, {m.faces.max()}] over {len(m.vertices)} vertices")
    f = m.frame
    _finite(origin, vertices=m.vertices, normals=m.normals, uvs=m.uvs,
            frame=None if f is None else np.concatenate([f.dpdu, f.dpdv, f.k1[:, None], f.k2[:, None], f.d1], 1))
    return m


MESH = PartKind("mesh", ".ply",
                lambda m: (ply.to_bytes(m), {"vertices": len(m.vertices), "faces": len(m.faces)}),
                _unpack_mesh, MeshMeta)

# --- spheres and capped cylinders ------------------------------------------------------------------

@dataclass(frozen=True)
class QuadricsMeta:
    spheres: int = setting(REQUIRED, COUNT, "spheres")
    cylinders: int = setting(REQUIRED, COUNT, "capped cylinders")


def _unpack_quadrics(data, meta, origin):
    q = quadrics.from_bytes(data, origin)
    if (len(q.spheres), len(q.cylinders)) != (meta["spheres"], meta["cylinders"]) or not len(q.spheres) + len(q.cylinders):
        _bad(origin, f"{len(q.spheres)} spheres and {len(q.cylinders)} cylinders where the manifest says "
                     f"{meta['spheres']} and {meta['cylinders']} (and at least one is needed)")
    _finite(origin, spheres=q.spheres, cylinders=q.cylinders)
    if (q.spheres[:, 3] <= 0).any() or (q.cylinders[:, 6] <= 0).any() or (
            np.linalg.norm(q.cylinders[:, 3:6] - q.cylinders[:, :3], axis=1) <= 0).any():
        _bad(origin, "a sphere or cylinder has no volume (radius or length 0)")
    return q


QUADRICS = PartKind("quadrics", ".ply",
                    lambda q: (quadrics.to_bytes(q), {"spheres": len(q.spheres), "cylinders": len(q.cylinders)}),
                    _unpack_quadrics, QuadricsMeta)

def _unpack_viewer_mesh(data, meta, origin):
    m, rgb = quadric_mesh.from_bytes(data, origin)
    if (len(m.vertices), len(m.faces)) != (meta["vertices"], meta["faces"]):
        _bad(origin, f"{len(m.vertices)} vertices and {len(m.faces)} faces where the manifest says "
                     f"{meta['vertices']} and {meta['faces']}")
    if m.faces.size and (m.faces.min() < 0 or m.faces.max() >= len(m.vertices)):
        _bad(origin, f"face indices span [{m.faces.min()}, {m.faces.max()}] over {len(m.vertices)} vertices")
    _finite(origin, vertices=m.vertices, normals=m.normals)
    return m, rgb


VIEWER_MESH = PartKind("viewer-mesh", ".ply",
                       lambda mc: (quadric_mesh.to_bytes(*mc), {"vertices": len(mc[0].vertices), "faces": len(mc[0].faces)}),
                       _unpack_viewer_mesh, MeshMeta)


# --- albedo maps: an asset's base-colour texture, a mesostructure tile's colour ----------------------

@dataclass(frozen=True)
class AlbedoMapMeta:
    width: int = setting(REQUIRED, Integer(1, 65536), "texels per row")
    height: int = setting(REQUIRED, Integer(1, 65536), "rows")


def _pack_albedo_map(a: np.ndarray):
    """8-bit sRGB PNG, as the asset's texture was (no precision lost), top row first as viewers expect."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(a[::-1]), "RGB").save(buf, "PNG", optimize=False, compress_level=6)
    return buf.getvalue(), {"width": a.shape[1], "height": a.shape[0]}


def _unpack_albedo_map(data, meta, origin) -> np.ndarray:
    import io

    from PIL import Image

    try:
        image = Image.open(io.BytesIO(data), formats=["PNG"])
        if image.mode != "RGB" or image.size != (meta["width"], meta["height"]):
            _bad(origin, f"a {image.mode} PNG of {image.size[0]}x{image.size[1]} where an RGB one of "
                         f"{meta['width']}x{meta['height']} was written")
        return texture.from_image(image)
    except InputError:
        raise
    except Exception as e:  # PIL raises many types for damaged files
        raise InputError(f"{origin}: unreadable PNG ({type(e).__name__}: {e}).") from None


ALBEDO_MAP = PartKind("albedo-map", ".png", _pack_albedo_map, _unpack_albedo_map, AlbedoMapMeta)


# --- mesostructure: the height field and its normal map --------------------------------------------

@dataclass
class MesostructureMaps:
    """One tile of the mesostructure (Wang2003 §3), N x N texels, row 0 at tile v = 0 (image order:
    [row, column] = [v, u]). heights in [0, 1] (1 = the reference surface); normals: unit
    texture-space normals of the displaced height field (z along the surface normal, the depth in
    tile units), the shading normals of every mesostructure technique and of the reference."""
    heights: np.ndarray   # (N, N) float32
    normals: np.ndarray   # (N, N, 3) float32


def _pack_mesostructure(m: MesostructureMaps):
    data = exr.to_bytes({"height": {"h": m.heights},
                         "normal": {f"normal.{a}": m.normals[..., i] for i, a in enumerate("XYZ")}})
    return data, {"size": int(m.heights.shape[0])}


def _unpack_mesostructure(data, meta, origin) -> MesostructureMaps:
    parts = _channels(data, origin)
    (h,) = _need(parts, "height", ["h"], origin)
    n = np.stack(_need(parts, "normal", ["normal.X", "normal.Y", "normal.Z"], origin), -1)
    size = meta["size"]
    _shape(origin, "height", h, (size, size))
    _shape(origin, "normal", n, (size, size, 3))
    _finite(origin, height=h, normal=n)
    return MesostructureMaps(h, n)


@dataclass(frozen=True)
class MesostructureMeta:
    size: int = setting(REQUIRED, Integer(4, 1024), "texels per tile side")


MESOSTRUCTURE = PartKind("mesostructure", ".exr", _pack_mesostructure, _unpack_mesostructure, MesostructureMeta)


# --- VDM: the SVD-compressed view-dependent displacement and maximal-view-angle tables --------------

@dataclass
class VDMTables:
    """d_VDM(x, y, phi, theta, c) ~ sum_i W[phi, y, x, i] E_vdm[i, c, theta] and theta_MVM(x, y, phi, c)
    ~ sum_i W[phi, y, x, i] E_mvm[i, c] (Wang2003 §3.3). x, y: texel centres of the tile; phi, theta: bin
    centres of [0, 2 pi) and [0, pi / 2]; c: the curvature samples listed in the manifest. d in
    texture units (extended d = l / sin(theta) on curved surfaces, Wang2003 Appendix), theta_MVM in radians.
    W is stored as float32, float16 or uint8 codes (vdmbake/vdm_storage.py): the weight is
    W * scale[i] + offset[i] (scale 1, offset 0 for floats)."""
    W: np.ndarray       # (n_phi, N, N, k) float32, float16 or uint8
    E_vdm: np.ndarray   # (k, n_c, n_theta) float32
    E_mvm: np.ndarray   # (k, n_c) float32
    scale: np.ndarray   # (k,) float32
    offset: np.ndarray  # (k,) float32


def _pack_vdm(t: VDMTables):
    n_phi, n, _, k = t.W.shape
    W = t.W.reshape(n_phi * n, n, k)        # rows: phi-major blocks of y
    codes = t.W.dtype == np.uint8           # EXR has no 8-bit channels: codes go in UINT ones (zipped, near a byte)
    tables = {"W": {f"W.{i:03d}": W[..., i].astype(np.uint32) if codes else W[..., i] for i in range(k)},
              "E_vdm": {f"E.{i:03d}": t.E_vdm[i] for i in range(k)},
              "E_mvm": {f"E.{i:03d}": t.E_mvm[i][None] for i in range(k)}}
    if codes:
        tables["W_dequant"] = {"scale": t.scale[None].astype(np.float32), "offset": t.offset[None].astype(np.float32)}
    return exr.to_bytes(tables), {"k": k, "n_phi": n_phi, "storage": str(t.W.dtype)}


def _unpack_vdm(data, meta, origin) -> VDMTables:
    parts = _channels(data, origin)
    k, n_phi = int(meta["k"]), int(meta["n_phi"])
    W = np.stack(_need(parts, "W", [f"W.{i:03d}" for i in range(k)], origin), -1)
    n = W.shape[1]
    E = [f"E.{i:03d}" for i in range(k)]
    if meta.get("storage") == "uint8":
        scale, offset = (a[0] for a in _need(parts, "W_dequant", ["scale", "offset"], origin))
        W = W.astype(np.uint8)
    else:
        scale, offset = np.ones(k, np.float32), np.zeros(k, np.float32)
    E_vdm, E_mvm = np.stack(_need(parts, "E_vdm", E, origin)), np.stack(_need(parts, "E_mvm", E, origin))
    if W.shape[0] != n_phi * n or E_mvm.shape[1] != 1 or E_mvm.shape[2] != E_vdm.shape[1]:
        _bad(origin, f"tables of shapes W {W.shape}, E_vdm {E_vdm.shape}, E_mvm {E_mvm.shape} for n_phi = {n_phi}")
    _finite(origin, W=W, E_vdm=E_vdm, E_mvm=E_mvm, scale=scale, offset=offset)
    return VDMTables(W.reshape(n_phi, n, n, k), E_vdm, E_mvm[:, 0], scale, offset)


@dataclass(frozen=True)
class VDMMeta:
    k: int = setting(REQUIRED, Integer(1, 4096), "eigenfunctions stored")
    n_phi: int = setting(REQUIRED, Integer(1, 256), "azimuth samples")
    storage: str = setting(REQUIRED, Choice("float32", "float16", "uint8"), "the weights' format")


VDM = PartKind("vdm", ".exr", _pack_vdm, _unpack_vdm, VDMMeta)


# --- enhanced billboards ----------------------------------------------------------------------------

@dataclass
class Billboard:
    """One enhanced billboard (Vichitvejpaisal2005 §3.1): a box looking along w at part of the model, and its
    R x R maps; texel [row, col] = (v, u), row 0 at v = 0."""
    origin: np.ndarray   # (3,) world corner of the box at texel (0, 0), depth 0
    axes: np.ndarray     # (3, 3) rows u, v, w (w = view direction into the model), right-handed
    size: np.ndarray     # (3,) world extent of the box along u, v, w
    alpha: np.ndarray    # (R, R) float32 coverage 0/1
    depth: np.ndarray    # (R, R) float32 in [0, 1] along w (0 = box front), 1 where alpha is 0
    normal: np.ndarray   # (R, R, 3) float32 world unit shading normal facing -w, 0 where alpha is 0
    albedo: np.ndarray | None = None   # (R, R, 3) the colour map (Vichitvejpaisal2005 §3.1): linear RGB albedo, 0 where alpha
                                       # is 0; only for assets with their own colours (texture.has_albedo)


def _albedo_channels(albedo: np.ndarray | None) -> dict:
    """A colour map as EXR channels: linear RGB in HALF, EXR's usual colour type (an 8-bit sRGB texture or
    vertex colour loses nothing visible there); none at all for an asset without colours."""
    return {} if albedo is None else {f"albedo.{c}": albedo[..., k].astype(np.float16) for k, c in enumerate("RGB")}


def _albedo_meta(values) -> dict:
    """The manifest's `albedo: true` when the maps carry colour (left out otherwise: uncoloured parts unchanged)."""
    values = list(values)
    if any(a is not None for a in values) and any(a is None for a in values):
        raise ValueError("colour maps for some maps only")
    return {"albedo": True} if values and values[0] is not None else {}


def _unpack_albedo(tables, name: str, meta, shape: tuple, origin: str) -> np.ndarray | None:
    if not meta.get("albedo"):
        return None
    a = np.stack(_need(tables, name, [f"albedo.{c}" for c in "RGB"], origin), -1).astype(np.float32)
    _shape(origin, f"{name} albedo", a, shape + (3,))
    _finite(origin, **{f"{name} albedo": a})
    return a


def _pack_billboards(boards: list[Billboard]):
    data = exr.to_bytes({f"bb{i:03d}": {"A": b.alpha, "depth.Z": b.depth,
                                        **{f"normal.{a}": b.normal[..., k] for k, a in enumerate("XYZ")},
                                        **_albedo_channels(b.albedo)}
                         for i, b in enumerate(boards)})
    return data, {"boards": [{"origin": b.origin.tolist(), "axes": b.axes.tolist(), "size": b.size.tolist()}
                             for b in boards], **_albedo_meta(b.albedo for b in boards)}


def _unpack_billboards(data, meta, origin) -> list[Billboard]:
    parts = _channels(data, origin) if meta["boards"] else {}
    out = []
    for i, b in enumerate(meta["boards"]):
        a, d, nx, ny, nz = _need(parts, f"bb{i:03d}", ["A", "depth.Z", "normal.X", "normal.Y", "normal.Z"], origin)
        axes = np.asarray(b["axes"], np.float64)
        _finite(origin, **{f"bb{i:03d}": np.stack([a, d, nx, ny, nz])})
        if abs(np.linalg.det(axes) - 1) > 1e-3 or (np.asarray(b["size"]) <= 0).any():
            _bad(origin, f"billboard {i}: axes not a right-handed orthonormal frame or a size not positive")
        out.append(Billboard(np.asarray(b["origin"], np.float64), axes,
                             np.asarray(b["size"], np.float64), a, d, np.stack([nx, ny, nz], -1),
                             _unpack_albedo(parts, f"bb{i:03d}", meta, a.shape, origin)))
    return out


class Matrix(Type):
    """rows x cols finite numbers, as nested lists."""

    def __init__(self, rows: int, cols: int):
        self.row, self.rows = Vector(cols), rows
        self.text = f"a list of {rows} rows of {cols} finite numbers"

    def parse(self, raw):
        if not isinstance(raw, list) or len(raw) != self.rows:
            raise Invalid
        return tuple(self.row.parse(r) for r in raw)


@dataclass(frozen=True)
class BoardMeta:
    origin: tuple = setting(REQUIRED, Vector(3), "world corner of the box")
    axes: tuple = setting(REQUIRED, Matrix(3, 3), "rows u, v, w")
    size: tuple = setting(REQUIRED, Vector(3, 0.0), "extent along u, v, w")


@dataclass(frozen=True)
class BillboardsMeta:
    boards: tuple = setting(REQUIRED, Tables(BoardMeta), "each billboard's box")
    albedo: bool = setting(False, Boolean(), "every billboard has a colour map")


BILLBOARDS = PartKind("billboards", ".exr", _pack_billboards, _unpack_billboards, BillboardsMeta)


@dataclass
class BorderedMaps:
    """One billboard's maps as its renderers sample them (vdmbake/billboard_maps.py): normal (xyz) and
    depth (w) with a one-texel border, the border and the empty texels near covered ones extrapolated;
    and, for the hierarchical march only, the min/max pyramid of its depth surface (empty cells marked);
    for an asset with colours, its colour map with the same border (the empty texels near covered ones
    hold their covered neighbours' mean)."""
    maps: np.ndarray                       # (R+2, R+2, 4) float32
    pyramid: pyramid.Pyramid | None = None
    albedo: np.ndarray | None = None       # (R+2, R+2, 3) float32 linear RGB


def _pack_bordered(boards: list[BorderedMaps]):
    tables = {}
    for i, b in enumerate(boards):
        tables[f"bb{i:03d}"] = {**{f"normal.{a}": b.maps[..., k] for k, a in enumerate("XYZ")}, "depth.Z": b.maps[..., 3],
                                **_albedo_channels(b.albedo)}
        if b.pyramid is not None:
            tables.update({f"bb{i:03d}.{k}": v for k, v in pyramid.to_parts(b.pyramid).items()})
    traced = [b.pyramid is not None for b in boards]
    return exr.to_bytes(tables), {"boards": len(boards), "pyramids": bool(traced) and all(traced),
                                  "mode": pyramid.CLAMP, **_albedo_meta(b.albedo for b in boards)}


def _unpack_bordered(data, meta, origin) -> list[BorderedMaps]:
    tables = _channels(data, origin) if meta["boards"] else {}
    out = []
    for i in range(meta["boards"]):
        name = f"bb{i:03d}"
        maps = np.stack(_need(tables, name, ["normal.X", "normal.Y", "normal.Z", "depth.Z"], origin), -1)
        pyr = None
        if meta["pyramids"]:
            sub = {k[len(name) + 1:]: v for k, v in tables.items() if k.startswith(name + ".")}
            _need(sub, "samples", ["depth.Z"], f"{origin} ({name})")
            pyr = pyramid.from_parts(sub, meta["mode"])
        _finite(origin, **{name: maps})
        out.append(BorderedMaps(maps.astype(np.float32), pyr, _unpack_albedo(tables, name, meta, maps.shape[:2], origin)))
    return out


@dataclass(frozen=True)
class BorderedMeta:
    boards: int = setting(REQUIRED, COUNT, "billboards")
    pyramids: bool = setting(REQUIRED, Boolean(), "every billboard has its pyramid")
    mode: str = setting(REQUIRED, Choice(*pyramid.MODES), "the pyramids' addressing")
    albedo: bool = setting(False, Boolean(), "every billboard has a colour map")


BORDERED = PartKind("bordered-billboards", ".exr", _pack_bordered, _unpack_bordered, BorderedMeta)

# --- min/max mip pyramid of a depth field (the hierarchical tracer's, vdmbake/pyramid.py) ------------

def _pack_pyramid(p: pyramid.Pyramid):
    return exr.to_bytes(pyramid.to_parts(p)), {"mode": p.mode, "levels": p.top + 1}


def _unpack_pyramid(data, meta, origin):
    tables = _channels(data, origin)
    _need(tables, "samples", ["depth.Z"], origin)
    levels = sorted(k for k in tables if k.startswith("L"))
    if len(levels) != meta["levels"]:
        _bad(origin, f"{len(levels)} levels where the manifest says {meta['levels']}")
    for k in levels:
        _need(tables, k, ["min.Z", "max.Z"], origin)
    p = pyramid.from_parts(tables, meta["mode"])
    _finite(origin, samples=p.samples)
    return p


@dataclass(frozen=True)
class PyramidMeta:
    mode: str = setting(REQUIRED, Choice(*pyramid.MODES), "addressing")
    levels: int = setting(REQUIRED, Integer(1, 64), "mip levels")


PYRAMID = PartKind("pyramid", ".exr", _pack_pyramid, _unpack_pyramid, PyramidMeta)

# --- octahedral impostors (Brucks 2018; vdmbake/octahedral.py) ----------------------------------------

@dataclass
class OctahedralAtlas:
    """N x N orthographic views of an object on the lattice of an octahedral map of directions (the full
    sphere, or the hemisphere above the map's z: hemi), R x R texels each, in one atlas of N R x N R
    texels: view (i, j) is the tile at rows j R.., columns i R.. (row 0 at v = 0). View k looks along
    -e_k over the square [-capture, capture]^2 of its frame (u_k, v_k) around `centre`; the frames and
    the map follow vdmbake/octahedral.py (`basis` turns world directions into the map's)."""
    views: int             # N
    hemi: bool
    basis: np.ndarray      # (3, 3) rows x, y, z of the map's frame (z: up)
    centre: np.ndarray     # (3,) world centre of the bounding sphere: every view's centre
    radius: float          # the bounding sphere's radius
    capture: float         # half side of every view's square, world units
    normal: np.ndarray     # (N R, N R, 2) float32 in [-1, 1]: the normal in its view's frame (u, v, e), octahedral code
    depth: np.ndarray      # (N R, N R) float32 in [0, 1] along -e_k over 2 capture, 1 where not covered
    coverage: np.ndarray   # (N R, N R) float32, 1 where a surface was hit, else 0
    rays: int              # rays the bake traced
    albedo: np.ndarray | None = None   # (N R, N R, 3) float32 linear RGB albedo of the surface (around silhouettes
                                       # the covered neighbours' mean); only for assets with their own colours

    @property
    def resolution(self) -> int:
        """R: texels per side of every view."""
        return self.depth.shape[0] // self.views


def _pack_octahedral(a: OctahedralAtlas):
    data = exr.to_bytes({"atlas": {"normal.U": a.normal[..., 0], "normal.V": a.normal[..., 1],
                                   "depth.Z": a.depth, "A": a.coverage, **_albedo_channels(a.albedo)}})
    return data, {"views": a.views, "resolution": a.resolution, "hemi": a.hemi, "basis": np.asarray(a.basis).tolist(),
                  "centre": np.asarray(a.centre).tolist(), "radius": float(a.radius), "capture": float(a.capture),
                  "rays": int(a.rays), **_albedo_meta([a.albedo])}


def _unpack_octahedral(data, meta, origin) -> OctahedralAtlas:
    tables = _channels(data, origin)
    nu, nv, d, a = _need(tables, "atlas", ["normal.U", "normal.V", "depth.Z", "A"], origin)
    side = int(meta["views"]) * int(meta["resolution"])
    for name, x in (("normal.U", nu), ("normal.V", nv), ("depth.Z", d), ("A", a)):
        _shape(origin, f"atlas {name} (the manifest says {meta['views']} views of {meta['resolution']}^2)", x,
               (side, side))
    _finite(origin, atlas=np.stack([nu, nv, d, a]))
    if abs(np.linalg.det(np.asarray(meta["basis"], np.float64)) - 1) > 1e-3:
        _bad(origin, "basis not a right-handed orthonormal frame")
    return OctahedralAtlas(int(meta["views"]), bool(meta["hemi"]), np.asarray(meta["basis"], np.float64),
                           np.asarray(meta["centre"], np.float64), float(meta["radius"]), float(meta["capture"]),
                           np.stack([nu, nv], -1), d, a, int(meta["rays"]),
                           _unpack_albedo(tables, "atlas", meta, (side, side), origin))


@dataclass(frozen=True)
class OctahedralMeta:
    views: int = setting(REQUIRED, Integer(2, 64), "N: views per side of the map")
    resolution: int = setting(REQUIRED, Integer(16, 4096), "R: texels per side of every view")
    hemi: bool = setting(REQUIRED, Boolean(), "the upper hemisphere only")
    basis: tuple = setting(REQUIRED, Matrix(3, 3), "rows x, y, z of the map's frame")
    centre: tuple = setting(REQUIRED, Vector(3), "the bounding sphere's centre")
    radius: float = setting(REQUIRED, Number(0.0, open_lo=True), "the bounding sphere's radius")
    capture: float = setting(REQUIRED, Number(0.0, open_lo=True), "half side of every view's square")
    rays: int = setting(REQUIRED, COUNT, "rays the bake traced")
    albedo: bool = setting(False, Boolean(), "the atlas has the surface's colour")


OCTAHEDRAL = PartKind("octahedral", ".exr", _pack_octahedral, _unpack_octahedral, OctahedralMeta)

KINDS = {k.name: k for k in (MESH, QUADRICS, VIEWER_MESH, ALBEDO_MAP, MESOSTRUCTURE, VDM, BILLBOARDS, BORDERED, PYRAMID,
                             OCTAHEDRAL)}


def stored(kind: PartKind, value):
    """`value` as a reader of the bundle sees it (float32 rounding included): what is derived from a
    part at bake time is derived from this, so that it agrees with what the renderer reads."""
    data, meta = kind.pack(value)
    return kind.unpack(data, meta, f"stored {kind.name}")
