"""glTF 2.0 colours, read from the file's own JSON and accessors. trimesh rounds COLOR_0 and baseColorFactor to 8
bits (and misreads a 16-bit COLOR_0), and keeps COLOR_0 apart from the visual where the primitive has a material;
glTF 2.0 gives both as linear multipliers of the base-colour texture (§3.9.2, §3.7.2.1). So they are read here as
one linear colour per vertex, never re-encoded: the texture stays the file's sRGB picture, and the renderer and the
reference multiply the two (mesh.frag, texture.surface_albedo). Textures read otherwise than the renderer reads
every map are refused (check_texture_read)."""
from __future__ import annotations

import functools

import numpy as np

from ..errors import InputError, escaped
from .references import gltf_buffer, gltf_tree

ALBEDO = "vdm_albedo"   # the vertex attribute that carries a primitive's colour through trimesh's to_mesh
_REPEAT = 10497          # glTF 2.0 §5.26: the sampler's default wrapS/wrapT, as the renderer and the reference wrap
_COLOUR_TYPES = {5121: np.dtype("u1"), 5123: np.dtype("<u2"), 5126: np.dtype("<f4")}   # COLOR_0's (§3.7.2.1)
_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}                # §3.6.2.2
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}          # what a primitive's attributes and indices are


def check_accessors(files: dict, origin: str) -> None:
    """Every accessor a mesh primitive reads (its attributes and indices) checked against its bufferView and buffer
    and against the primitive's other attributes (glTF 2.0 §3.6.2, §3.7.2.1), before trimesh or colour_0 reads a
    byte: a component type and type of a vertex attribute, a count shared by every attribute, a byteStride no
    smaller than the element (else elements overlap), offsets aligned to the component, and every element within
    the view and the view within the buffer. InputError names the file, the accessor and what is wrong."""
    try:
        tree = gltf_tree(files)
    except (ValueError, RecursionError) as e:        # JSONDecodeError and UnicodeDecodeError are ValueErrors
        raise InputError(f"{origin}: not readable glTF JSON ({type(e).__name__}: {escaped(str(e))[:200]}); fix the "
                         "file.") from None
    buffer = functools.cache(lambda i: gltf_buffer(files, tree, i, origin))
    try:
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


def _accessor(tree: dict, index, buffer, shown: str) -> int:
    """The count of accessor `index`, after checking its layout in its bufferView and buffer (§3.6.2.4)."""
    if type(index) is not int or not 0 <= index < len(tree["accessors"]):
        raise InputError(f"{shown}: no such accessor (the file has {len(tree['accessors'])}); fix the file.")
    a = tree["accessors"][index]
    size, width, count = _COMPONENT_BYTES.get(a.get("componentType")), _WIDTHS.get(a.get("type")), a.get("count")
    if size is None or width is None or type(count) is not int or count < 1:
        raise InputError(f"{shown}: componentType {escaped(repr(a.get('componentType')))}, type "
                         f"{escaped(repr(a.get('type')))}, count {escaped(repr(count))}; glTF 2.0 allows a "
                         f"componentType of {sorted(_COMPONENT_BYTES)}, a type of {list(_WIDTHS)} for a primitive "
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


def gltf_albedo(scene, files: dict, textures: bool, origin: str) -> None:
    """Give each triangle geometry of a glTF's trimesh `scene` (before to_mesh places its instances) its linear
    albedo per vertex as the vertex attribute ALBEDO: its material's baseColorFactor times its COLOR_0 (`textures`:
    the material is read, else only COLOR_0). None where no primitive gives a colour (the scene's material applies);
    glTF's default 1 where another does. A base-colour texture read otherwise than the renderer reads it is refused."""
    import trimesh

    tree = gltf_tree(files)
    buffer = functools.cache(lambda i: gltf_buffer(files, tree, i, origin))
    try:
        # trimesh makes one geometry of each primitive it can draw (points, lines, triangles, strips), in file order
        prims = [p for m in tree.get("meshes", []) for p in m["primitives"] if p.get("mode", 4) in (0, 1, 4, 5)]
        pairs = [(g, p) for g, p in zip(scene.geometry.values(), prims) if isinstance(g, trimesh.Trimesh)]
        if len(prims) != len(scene.geometry) or any(
                len(g.vertices) != tree["accessors"][p["attributes"]["POSITION"]]["count"] for g, p in pairs):
            raise InputError(f"{origin}: trimesh loads its primitives otherwise than the file lists them, so their "
                             "colours cannot be matched to them; report the file.")
        colours = [primitive_albedo(tree, p, buffer, textures, origin) for g, p in pairs]
        if textures:
            for g, p in pairs:
                check_texture_read(tree, p, g.visual, origin)
    except (KeyError, IndexError, TypeError, AttributeError, ValueError) as e:
        raise InputError(f"{origin}: cannot read its colours or material ({type(e).__name__}: "
                         f"{escaped(str(e))}); fix the file.") from None
    if any(c is not None for c in colours):
        for (g, p), c in zip(pairs, colours):
            g.vertex_attributes[ALBEDO] = np.ones((len(g.vertices), 3)) if c is None else c


def primitive_albedo(tree: dict, prim: dict, buffer, textures: bool, origin: str) -> np.ndarray | None:
    """(V, 3) linear albedo of a glTF primitive's vertices: baseColorFactor's RGB (if `textures`) times COLOR_0's
    (alpha is coverage, not albedo); None where it has neither."""
    pbr = tree["materials"][prim["material"]].get("pbrMetallicRoughness", {}) if textures and "material" in prim else {}
    factor = pbr.get("baseColorFactor")
    if factor is not None and not (isinstance(factor, list) and len(factor) == 4 and all(
            type(x) in (int, float) and 0 <= x <= 1 for x in factor)):
        raise InputError(f"{origin}: material {prim['material']}'s baseColorFactor is {escaped(repr(factor))}; "
                         "glTF 2.0 gives four numbers from 0 to 1; fix the file.")
    colour = colour_0(tree, prim["attributes"]["COLOR_0"], buffer, origin) if "COLOR_0" in prim["attributes"] else None
    if factor is None and colour is None:
        return None
    rgb = np.ones((tree["accessors"][prim["attributes"]["POSITION"]]["count"], 3)) if colour is None else colour
    return rgb * (1.0 if factor is None else np.asarray(factor[:3], np.float64))


def colour_0(tree: dict, index: int, buffer, origin: str) -> np.ndarray:
    """(V, 3) linear RGB of COLOR_0 accessor `index`: float, or unsigned byte or short normalized to [0, 1]
    (glTF 2.0 §3.7.2.1; divided by 255 or 65535), laid out as §3.6.2 says (the view's and the accessor's
    byteOffset, the view's byteStride)."""
    a = tree["accessors"][index]
    dtype, width = _COLOUR_TYPES.get(a.get("componentType")), {"VEC3": 3, "VEC4": 4}.get(a.get("type"))
    shown = f"{origin}: COLOR_0 accessor {index}"
    if dtype is None or width is None or a.get("normalized", False) != (dtype.kind == "u"):
        raise InputError(f"{shown} is {escaped(repr(a.get('type')))} of componentType "
                         f"{escaped(repr(a.get('componentType')))}{' normalized' if a.get('normalized') else ''}; "
                         "glTF 2.0 allows VEC3 or VEC4 of float (5126), or of normalized unsigned byte (5121) or "
                         "short (5123); fix the file.")
    if "bufferView" not in a or "sparse" in a:
        raise InputError(f"{shown} is sparse or compressed (no bufferView); not read here: export it uncompressed.")
    view = tree["bufferViews"][a["bufferView"]]
    item = dtype.itemsize * width
    stride, start = view.get("byteStride", item), view.get("byteOffset", 0) + a.get("byteOffset", 0)
    data = buffer(view["buffer"])
    if start + stride * (a["count"] - 1) + item > min(len(data), view.get("byteOffset", 0) + view["byteLength"]):
        raise InputError(f"{shown} reaches past its bufferView or buffer; fix the file.")
    rgb = np.ndarray((a["count"], width), dtype, data, start, (stride, dtype.itemsize))[:, :3].astype(np.float64)
    rgb /= np.iinfo(dtype).max if dtype.kind == "u" else 1.0
    if not ((rgb >= 0) & (rgb <= 1)).all():    # NaN fails too
        raise InputError(f"{shown} has values outside [0, 1] (or NaN); a colour is a multiplier from 0 to 1; "
                         "fix the file.")
    return rgb


def check_texture_read(tree: dict, prim: dict, visual, origin: str) -> None:
    """Refuse a primitive's base-colour texture read otherwise than the renderer and the reference read every map:
    at TEXCOORD_0 (trimesh reads no other), untransformed (KHR_texture_transform other than the identity), and
    wrapping around (the default wrapS/wrapT, §5.26); another wrap mode only where a UV reaches within half a texel
    of an edge or past it, where the mode decides what bilinear filtering reads."""
    info = tree["materials"][prim["material"]].get("pbrMetallicRoughness", {}).get("baseColorTexture") \
        if "material" in prim else None
    if info is None:
        return
    shown = f"{origin}: material {prim['material']}'s base-colour texture"
    transform = info.get("extensions", {}).get("KHR_texture_transform")
    if info.get("texCoord", 0) != 0 or (transform or {}).get("texCoord", 0) != 0:
        raise InputError(f"{shown} is read at another TEXCOORD than TEXCOORD_0, which is the only one read; "
                         'export it with one UV set, or set textures = "ignore" on the object.')
    if transform is not None and (transform.get("offset", [0, 0]) != [0, 0] or transform.get("rotation", 0) != 0
                                  or transform.get("scale", [1, 1]) != [1, 1]):
        raise InputError(f"{shown} has a KHR_texture_transform ({escaped(repr(transform))}), which is not "
                         'applied here; bake it into the UVs, or set textures = "ignore" on the object.')
    sampler = tree["textures"][info["index"]].get("sampler")
    sampler = tree["samplers"][sampler] if sampler is not None else {}
    image, uv = getattr(visual.material, "baseColorTexture", None), getattr(visual, "uv", None)
    if image is None or uv is None:
        return   # nothing read
    for axis, key in enumerate(("wrapS", "wrapT")):
        mode, size = sampler.get(key, _REPEAT), image.size[axis]
        if mode != _REPEAT and not ((0.5 / size <= uv[:, axis]) & (uv[:, axis] <= 1 - 0.5 / size)).all():
            raise InputError(f"{shown} has {key} = {escaped(repr(mode))} and UVs that reach its edge, where "
                             f"only REPEAT ({_REPEAT}) is read as the file means; set {key} to {_REPEAT} (or "
                             'leave it out), or set textures = "ignore" on the object.')
