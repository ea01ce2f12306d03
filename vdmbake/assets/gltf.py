"""glTF 2.0 meshes read from the file's own JSON and accessors (not through trimesh, whose scene merge packs several
base-colour pictures and the materials' factors into one atlas whose UVs point at other regions, and multiplies a
factor in twice): the default scene's node tree with each node's transform (§3.5.2), each triangle primitive with
its POSITION, NORMAL, TEXCOORD_n and COLOR_0 in any legal encoding, sparse accessors (§3.6.2.3), morph targets at
the default weights (§3.7.2.2), strips and fans (§3.7.2.1), EXT_mesh_gpu_instancing's copies, and its material:
baseColorFactor x COLOR_0 as one linear colour per vertex, applied once (§3.9.2), and the base-colour picture kept
as the file's own sRGB texels, read at its texCoord through its KHR_texture_transform.
Several pictures (or pictured and unpictured primitives, or a picture whose wrap mode is not REPEAT where its UVs
reach the edge) in one file go into an atlas built here, each picture laid out over the UVs that read it as its
sampler's wrap modes read it (at least with a one-texel gutter), so the renderer's and the reference's bilinear
read (vdmbake.common.texture.sample) reads every texel as the file means it.

The file is untrusted: an extension it requires and this reader does not apply is refused (§3.12), and its work is
bounded before anything is allocated: elements no byte stores by the file's size, each node visited once, the copies
placed by MAX_COPIES and their vertices by the bake's memory budget (vdmbake.bundle.budget)."""
from __future__ import annotations

import base64
import binascii
import copy
import functools
import io
from dataclasses import dataclass

import numpy as np

from ..bundle import budget
from ..common import texture
from ..errors import InputError, cut, escaped
from ..formats.gltf import (BYTE, COLOUR_TYPES, DTYPES, FLOAT, INDEX_TYPES, MODES, REPEAT, SHORT, UNSIGNED_INT,
                            WIDTHS, WRAPS)
from .references import MAX_TEXTURE_SIDE, check_picture, gltf_buffer, gltf_tree

WHITE_TILE = 32           # the side of the white tile an atlas gives unpictured primitives: at (0, 0), the atlas's
                          # sides multiples of it, so its box-filtered mip levels stay white to level 5 (a mipmapping
                          # engine reading the exported map, or a level forced, does not average in its neighbours)
MAX_ELEMENTS = 1 << 26     # the most elements of an accessor one file may make (our bound)
MAX_COPIES = 1_000_000     # the most meshes one file may place (nodes and their EXT_mesh_gpu_instancing copies), as
                           # many as a scene's instances.scatter makes
BYTES_PER_VERTEX = 1024    # peak memory per vertex placed, through the read, the merge and the normals: 757 bytes
                           # (tracemalloc, a 90,000-vertex grid with NORMAL and TEXCOORD_0), rounded up
_DRACO, _MESHOPT = "KHR_draco_mesh_compression", "EXT_meshopt_compression"   # decoded: opened
# The extensions a file may require (glTF 2.0 §3.12: a loader refuses a file requiring any other): what this reader
# honours. KHR_texture_transform: applied to the base colour's UVs (_material); KHR_mesh_quantization:
# the integer attributes values() reads; EXT_mesh_gpu_instancing: its copies placed (_gpu_instances);
# KHR_draco_mesh_compression and EXT_meshopt_compression: decoded into plain accessors and views (opened).
REQUIRED_READ = ("KHR_texture_transform", "KHR_mesh_quantization", "EXT_mesh_gpu_instancing", _DRACO, _MESHOPT)


@dataclass
class Opened:
    """A glTF file as read_gltf reads it: its JSON with compressed data rewritten as plain (each meshopt bufferView
    over its decoded bytes, each Draco primitive over accessors of its decoded attributes), `buffer(i)` the bytes of
    buffer i (the decoded data as buffers after the file's own), and `stored` the bytes of the file, the files it
    reaches and the decoded data."""
    tree: dict
    buffer: object
    stored: int


def opened(files: dict, origin: str) -> Opened:
    """The glTF among `files` (references.reached_files) parsed, its extensions checked (check_extensions) and its
    compressed data decoded (_meshopt, then _draco, whose stream may lie in a meshopt view), so that decoded data
    meets every check plain data meets (check_accessors, values, the memory budget)."""
    try:
        tree = gltf_tree(files)
    except (ValueError, RecursionError) as e:        # JSONDecodeError and UnicodeDecodeError are ValueErrors
        raise InputError(f"{origin}: not readable glTF JSON ({type(e).__name__}: {cut(str(e))}); fix the "
                         "file.") from None
    if not isinstance(tree, dict):
        raise InputError(f"{origin}: its JSON is a {type(tree).__name__}, where glTF 2.0 gives an object; fix the "
                         "file.")
    check_extensions(tree, origin)
    buffer = functools.cache(lambda i: (_at(tree, "buffers", i, origin), gltf_buffer(files, tree, i, origin))[1])
    stored = sum(len(f.data) for f in files.values())
    blobs, first = [], len(tree.get("buffers", [])) if isinstance(tree.get("buffers", []), list) else 0

    def added(data: bytes) -> int:
        """A buffer of decoded bytes, after the file's own: its index."""
        blobs.append(data)
        tree.setdefault("buffers", []).append({"byteLength": len(data)})
        return first + len(blobs) - 1

    def read(i):
        return blobs[i - first] if type(i) is int and i >= first else buffer(i)

    try:
        if _meshopt_views(tree) or _draco_primitives(tree):
            tree = copy.deepcopy(tree)   # rewritten below (the file's own buffers keep their entries)
            _meshopt(tree, buffer, added, origin)
            _draco(tree, read, added, origin)
    except (KeyError, IndexError, TypeError, AttributeError, ValueError) as e:
        raise InputError(f"{origin}: cannot read its compressed data ({type(e).__name__}: "
                         f"{cut(str(e))}); fix the file.") from None
    return Opened(tree, read if blobs else buffer, stored + sum(map(len, blobs)))


def _meshopt_views(tree: dict) -> list:
    """(index, bufferView) of every bufferView with EXT_meshopt_compression."""
    return [(v, view) for v, view in enumerate(tree.get("bufferViews", []))
            if isinstance(view, dict) and _MESHOPT in (view.get("extensions") or {})]


def _draco_primitives(tree: dict) -> list:
    """(mesh, primitive) of every primitive with KHR_draco_mesh_compression."""
    return [(m, p) for m, mesh in enumerate(tree.get("meshes", [])) if isinstance(mesh, dict)
            for p, prim in enumerate(mesh.get("primitives", []))
            if isinstance(prim, dict) and _DRACO in (prim.get("extensions") or {})]


def _meshopt(tree: dict, buffer, added, origin: str) -> None:
    """Every bufferView with EXT_meshopt_compression rewritten over its decoded bytes (the `meshopt` package, the
    JavaScript decoder's functions over meshoptimizer 1.3's C++): `count` elements of `byteStride` bytes decoded
    in its mode (ATTRIBUTES, TRIANGLES, INDICES) and filter (NONE, OCTAHEDRAL, QUATERNION, EXPONENTIAL), in a
    buffer of their own; the view's byteLength must be what they fill (the extension: count x byteStride). The
    views' decoded bytes are held to the memory budget before any is decoded; the fallback buffer is never read."""
    views = _meshopt_views(tree)
    if not views:
        return
    import meshopt

    sizes = []
    for v, view in views:
        ext, shown = view["extensions"][_MESHOPT], f"{origin}: bufferView {v} ({_MESHOPT})"
        count, stride, mode = ext.get("count"), ext.get("byteStride"), ext.get("mode")
        filter_ = ext.get("filter", "NONE")
        sizes_ok = {"ATTRIBUTES": stride in range(4, 257, 4), "TRIANGLES": stride in (2, 4) and count % 3 == 0,
                    "INDICES": stride in (2, 4)} if type(count) is int and type(stride) is int and count > 0 else {}
        if not sizes_ok.get(mode) or filter_ not in ("NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL") or (
                mode != "ATTRIBUTES" and filter_ != "NONE") or view.get("byteLength") != count * stride:
            raise InputError(f"{shown}: count {escaped(repr(count))}, byteStride {escaped(repr(stride))}, mode "
                             f"{escaped(repr(mode))}, filter {escaped(repr(filter_))} for a view of "
                             f"{escaped(repr(view.get('byteLength')))} bytes; the extension gives a positive count, "
                             "ATTRIBUTES of 4 to 256 bytes in fours (filtered or not), TRIANGLES (a count in threes) "
                             "or INDICES of 2 or 4 bytes unfiltered, and a byteLength of count x byteStride; fix the "
                             "file.")
        sizes.append(count * stride)
    budget.check(2 * sum(sizes), f"{origin}: its {len(views)} meshopt-compressed bufferViews, decoded ({sum(sizes)} "
                 "bytes) beside the file,", "simplify the mesh")
    for v, view in views:
        ext, shown = view["extensions"].pop(_MESHOPT), f"{origin}: bufferView {v} ({_MESHOPT})"
        start, length = ext.get("byteOffset", 0), ext.get("byteLength")
        data = buffer(ext["buffer"]) if type(ext.get("buffer")) is int else None
        if data is None or not (type(start) is int and type(length) is int and 0 <= start
                                and start + length <= len(data)):
            raise InputError(f"{shown}: its compressed bytes (buffer {escaped(repr(ext.get('buffer')))}, byteOffset "
                             f"{escaped(repr(start))}, byteLength {escaped(repr(length))}) are not within a buffer of "
                             "the file; fix the file.")
        try:
            rows = meshopt.decode_gltf_buffer(data[start:start + length], ext["count"], ext["byteStride"],
                                              ext["mode"], ext.get("filter", "NONE"))
        except ValueError as e:   # meshoptimizer's decoders check every read against the data's end
            raise InputError(f"{shown}: its {length} compressed bytes cannot be decoded ({cut(str(e))}); "
                             "fix the file.") from None
        view.update(buffer=added(np.ascontiguousarray(rows).tobytes()), byteOffset=0)


def _draco(tree: dict, buffer, added, origin: str) -> None:
    """Every primitive with KHR_draco_mesh_compression decoded by DracoPy and rewritten as a plain one, each
    attribute the extension names (and the indices) a new accessor over a buffer of its own (`added`), of the
    component type and type its own accessor declares, which the extension says the decoded data has (the declared
    accessor stays for its type and count). The declared POSITION counts are held to the memory
    budget before anything is decoded; a decoded attribute of another count or width than declared is refused."""
    draco = _draco_primitives(tree)
    if not draco:
        return
    import DracoPy

    declared = sum(_at(tree, "accessors", tree["meshes"][m]["primitives"][p]["attributes"]["POSITION"], origin)
                   ["count"] for m, p in draco)
    budget.check(declared * BYTES_PER_VERTEX, f"{origin}: its {len(draco)} Draco-compressed primitives of "
                 f"{declared} vertices (as their POSITION accessors declare), decoded,", "simplify the mesh")

    def plain(array: np.ndarray, declared: dict) -> int:
        """A new accessor of `declared`'s componentType, type and normalized over `array`, in a buffer of its own."""
        data = np.ascontiguousarray(array).tobytes()
        tree.setdefault("bufferViews", []).append({"buffer": added(data), "byteLength": len(data)})
        tree["accessors"].append({key: declared[key] for key in ("componentType", "type", "normalized", "count")
                                  if key in declared} | {"bufferView": len(tree["bufferViews"]) - 1})
        return len(tree["accessors"]) - 1

    for m, p in draco:
        prim, where = tree["meshes"][m]["primitives"][p], f"{origin}: mesh {m} primitive {p}"
        ext = prim["extensions"].pop(_DRACO)
        if prim.get("mode", 4) != 4:
            raise InputError(f"{where}: mode {escaped(repr(prim.get('mode')))} with {_DRACO}, which decodes "
                             "triangles; the extension allows triangles (mode 4) here; fix the file.")
        view = _at(tree, "bufferViews", ext.get("bufferView"), where)
        data = _strided(tree, ext["bufferView"], 0, view["byteLength"], np.dtype("u1"), 1, buffer, where).tobytes()
        try:
            mesh = DracoPy.decode(data)
        except Exception as e:   # DracoPy raises ValueError, FileTypeException, ... for what it cannot decode
            raise InputError(f"{where}: its {_DRACO} data ({len(data)} bytes) cannot be decoded ({type(e).__name__}: "
                             f"{cut(str(e))}); fix the file.") from None
        if not isinstance(mesh, DracoPy.DracoMesh):
            raise InputError(f"{where}: its {_DRACO} data decodes to points without triangles; fix the file.")
        by_id = {a["unique_id"]: a for a in mesh.attributes}
        for name, uid in ext["attributes"].items():
            shown = f"{where} {escaped(name)}"
            index = prim["attributes"].get(name)
            a = _at(tree, "accessors", index, shown)
            width, ct = WIDTHS.get(a.get("type")), a.get("componentType")
            got = by_id.get(uid)
            if got is None or width is None or ct not in DTYPES:
                raise InputError(f"{shown}: {_DRACO} names attribute {escaped(repr(uid))} of the decoded data "
                                 f"(which has {sorted(by_id)}) for accessor {index} ({escaped(repr(a.get('type')))} "
                                 f"of componentType {escaped(repr(ct))}); fix the file.")
            decoded = np.asarray(got["data"]).reshape(len(got["data"]), -1)
            typed = decoded.astype(DTYPES[ct])
            if decoded.shape != (a.get("count"), width) or not np.array_equal(typed, decoded, equal_nan=True):
                raise InputError(f"{shown}: decodes to {decoded.shape[0]} x {decoded.shape[1]} values of "
                                 f"{decoded.dtype}, where accessor {index} declares {escaped(repr(a.get('count')))} "
                                 f"x {width} of componentType {ct}; fix the file.")
            prim["attributes"][name] = plain(typed, a)
        faces = np.asarray(mesh.faces, np.uint32).ravel()
        given = _at(tree, "accessors", prim["indices"], f"{where} indices") if "indices" in prim else {}
        if given and given.get("count") != len(faces):
            raise InputError(f"{where}: decodes to {len(faces)} indices where its indices accessor declares "
                             f"{escaped(repr(given.get('count')))}; fix the file.")
        prim["indices"] = plain(faces, {"componentType": UNSIGNED_INT, "type": "SCALAR", "count": len(faces)})


def check_accessors(gltf: Opened, origin: str) -> None:
    """Every accessor a mesh primitive reads (its attributes and indices) checked against its bufferView and buffer
    and against the primitive's other attributes (glTF 2.0 §3.6.2, §3.7.2.1), before read_gltf reads a
    byte: a component type and type of a vertex attribute, a count shared by every attribute, a byteStride no
    smaller than the element (else elements overlap), offsets aligned to the component, and every element within
    the view and the view within the buffer. InputError names the file, the accessor and what is wrong."""
    tree, buffer, stored = gltf.tree, gltf.buffer, gltf.stored
    try:
        for k, a in enumerate(tree.get("accessors", [])):   # zeros or sparse: elements no byte of the file stores
            if "bufferView" not in a and type(a.get("count")) is int and a["count"] > stored:
                raise InputError(f"{origin}: accessor {k} has {a['count']} elements and no bufferView, more than the "
                                 f"{stored} bytes of the file and its buffers; an accessor without bytes holds at "
                                 "most one element per byte of the file (our bound: it would be zeros); fix the file.")
        for m, mesh in enumerate(tree.get("meshes", [])):
            for p, prim in enumerate(mesh["primitives"]):
                where = f"{origin}: mesh {m} primitive {p}"
                used = [*prim["attributes"].items()] + ([("indices", prim["indices"])] if "indices" in prim else [])
                counts = {name: _accessor(tree, index, buffer, f"{where} {name} (accessor {index})")
                          for name, index in used}
                attributes = {name: n for name, n in counts.items() if name != "indices"}
                if len(set(attributes.values())) > 1:
                    raise InputError(f"{where}: its attributes have different counts ({escaped(repr(attributes))})"
                                     "; glTF 2.0 gives every attribute of a primitive one entry per vertex; fix the "
                                     "file.")
    except (KeyError, IndexError, TypeError, AttributeError, ValueError) as e:
        raise InputError(f"{origin}: cannot read its meshes' accessors ({type(e).__name__}: "
                         f"{escaped(str(e))}); fix the file.") from None


def check_extensions(tree: dict, origin: str) -> None:
    """Refuse what the file requires and this reader does not do (glTF 2.0 §3.12: a loader that does not support an
    extension in extensionsRequired refuses the file)."""
    required = tree.get("extensionsRequired", [])
    if not isinstance(required, list) or not all(isinstance(e, str) for e in required):
        raise InputError(f"{origin}: extensionsRequired is {cut(repr(required))}; glTF 2.0 gives a list of "
                         "names; fix the file.")
    unread = [e for e in required if e not in REQUIRED_READ]
    if unread:
        raise InputError(f"{origin}: it requires the extension{'s' if len(unread) > 1 else ''} "
                         f"{cut(', '.join(unread), 300)} (extensionsRequired), which this reader does not apply; "
                         f"glTF 2.0 §3.12 says to refuse such a file. Read here: {', '.join(REQUIRED_READ)}; export "
                         "the file without it.")


def _accessor(tree: dict, index, buffer, shown: str) -> int:
    """The count of accessor `index`, after checking its layout in its bufferView and buffer (§3.6.2.4)."""
    if type(index) is not int or not 0 <= index < len(tree["accessors"]):
        raise InputError(f"{shown}: no such accessor (the file has {len(tree['accessors'])}); fix the file.")
    a = tree["accessors"][index]
    size, width, count = (d.itemsize if (d := DTYPES.get(a.get("componentType"))) else None), WIDTHS.get(a.get("type")), a.get("count")
    if size is None or width is None or type(count) is not int or count < 1:
        raise InputError(f"{shown}: componentType {escaped(repr(a.get('componentType')))}, type "
                         f"{escaped(repr(a.get('type')))}, count {escaped(repr(count))}; glTF 2.0 allows a "
                         f"componentType of {sorted(DTYPES)}, a type of {list(WIDTHS)} for a primitive "
                         "and a count of at least 1; fix the file.")
    if "bufferView" not in a:
        return count                                  # zeros (or sparse): no bytes to lay out
    views = tree["bufferViews"]
    if type(a["bufferView"]) is not int or not 0 <= a["bufferView"] < len(views):
        raise InputError(f"{shown}: bufferView {escaped(repr(a['bufferView']))} does not exist; fix the file.")
    view, item = views[a["bufferView"]], size * width
    offset, view_offset, length = a.get("byteOffset", 0), view.get("byteOffset", 0), view.get("byteLength")
    stride = view.get("byteStride", item)
    if not all(type(x) is int and x >= 0 for x in (offset, view_offset, length, stride)):
        raise InputError(f"{shown}: byteOffset {escaped(repr(offset))}, bufferView byteOffset "
                         f"{escaped(repr(view_offset))}, byteLength {escaped(repr(length))}, byteStride "
                         f"{escaped(repr(stride))}; glTF 2.0 gives non-negative integers; fix the file.")
    if stride < item:
        raise InputError(f"{shown}: bufferView {a['bufferView']}'s byteStride {stride} is smaller than one element "
                         f"({width} x {size} bytes = {item}), so its elements would overlap; fix the file.")
    if offset % size or (view_offset + offset) % size or stride % size:
        raise InputError(f"{shown}: byteOffset {offset} (bufferView's {view_offset}, byteStride {stride}) is not a "
                         f"multiple of its component's {size} bytes, as glTF 2.0 requires; fix the file.")
    end = offset + stride * (count - 1) + item
    if end > length:
        raise InputError(f"{shown}: {count} elements from byteOffset {offset} with stride {stride} end at byte {end}"
                         f", past bufferView {a['bufferView']}'s byteLength {length}; fix the file.")
    data = buffer(view["buffer"])
    if view_offset + length > len(data):
        raise InputError(f"{shown}: bufferView {a['bufferView']} ends at byte {view_offset + length}, past its "
                         f"buffer {view['buffer']} of {len(data)} bytes; fix the file.")
    return count


@dataclass
class Read:
    """A glTF's triangles as one mesh, before vertices are merged (meshes.load_mesh_file)."""
    vertices: np.ndarray               # (V, 3) in the scene's space
    faces: np.ndarray                  # (F, 3) counter-clockwise seen from the front
    normals: np.ndarray                # (V, 3) unit, the file's; NaN where its primitive has no NORMAL
    uvs: np.ndarray | None             # (V, 2), v up (the file's v flipped, as texture maps are stored)
    colors: np.ndarray | None          # (V, 3) linear baseColorFactor x COLOR_0; None where no primitive has either
    texture: np.ndarray | None         # the albedo map read at `uvs` (the file's picture, or the atlas of them)


def read_gltf(files: dict, gltf: Opened, textures: bool, origin: str, warn) -> Read:
    """The triangles of the glTF among `files` (references.reached_files; `gltf` as `opened` reads it) as the
    default scene places them, with their albedo (`textures`: materials read, else COLOR_0 only). Points and lines
    beside triangles are left out and named to `warn`; a file of only those is refused by name. Every other fault
    is an InputError naming `origin`."""
    tree, buffer = gltf.tree, gltf.buffer
    try:
        # A file's numbers may overflow float64 once multiplied (a scale of 1e308): every product is checked instead of
        # warned about (_local refuses a non-finite transform, meshes.validate a non-finite vertex), so a clean error
        # is the only thing printed.
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return _read(tree, files, buffer, textures, origin, warn)
    except (KeyError, IndexError, TypeError, AttributeError, ValueError, OverflowError, RecursionError) as e:
        raise InputError(f"{origin}: cannot read its meshes ({type(e).__name__}: {cut(str(e))}); fix the "
                         "file.") from None


def _at(tree: dict, key: str, index, origin: str):
    """tree[key][index], refused unless `index` is an int in range (a negative one would count from the end)."""
    items = tree.get(key, [])
    if type(index) is not int or not 0 <= index < len(items):
        raise InputError(f"{origin}: {key[:-1]} {escaped(repr(index))} does not exist (the file has {len(items)}); "
                         "fix the file.")
    return items[index]


def _read(tree, files, buffer, textures, origin, warn) -> Read:
    parts, skipped, geometry = [], {}, {}
    placed = _instances(tree, buffer, origin)
    vertices = sum(_position_count(tree, _at(tree, "meshes", m, origin)) for m, _, _ in placed)
    budget.check(vertices * BYTES_PER_VERTEX, f"{origin}: its node tree places {len(placed)} meshes of {vertices} "
                 "vertices in all, which", "place fewer copies in the file, or give the copies as the object's "
                 "instances in the scene (drawn instanced, not merged)")
    for mesh_index, matrix, weights in placed:
        mesh = _at(tree, "meshes", mesh_index, origin)
        weights = mesh.get("weights") if weights is None else weights   # a node's weights override (§3.7.2.2)
        for p, prim in enumerate(mesh["primitives"]):
            where, mode = f"mesh {mesh_index} primitive {p}", prim.get("mode", 4)
            if mode in (0, 1, 2, 3):
                skipped[where] = f"{where} draws {MODES[mode]} (mode {mode})"
                continue
            if mode not in MODES:
                raise InputError(f"{origin}: {where} has mode {escaped(repr(mode))}; glTF 2.0 gives 0 to 6; fix the "
                                 "file.")
            key = (mesh_index, p, repr(weights))
            if key not in geometry:
                geometry[key] = _geometry(tree, buffer, prim, weights, f"{origin}: {where}")
            pos, normal, uv, faces = geometry[key]
            m3 = matrix[:3, :3]
            det = np.linalg.det(m3)
            if normal is not None:   # normals by the inverse transpose (§3.7.2.1 attributes are in the node's space)
                normal = normal @ np.linalg.inv(m3) if abs(det) > 1e-300 else np.full_like(normal, np.nan)
                with np.errstate(invalid="ignore", divide="ignore"):
                    normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
            parts.append(dict(where=where, prim=prim, pos=pos @ m3.T + matrix[:3, 3], normal=normal, uv=uv,
                              faces=faces if det >= 0 else faces[:, ::-1]))   # a mirroring node flips the winding
    if skipped and not parts:
        raise InputError(f"{origin}: {'; '.join(skipped.values())}; only triangles are rendered (modes 4, 5 and 6) "
                         "and the file has none; export its surfaces as triangles.")
    if skipped:
        warn(f"{origin}: left out {'; '.join(skipped.values())}: only triangles are rendered (modes 4, 5 and 6)")
    if not parts:
        return Read(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3)), None, None, None)
    for part in parts:
        part.update(_material(tree, part, buffer, textures, origin))
    offsets = np.cumsum([0] + [len(q["pos"]) for q in parts[:-1]])
    colours = [q["albedo"] for q in parts]
    uvs, albedo_map = _texture(tree, files, buffer, parts, origin) if textures else (None, None)
    if uvs is None and all(q["uv"] is not None for q in parts):
        uvs = np.concatenate([q["uv"] for q in parts])
    return Read(np.concatenate([q["pos"] for q in parts]),
                np.concatenate([q["faces"] + o for q, o in zip(parts, offsets)]),
                np.concatenate([np.full((len(q["pos"]), 3), np.nan) if q["normal"] is None else q["normal"]
                                for q in parts]),
                uvs,
                None if all(c is None for c in colours) else
                np.concatenate([np.ones((len(q["pos"]), 3)) if c is None else c for q, c in zip(parts, colours)]),
                albedo_map)


def _instances(tree: dict, buffer, origin: str) -> list:
    """(mesh, 4x4 transform, node weights or None) for every mesh the default scene places: each node's transform
    the product of its ancestors' (§3.5.2), once per copy of EXT_mesh_gpu_instancing where the node has it; without
    scenes, the nodes no node names as a child are the roots; without nodes, every mesh in place. Each node is
    visited once: a node reached twice (its own ancestor, or a child of two parents) is refused, as node
    hierarchies are disjoint trees (§3.5.1), so the work is linear in the file (23 nodes each naming the next twice
    would place 2^22 copies)."""
    nodes = tree.get("nodes", [])
    if tree.get("scenes"):
        roots = _at(tree, "scenes", tree.get("scene", 0), origin).get("nodes", [])
    elif nodes:
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    else:
        return [(m, np.eye(4), None) for m in range(len(tree.get("meshes", [])))]
    out, stack, seen = [], [(r, np.eye(4)) for r in reversed(roots)], set()
    while stack:
        i, parent = stack.pop()
        node = _at(tree, "nodes", i, origin)
        if i in seen:
            raise InputError(f"{origin}: node {i} is reached twice (its own ancestor, or a child of two parents); "
                             "glTF 2.0 node hierarchies are disjoint trees (§3.5.1); fix the file.")
        seen.add(i)
        matrix = parent @ _local(node, f"{origin}: node {i}")
        if "mesh" in node:
            out += [(node["mesh"], matrix @ copy, node.get("weights"))
                    for copy in _gpu_instances(tree, node, buffer, f"{origin}: node {i}", MAX_COPIES - len(out))]
        stack += [(c, matrix) for c in reversed(node.get("children", []))]
    return out


def _gpu_instances(tree: dict, node: dict, buffer, shown: str, room: int) -> np.ndarray:
    """(N, 4, 4) the copies a node's EXT_mesh_gpu_instancing places in the node's space (each T x R x S from its
    TRANSLATION, ROTATION and SCALE accessors, a missing one the identity), or the identity alone without it; at most
    `room` copies."""
    ext = (node.get("extensions") or {}).get("EXT_mesh_gpu_instancing")
    attrs = {} if ext is None else ext["attributes"]
    if ext is not None and (not attrs or set(attrs) - {"TRANSLATION", "ROTATION", "SCALE"}):
        raise InputError(f"{shown}: EXT_mesh_gpu_instancing attributes {cut(repr(sorted(attrs)))}; "
                         "applied here: TRANSLATION, ROTATION and SCALE, at least one; fix the file.")
    count = max(_at(tree, "accessors", index, shown).get("count", 0) for index in attrs.values()) if attrs else 1
    if type(count) is not int or count > room:   # checked before a matrix is made
        raise InputError(f"{shown} places {escaped(repr(count))} copies of its mesh where {max(room, 0)} more fit the "
                         f"{MAX_COPIES} a file may place (each merged into the one mesh baked); give the copies as the "
                         "object's instances in the scene instead, or place fewer.")
    if ext is None:
        return np.eye(4)[None]
    read = {name: values(tree, index, buffer, f"{shown} EXT_mesh_gpu_instancing {name}",
                         ("VEC4",) if name == "ROTATION" else ("VEC3",),
                         (FLOAT, BYTE, SHORT) if name == "ROTATION" else (FLOAT,)) for name, index in attrs.items()}
    counts = {len(v) for v in read.values()}
    if len(counts) > 1:
        raise InputError(f"{shown}: its EXT_mesh_gpu_instancing attributes have different counts "
                         f"({escaped(repr({k: len(v) for k, v in read.items()}))}); fix the file.")
    n = counts.pop()
    return _trs(read.get("TRANSLATION", np.zeros((n, 3))), read.get("ROTATION", np.tile([0.0, 0, 0, 1], (n, 1))),
                read.get("SCALE", np.ones((n, 3))))


def _position_count(tree: dict, mesh: dict) -> int:
    """The vertices of a mesh's primitives (their POSITION accessors' counts, checked by check_accessors)."""
    return sum(tree["accessors"][p["attributes"]["POSITION"]]["count"] for p in mesh["primitives"])


def _local(node: dict, shown: str) -> np.ndarray:
    """A node's 4x4 local transform: its column-major `matrix`, or T x R x S."""
    if "matrix" in node:
        m = np.array(node["matrix"], np.float64).reshape(4, 4).T
    else:
        m = _trs(*(np.array(node.get(key, default), np.float64).reshape(1, n) for key, default, n in
                   (("translation", [0, 0, 0], 3), ("rotation", [0, 0, 0, 1], 4), ("scale", [1, 1, 1], 3))))[0]
    if not np.isfinite(m).all():
        raise InputError(f"{shown}: its transform has a non-finite number; fix the file.")
    return m


def _trs(t: np.ndarray, q: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(N, 4, 4) T x R x S from (N, 3) translations, (N, 4) rotations (unit quaternions x, y, z, w) and (N, 3)
    scales (§3.5.2, and EXT_mesh_gpu_instancing's copies)."""
    x, y, z, w = q.T
    m = np.tile(np.eye(4), (len(t), 1, 1))
    m[:, :3, :3] = np.stack([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                             [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                             [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]).transpose(2, 0, 1) \
        * scale[:, None, :]
    m[:, :3, 3] = t
    return m


def _geometry(tree, buffer, prim, weights, where):
    """A primitive's positions, normals (or None), UVs (or None, v flipped) and triangles, morphed at `weights`."""
    attrs = prim["attributes"]
    pos = values(tree, attrs["POSITION"], buffer, f"{where} POSITION", ("VEC3",))
    count = len(pos)
    normal = values(tree, attrs["NORMAL"], buffer, f"{where} NORMAL", ("VEC3",)) if "NORMAL" in attrs else None
    uv = values(tree, attrs["TEXCOORD_0"], buffer, f"{where} TEXCOORD_0", ("VEC2",)) if "TEXCOORD_0" in attrs else None
    for name, got in (("NORMAL", normal), ("TEXCOORD_0", uv)):
        if got is not None and len(got) != count:
            raise InputError(f"{where}: {name} has {len(got)} entries, POSITION {count}; glTF 2.0 gives every "
                             "attribute one entry per vertex; fix the file.")
    targets = prim.get("targets", [])
    weights = [0.0] * len(targets) if weights is None else weights
    if len(weights) != len(targets) or not all(type(w) in (int, float) and np.isfinite(w) for w in weights):
        raise InputError(f"{where}: {len(targets)} morph targets and weights {cut(repr(weights), 100)}; glTF "
                         "2.0 gives one finite weight per target (§3.7.2.2); fix the file.")
    for t, (target, w) in enumerate(zip(targets, weights)):
        for name, index in target.items():   # morphed = base + sum of weight x target delta (§3.7.2.2)
            if w == 0 or name == "TANGENT":
                continue
            if name not in ("POSITION", "NORMAL") or (name == "NORMAL" and normal is None):
                raise InputError(f"{where}: morph target {t} moves {escaped(name)} at weight {w:g}; only POSITION "
                                 "and NORMAL targets are applied here; bake the morph into the mesh, or set that "
                                 "weight to 0.")
            delta = values(tree, index, buffer, f"{where} morph target {t} {name}", ("VEC3",))
            if len(delta) != count:
                raise InputError(f"{where}: morph target {t} {name} has {len(delta)} entries, POSITION {count}; fix "
                                 "the file.")
            if name == "POSITION":
                pos = pos + w * delta
            else:
                normal = normal + w * delta
    if "indices" in prim:
        idx = values(tree, prim["indices"], buffer, f"{where} indices", ("SCALAR",), INDEX_TYPES, raw=True)
        idx = idx[:, 0].astype(np.int64)
        if len(idx) and idx.max() >= count:
            raise InputError(f"{where}: index {int(idx.max())} reaches past its {count} vertices; fix the file.")
    else:
        idx = np.arange(count)
    n = len(idx) - 2
    mode = prim.get("mode", 4)
    if mode == 4:
        faces = idx[:len(idx) // 3 * 3].reshape(-1, 3)
    elif n <= 0:
        faces = np.zeros((0, 3), np.int64)
    elif mode == 5:   # strip: triangle i is (i, i+1, i+2), its second and third swapped when i is odd (§3.7.2.1)
        i = np.arange(n)
        faces = np.column_stack([idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2]])
    else:             # fan: triangle i is (i+1, i+2, 0)
        i = np.arange(n)
        faces = np.column_stack([idx[i + 1], idx[i + 2], np.full(n, idx[0])])
    if mode != 4:     # a strip's or fan's repeated index makes a triangle of no area, as a restart: dropped
        faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])]
    if uv is not None:
        uv = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])   # glTF's v runs down the picture; maps have row 0 at v = 0
    return pos, normal, uv, faces


def values(tree: dict, index, buffer, shown: str, types, components=tuple(DTYPES), raw: bool = False) -> np.ndarray:
    """(count, width) elements of accessor `index`: from its bufferView (or zeros without one), its sparse part
    written over them (§3.6.2.3), as float64 with normalized integers mapped to [0, 1] or [-1, 1] (§3.11), or as
    stored (`raw`). `types` and `components` are what the attribute allows."""
    if type(index) is not int or not 0 <= index < len(tree.get("accessors", [])):
        raise InputError(f"{shown}: no such accessor ({escaped(repr(index))}); fix the file.")
    a = tree["accessors"][index]
    shown = f"{shown} (accessor {index})"
    ct, kind, count = a.get("componentType"), a.get("type"), a.get("count")
    if ct not in components or kind not in types or type(count) is not int or not 1 <= count <= MAX_ELEMENTS:
        raise InputError(f"{shown}: {escaped(repr(kind))} of componentType {escaped(repr(ct))}, count "
                         f"{escaped(repr(count))}; allowed here: {' or '.join(types)} of componentType "
                         f"{sorted(components)}, a count from 1 to {MAX_ELEMENTS}; fix the file.")
    dtype, width = DTYPES[ct], WIDTHS[kind]
    out = (_strided(tree, a["bufferView"], a.get("byteOffset", 0), count, dtype, width, buffer, shown).copy()
           if "bufferView" in a else np.zeros((count, width), dtype))
    sparse = a.get("sparse")
    if sparse is not None:
        n, ix = sparse["count"], sparse["indices"]
        if type(n) is not int or not 1 <= n <= count or ix.get("componentType") not in INDEX_TYPES:
            raise InputError(f"{shown}: sparse count {escaped(repr(n))} with indices of componentType "
                             f"{escaped(repr(ix.get('componentType')))}; glTF 2.0 gives 1 to the accessor's count "
                             "(5121, 5123 or 5125); fix the file.")
        at = _strided(tree, ix["bufferView"], ix.get("byteOffset", 0), n, DTYPES[ix["componentType"]], 1,
                      buffer, f"{shown} sparse indices")[:, 0].astype(np.int64)
        if (np.diff(at) <= 0).any() or at[-1] >= count:
            raise InputError(f"{shown}: its sparse indices are not strictly increasing below its count {count}, as "
                             "glTF 2.0 requires (§3.6.2.3); fix the file.")
        out[at] = _strided(tree, sparse["values"]["bufferView"], sparse["values"].get("byteOffset", 0), n, dtype,
                           width, buffer, f"{shown} sparse values")
    if raw:
        return out
    result = out.astype(np.float64)
    if a.get("normalized") is True and dtype.kind in "iu":
        result = np.maximum(result / np.iinfo(dtype).max, -1.0)
    if not np.isfinite(result).all():
        raise InputError(f"{shown}: NaN or Inf among its values; fix the file.")
    return result


def _strided(tree, view_index, offset, count, dtype, width, buffer, shown) -> np.ndarray:
    """(count, width) elements of `dtype` from bufferView `view_index` at byte `offset`, its byteStride apart,
    each within the view and the view within its buffer (§3.6.2.4)."""
    view = _at(tree, "bufferViews", view_index, shown)
    item = dtype.itemsize * width
    start, length, stride = view.get("byteOffset", 0), view.get("byteLength"), view.get("byteStride", item)
    if not all(type(x) is int and x >= 0 for x in (offset, start, length, stride)) or stride < item:
        raise InputError(f"{shown}: bufferView {view_index} or its accessor's byteOffset, byteLength or byteStride "
                         "is not a non-negative integer (a stride at least one element); fix the file.")
    data = buffer(view["buffer"])
    if offset + stride * (count - 1) + item > length or start + length > len(data):
        raise InputError(f"{shown}: {count} elements from byte {offset} of bufferView {view_index} reach past it or "
                         "its buffer; fix the file.")
    return np.ndarray((count, width), dtype, data, start + offset, (stride, dtype.itemsize))


def _material(tree, part, buffer, textures, origin) -> dict:
    """A part's `albedo` ((V, 3) baseColorFactor x COLOR_0, or None), `picture` (the base-colour texture as
    (image, wrapS, wrapT), or None) and `shown` (its primitive and material, for messages)."""
    prim, where = part["prim"], part["where"]
    index = prim.get("material")
    shown = f"{origin}: {where}" + ("" if index is None else f" (material {index})")
    pbr = _at(tree, "materials", index, shown).get("pbrMetallicRoughness", {}) if textures and index is not None \
        else {}
    factor = pbr.get("baseColorFactor")
    if factor is not None and not (isinstance(factor, list) and len(factor) == 4 and all(
            type(x) in (int, float) and 0 <= x <= 1 for x in factor)):
        raise InputError(f"{origin}: material {index}'s baseColorFactor is {escaped(repr(factor))}; "
                         "glTF 2.0 gives four numbers from 0 to 1; fix the file.")
    attrs = prim["attributes"]
    colour = colour_0(tree, attrs["COLOR_0"], buffer, origin) if "COLOR_0" in attrs else None
    if colour is not None and len(colour) != len(part["pos"]):
        raise InputError(f"{shown}: COLOR_0 has {len(colour)} entries, POSITION {len(part['pos'])}; fix the file.")
    albedo = None
    if factor is not None or colour is not None:   # the factor applied once, here, to COLOR_0 (§3.9.2)
        albedo = (np.ones((len(part["pos"]), 3)) if colour is None else colour) * (
            1.0 if factor is None else np.asarray(factor[:3], np.float64))
    info = pbr.get("baseColorTexture")
    if info is None:
        return {"albedo": albedo, "picture": None, "shown": shown}
    said = f"{shown}: its base-colour texture"
    transform = (info.get("extensions") or {}).get("KHR_texture_transform")
    # KHR_texture_transform: the extension's texCoord, where given, overrides the textureInfo's
    at = info.get("texCoord", 0) if transform is None or "texCoord" not in transform else transform["texCoord"]
    if type(at) is not int or at < 0:
        raise InputError(f"{said}: texCoord {escaped(repr(at))}; glTF 2.0 gives a non-negative integer; fix the file.")
    uv = part["uv"] if at == 0 else _texcoord(tree, prim, at, buffer, shown, len(part["pos"]))
    if uv is None:
        raise InputError(f"{said} is read at TEXCOORD_{at}, which the primitive does not have; fix the file, or set "
                         'textures = "ignore" on the object.')
    if transform is not None:
        uv = _transformed(uv, transform, said)
    tex = _at(tree, "textures", info.get("index"), said)
    if "source" not in tex:
        raise InputError(f"{said} names its picture only through an extension ({cut(repr(list(tex)), 80)}), "
                         "which is not read; export a PNG or JPEG source, or set textures = \"ignore\".")
    sampler = _at(tree, "samplers", tex["sampler"], said) if "sampler" in tex else {}
    wrap = (sampler.get("wrapS", REPEAT), sampler.get("wrapT", REPEAT))
    if not all(w in WRAPS for w in wrap):
        raise InputError(f"{said}: sampler wrap modes {escaped(repr(wrap))}; glTF 2.0 gives {list(WRAPS)}; fix the "
                         "file.")
    _at(tree, "images", tex["source"], said)
    return {"albedo": albedo, "picture": (tex["source"], *wrap), "shown": shown, "uv": uv}


def _texcoord(tree, prim, at: int, buffer, shown: str, count: int) -> np.ndarray:
    """TEXCOORD_`at` of a primitive (v flipped, as _geometry flips TEXCOORD_0), or None where it has none."""
    index = prim["attributes"].get(f"TEXCOORD_{at}")
    if index is None:
        return None
    uv = values(tree, index, buffer, f"{shown} TEXCOORD_{at}", ("VEC2",))
    if len(uv) != count:
        raise InputError(f"{shown}: TEXCOORD_{at} has {len(uv)} entries, POSITION {count}; glTF 2.0 gives every "
                         "attribute one entry per vertex; fix the file.")
    return np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])


def _transformed(uv: np.ndarray, transform, said: str) -> np.ndarray:
    """UVs (v flipped) through a KHR_texture_transform: in the file's UV space, scale, then rotate (u' = cos u +
    sin v, v' = -sin u + cos v: the extension's rotation matrix, as its example's 'lower left quadrant, rotated
    clockwise 90 deg' reads), then offset. Affine, so the per-vertex UVs transformed read as a transform per
    fragment would: applied once here, the frames, the reference and the exported file read the same UVs."""
    def numbers(key, default, n):
        got = transform.get(key, default)
        got = [got] if n == 1 and type(got) in (int, float) else got
        if not (isinstance(got, list) and len(got) == n and all(type(x) in (int, float) and np.isfinite(x)
                                                               for x in got)):
            raise InputError(f"{said}: KHR_texture_transform {key} is {cut(repr(transform.get(key)), 100)}; "
                             f"the extension gives {'a number' if n == 1 else f'{n} numbers'}; fix the file.")
        return np.asarray(got, np.float64)

    if not isinstance(transform, dict):
        raise InputError(f"{said}: KHR_texture_transform is {cut(repr(transform), 100)}, not an object; fix "
                         "the file.")
    offset, (rotation,), scale = numbers("offset", [0, 0], 2), numbers("rotation", 0, 1), numbers("scale", [1, 1], 2)
    s, t = uv[:, 0] * scale[0], (1.0 - uv[:, 1]) * scale[1]
    c, r = np.cos(rotation), np.sin(rotation)
    return np.column_stack([c * s + r * t + offset[0], 1.0 - (-r * s + c * t + offset[1])])


def _picture(tree, files, buffer, source: int, origin: str) -> np.ndarray:
    """Image `source` as an albedo map (texture.from_image): a file the glTF names, a data: URI or a bufferView."""
    from PIL import Image

    image, shown = tree["images"][source], f"{origin}: image {source}"
    if ("uri" in image) == ("bufferView" in image):   # a reader would have to guess which picture is meant
        raise InputError(f"{shown} has {'both a uri and' if 'uri' in image else 'neither a uri nor'} a bufferView; "
                         "glTF 2.0 gives exactly one (§5.17, image.bufferView); fix the file.")
    if "uri" in image:
        uri = image["uri"]
        if uri.startswith("data:"):
            try:
                data = base64.b64decode(uri.partition(",")[2], validate=True)
            except binascii.Error:
                raise InputError(f"{shown}: its data: URI is not base64; fix the file.") from None
        else:
            spec = next(chain for chain in files if len(chain) == 1)
            data = files[spec + (uri,)].data
    else:
        view = _at(tree, "bufferViews", image.get("bufferView"), shown)
        data = _strided(tree, image["bufferView"], 0, view["byteLength"], np.dtype("u1"), 1, buffer, shown).tobytes()
    check_picture(data, shown)
    with Image.open(io.BytesIO(data)) as im:
        return texture.from_image(im)


def _texture(tree, files, buffer, parts, origin):
    """(UVs, albedo map) of the parts: None, None where none has a base-colour texture; the file's picture and
    UVs where every part reads one picture the same way and the renderer's REPEAT read is its sampler's (REPEAT, or
    UVs that stay half a texel inside the picture); else an atlas of every (picture, wrapS, wrapT) laid out over
    the UVs that read it (_laid_out), a white tile for the unpictured parts, with UVs moved into the tiles."""
    keys = list(dict.fromkeys(q["picture"] for q in parts if q["picture"] is not None))
    if not keys:
        return None, None
    pictures = {k: _picture(tree, files, buffer, k[0], origin) for k in keys}
    if len(keys) == 1 and all(q["picture"] is not None for q in parts):
        picture, uvs = pictures[keys[0]], np.concatenate([q["uv"] for q in parts])
        inside = [(0.5 / size <= uvs[:, axis]).all() and (uvs[:, axis] <= 1 - 0.5 / size).all()
                  for axis, size in enumerate((picture.shape[1], picture.shape[0]))]
        if all(mode == REPEAT or near for mode, near in zip(keys[0][1:], inside)):
            return uvs, picture
    spans = {}   # per key, the UVs its parts read, and at least the whole picture (so a file of UVs in [0, 1]
    for q in parts:   # lays out as it always did: each picture with a one-texel gutter)
        if q["picture"] is not None:
            if not np.isfinite(q["uv"]).all():
                raise InputError(f"{q['shown']}: its base-colour UVs are not finite (after its KHR_texture_transform);"
                                 " fix the file.")
            lo, hi = spans.get(q["picture"], (np.zeros(2), np.ones(2)))
            spans[q["picture"]] = (np.minimum(lo, q["uv"].min(0)), np.maximum(hi, q["uv"].max(0)))
    tiles = [(k, *_laid_out(pictures[k], k, spans[k], next(q["shown"] for q in parts if q["picture"] == k)))
             for k in keys]
    if any(q["picture"] is None for q in parts):   # glTF's default base colour: white (§3.9.2)
        tiles.append((None, np.full((WHITE_TILE, WHITE_TILE, 3), 255, np.uint8), None))
    atlas, place = _atlas([(k, m) for k, m, _ in tiles], origin)
    h, w = atlas.shape[:2]
    start = {k: s for k, _, s in tiles}
    uvs = []
    for q in parts:
        x, y = place[q["picture"]]
        if q["picture"] is None:
            uvs.append(np.tile([(x + WHITE_TILE / 2) / w, (y + WHITE_TILE / 2) / h], (len(q["pos"]), 1)))
            continue
        picture, (c0, r0) = pictures[q["picture"]], start[q["picture"]]
        uvs.append(np.column_stack([(x + q["uv"][:, 0] * picture.shape[1] - c0) / w,
                                    (y + q["uv"][:, 1] * picture.shape[0] - r0) / h]))
    return np.concatenate(uvs), atlas


def _wrapped(index: np.ndarray, size: int, mode: int) -> np.ndarray:
    """Texel indices as a sampler of `mode` reads them past the edge (the GL 4.6 spec, §8.14.2, to which glTF 2.0
    §5.26 defers): REPEAT modulo the size, CLAMP_TO_EDGE clamped, MIRRORED_REPEAT (size - 1) - mirror((i mod
    2 size) - size), mirror(a) = a for a >= 0, else -(1 + a)."""
    if mode == REPEAT:
        return index % size
    if mode == 33071:
        return np.clip(index, 0, size - 1)
    a = index % (2 * size) - size
    return size - 1 - np.where(a >= 0, a, -(1 + a))


def _laid_out(picture: np.ndarray, key, span, shown: str):
    """(tile, (first column, first row)): the texels a bilinear read of `picture` with the key's wrapS and wrapT
    touches at UVs within `span` ((lo, hi), each (u, v)), laid out in order, each index wrapped as the sampler wraps
    it (_wrapped). Read without wrapping at tile x + u W - first column, the tile gives every such UV the file's
    sampler's texels and weights, whatever the mode, so pictures of different modes share an atlas, and UVs outside
    [0, 1] (tiled floors, transformed UVs) read as the file means. Sizes are checked before a texel is copied."""
    (lo, hi), (height, width) = span, picture.shape[:2]
    first = np.floor(lo * (width, height) - 0.5).astype(np.int64)     # the lowest texel a read touches, per axis
    end = np.floor(hi * (width, height) - 0.5).astype(np.int64) + 2   # past the highest (its right neighbour)
    n = end - first
    if n.max() > MAX_TEXTURE_SIDE or n[0] * n[1] > texture.MAX_PIXELS:
        raise InputError(f"{shown}: its base-colour UVs span u {lo[0]:.4g} to {hi[0]:.4g}, v {1 - hi[1]:.4g} to "
                         f"{1 - lo[1]:.4g} over a picture of {width} x {height} with wrap modes {key[1]}, {key[2]}; "
                         "read from an atlas (the file has several pictures, or a mode other than REPEAT), that span "
                         f"is laid out as {n[0]} x {n[1]} texels, over the {MAX_TEXTURE_SIDE} a side and "
                         f"{texture.MAX_PIXELS} texels accepted; keep the UVs nearer [0, 1], or set textures = "
                         '"ignore" on the object.')
    cols = _wrapped(np.arange(first[0], end[0]), width, key[1])
    rows = _wrapped(np.arange(first[1], end[1]), height, key[2])
    return picture[rows][:, cols], (int(first[0]), int(first[1]))


def _atlas(tiles, origin):
    """One albedo map holding every tile (key, map) on shelves, tallest first; the white tile (key None), where
    there is one, at (0, 0) and the sides multiples of WHITE_TILE. Returns the map and, per key, the tile's (x, y)
    in texels."""
    align = WHITE_TILE if any(key is None for key, _ in tiles) else 1
    widest = max(m.shape[1] for _, m in tiles)
    width = min(max(widest, int(np.ceil(np.sqrt(sum(m.shape[0] * m.shape[1] for _, m in tiles))))), MAX_TEXTURE_SIDE)
    width = -(-width // align) * align
    x = y = shelf = 0
    spots = []
    for key, m in sorted(tiles, key=lambda t: (t[0] is not None, -t[1].shape[0])):
        if x + m.shape[1] > width:
            x, y, shelf = 0, y + shelf, 0
        spots.append((key, m, x, y))
        x, shelf = x + m.shape[1], max(shelf, m.shape[0])
    height = -(-(y + shelf) // align) * align
    if width * height > texture.MAX_PIXELS or max(widest, height) > MAX_TEXTURE_SIDE:
        raise InputError(f"{origin}: its {len(tiles)} base-colour pictures make an atlas of {max(widest, width)} x "
                         f"{height} texels (each picture laid out over the UVs that read it, at least with a one-texel "
                         f"gutter), over the {texture.MAX_PIXELS} texels and {MAX_TEXTURE_SIDE} a side accepted; "
                         'scale them down, or set textures = "ignore".')
    atlas = np.zeros((height, width, 3), np.uint8)
    place = {}
    for key, m, x, y in spots:
        atlas[y:y + m.shape[0], x:x + m.shape[1]] = m
        place[key] = (x, y)
    return atlas, place


def colour_0(tree: dict, index: int, buffer, origin: str) -> np.ndarray:
    """(V, 3) linear RGB of COLOR_0 accessor `index`: float, or unsigned byte or short normalized to [0, 1]
    (glTF 2.0 §3.7.2.1; divided by 255 or 65535), sparse or not."""
    a = tree["accessors"][index] if type(index) is int and 0 <= index < len(tree.get("accessors", [])) else {}
    dtype, width = (DTYPES[c] if (c := a.get("componentType")) in COLOUR_TYPES else None), {"VEC3": 3, "VEC4": 4}.get(a.get("type"))
    shown = f"{origin}: COLOR_0 accessor {escaped(repr(index))}"
    if dtype is None or width is None or a.get("normalized", False) != (dtype.kind == "u"):
        raise InputError(f"{shown} is {escaped(repr(a.get('type')))} of componentType "
                         f"{escaped(repr(a.get('componentType')))}{' normalized' if a.get('normalized') else ''}; "
                         "glTF 2.0 allows VEC3 or VEC4 of float (5126), or of normalized unsigned byte (5121) or "
                         "short (5123); fix the file.")
    rgb = values(tree, index, buffer, f"{origin}: COLOR_0", ("VEC3", "VEC4"), COLOUR_TYPES)[:, :3]
    if not ((rgb >= 0) & (rgb <= 1)).all():
        raise InputError(f"{shown} has values outside [0, 1]; a colour is a multiplier from 0 to 1; fix the file.")
    return rgb
