"""The files a mesh file reaches: an OBJ its MTL (`mtllib`) and the MTL its texture (`map_Kd`), a glTF its
buffers and images by URI, a PLY its texture (`comment TextureFile`). They are inputs as much as the mesh
file: `reached_files` reads each once with the checks of the scene's own files (a regular file of bounded
size, so a FIFO is refused instead of waited on), for the input hash and for loading (meshes.load_mesh_file
hands trimesh only these bytes). A texture that cannot be used is an error naming it and the file that
named it, not a mesh silently baked without it.

Mesh files are untrusted input (asset libraries, CI jobs and farms bake files nobody here wrote), so every name
one gives goes through one rule, `confined`, whatever the format: it must resolve, symbolic links followed, inside
the allowed root (the scene's folder, as bake.py passes it) or the mesh file's own folder, as a browser's glTF
loader reads nothing outside the asset's origin. Each file so resolved is read once however it is spelt, and
together they hold at most MAX_FILE_BYTES."""
from __future__ import annotations

import base64
import binascii
import io
import json
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote

from ..common import texture
from ..errors import InputError, cut, escaped
from ..formats.safeio import read_regular

MAX_FILE_BYTES = 2 << 30   # the largest mesh file or file it names (an OBJ of 16 M faces is about 1 GB)
MAX_TEXTURE_SIDE = 16384   # an albedo map's longest side: GL 4.5's least GL_MAX_TEXTURE_SIZE, so every device reads
                           # it (a wider texture samples as black: vdmrender.gpu.gl.albedo_texture refuses it)


def references(kind: str, data: bytes, textures: bool, origin: str) -> list[tuple[str, str]]:
    """The files a file names, as trimesh asks for them: (the name as written, what it is). `kind` is the
    file's type: a mesh file's suffix (obj, gltf, glb, ply) or `mtl`. OBJ: its first `mtllib` (the one trimesh
    reads); MTL: every `map_Kd` (the one map trimesh reads); glTF: `buffers[].uri` and `images[].uri` that are not
    data: URIs (a GLB's own buffer is inside it); PLY: its `comment TextureFile`. Textures, and the MTL that
    only names textures, are listed only if `textures`; then a glTF material whose base colour names no image
    of the file is an InputError naming `origin`. A file too malformed to list is left to trimesh to refuse."""
    if kind == "obj" and textures:   # found as trimesh finds it: the first "mtllib" anywhere, to the line's end
        text = "\n{}\n".format(data.decode("utf-8", "replace").strip().replace("\r\n", "\n")).replace("\\\n", "")
        at = text.find("mtllib")
        return [(text[at + 6:text.find("\n", at)].strip(), "material library")] if at >= 0 else []
    if kind == "mtl" and textures:
        lines = [line.split(None, 1) for line in data.decode("utf-8", "replace").splitlines()]
        return [(words[1].strip(), "texture") for words in lines if len(words) == 2 and words[0].lower() == "map_kd"]
    if kind == "ply" and textures:
        header = data.partition(b"end_header")[0].decode("utf-8", "replace")
        names = [line[line.lower().index("texturefile") + 11:].strip() for line in header.splitlines()
                 if "texturefile" in line.lower()]
        return [(names[-1], "texture")] if names and names[-1] else []
    if kind in ("gltf", "glb"):
        try:
            return _gltf_references(_gltf_json(kind, data, origin), textures, origin)
        except (ValueError, RecursionError, AttributeError, TypeError, KeyError):
            return []
    return []


def glb_chunks(data: bytes, origin: str) -> tuple[bytes, bytes | None]:
    """A GLB's JSON chunk and its BIN chunk (None without one), after checking its header as glTF 2.0 §4.4 gives
    it: magic "glTF", version 2, the length the file has, then a JSON chunk and at most a BIN chunk, each within
    that length. InputError names `origin` and what is wrong."""
    head = [int.from_bytes(data[i:i + 4], "little") for i in (4, 8)] if len(data) >= 12 else []
    if data[:4] != b"glTF" or head[:1] != [2] or head[1] != len(data):
        raise InputError(f"{origin}: not a GLB file of glTF 2.0 (magic {escaped(repr(data[:4]))}, version "
                         f"{head[0] if head else None}, a length of {head[1] if head else None} bytes where the file "
                         f"has {len(data)}); glTF 2.0 §4.4 gives 'glTF', 2 and the file's length; fix the file.")
    chunks, at = [], 12
    while at < len(data):
        length = int.from_bytes(data[at:at + 4], "little")
        kind, end = data[at + 4:at + 8], at + 8 + length
        if end > len(data) or len(data) - at < 8:
            raise InputError(f"{origin}: GLB chunk {len(chunks)} of {length} bytes at byte {at} reaches past the "
                             f"file's {len(data)} bytes (glTF 2.0 §4.4); fix the file.")
        chunks.append((kind, data[at + 8:end]))
        at = end
    kinds = [k for k, _ in chunks]
    if kinds not in ([b"JSON"], [b"JSON", b"BIN\0"]):
        raise InputError(f"{origin}: GLB chunks {cut(repr(kinds))}; glTF 2.0 §4.4 gives a JSON chunk "
                         "first, then at most one BIN chunk; fix the file.")
    return chunks[0][1], chunks[1][1] if len(chunks) > 1 else None


def _gltf_json(kind: str, data: bytes, origin: str = "the glTF"):
    return json.loads(glb_chunks(data, origin)[0] if kind == "glb" else data)


def gltf_tree(files: dict) -> dict:
    """The JSON of the glTF or GLB mesh file among `files` (reached_files)."""
    mesh = next(f for chain, f in files.items() if len(chain) == 1)
    return _gltf_json(mesh.path.suffix[1:].lower(), mesh.data)


def gltf_buffer(files: dict, tree: dict, index: int, origin: str) -> bytes:
    """Buffer `index` of the glTF or GLB mesh file among `files`, whose JSON is `tree` (glTF 2.0 §3.6.1): a data:
    URI decoded, a file as `reached_files` read it, or, without a uri, a GLB's binary chunk (chapter 4)."""
    spec, mesh = next((chain, f) for chain, f in files.items() if len(chain) == 1)
    uri = tree["buffers"][index].get("uri")
    if uri is None:
        binary = glb_chunks(mesh.data, origin)[1] if mesh.path.suffix.lower() == ".glb" else None
        if binary is None:
            raise InputError(f"{origin}: buffer {index} has no uri and the file has no GLB binary chunk; glTF 2.0 "
                             "gives every buffer of a .gltf a uri.")
        return binary
    if not uri.startswith("data:"):
        return files[spec + (uri,)].data
    head, _, body = uri.partition(",")
    try:
        if head.endswith(";base64"):
            return base64.b64decode(body, validate=True)
    except binascii.Error:
        pass
    raise InputError(f"{origin}: buffer {index}'s data: URI is not base64 (glTF 2.0 §3.6.1: "
                     "data:application/octet-stream;base64,...); re-export the file.")


def names_texture(kind: str, files: dict) -> bool:
    """Whether the mesh file (of `kind`, its suffix) asks for a base-colour texture: a reached texture file (an
    MTL's map_Kd, a PLY's TextureFile, a glTF image file) or a glTF material's baseColorTexture (its image maybe
    embedded). Then a mesh that loads without one has lost it."""
    if any(f.what == "texture" for f in files.values()):
        return True
    if kind not in ("gltf", "glb"):
        return False
    mesh = next(f for chain, f in files.items() if len(chain) == 1)
    try:
        return any("baseColorTexture" in m.get("pbrMetallicRoughness", {}) for m in _gltf_json(kind, mesh.data)
                   .get("materials", []))
    except (ValueError, RecursionError, AttributeError, TypeError):
        return False


def _gltf_references(tree: dict, textures: bool, origin: str) -> list[tuple[str, str]]:
    named = [(b["uri"], "buffer") for b in tree.get("buffers", []) if "uri" in b]
    if textures:
        images = tree.get("images", [])
        named += [(images[i]["uri"], "texture") for i in sorted(_base_colour_images(tree, origin))
                  if "uri" in images[i]]
    for uri, what in named:
        if not isinstance(uri, str):
            raise InputError(f"{origin}: a {what} uri is {escaped(repr(uri))}; glTF 2.0 gives a uri as a string.")
    return [(uri, what) for uri, what in named if not uri.startswith("data:")]


def _base_colour_images(tree: dict, origin: str) -> set[int]:
    """The images a material's base colour reads (through its texture's source), the only pictures drawn: the
    others (occlusion, metallic-roughness, normal, emissive) are never opened. A base colour naming no image is an
    InputError naming `origin`."""
    listed, images, read = tree.get("textures", []), tree.get("images", []), set()
    for i, material in enumerate(tree.get("materials", [])):
        index = material.get("pbrMetallicRoughness", {}).get("baseColorTexture", {}).get("index")
        if index is None:
            continue
        texture = listed[index] if isinstance(index, int) and 0 <= index < len(listed) else {}
        source = texture.get("source", 0)   # none: an extension names the image
        if not texture or not (isinstance(source, int) and 0 <= source < len(images)):
            raise InputError(f"{origin}: material {i}'s base colour is texture {escaped(repr(index))}, which "
                             f"names no image of the file ({len(listed)} textures, {len(images)} images); fix "
                             'the file, or set textures = "ignore" on the object.')
        read.add(source)
    return read


def _missing_unread_pictures(path: Path, data: bytes, roots: tuple[Path, ...], origin: str) -> list[str]:
    """Warnings for the image files of the glTF at `path` (its bytes `data`) that no base colour reads and that are
    not there (or lie outside `roots`): only the base colour is drawn, so a file whose occlusion picture was left
    behind (as copies of the published BoomBox are) still bakes, and the warning says what is missing."""
    try:
        tree = _gltf_json(path.suffix[1:].lower(), data, origin)
        images, read = tree.get("images", []), _base_colour_images(tree, origin)
        unread = [(i, image["uri"]) for i, image in enumerate(images)
                  if i not in read and isinstance(image.get("uri"), str) and not image["uri"].startswith("data:")]
    except (ValueError, RecursionError, AttributeError, TypeError, KeyError, InputError):
        return []   # the reader refuses such a file with its reason
    missing = []
    for i, uri in unread:
        try:
            there = confined(unquote(uri), path.parent, roots, "").is_file()
        except InputError:
            there = False
        if not there:
            missing.append(f"{origin}: image {i} '{escaped(uri)}' is not found (or lies outside the folders a mesh "
                           "file may name); no material's base colour reads it, and only the base colour is drawn, "
                           "so the file is read without it")
    return missing


@dataclass(frozen=True)
class Reached:
    """A mesh file, or a file it reaches, as read: what it is, where, its bytes."""
    what: str          # "mesh file", "material library", "texture" or "buffer"
    path: Path
    data: bytes


def described(chain: tuple[str, ...], what: str) -> str:
    """`the texture named by quad.obj > m.mtl`: a reached file's part in an error message."""
    return f"{what} named by {escaped(' > '.join(chain[:-1]))}" if len(chain) > 1 else what


def confined(name: str, folder: Path, roots: tuple[Path, ...], shown: str) -> Path:
    """The file a mesh file names: `name` (as written; a glTF URI already percent-decoded, RFC 3986) relative to
    `folder`, the mesh file's, with every symbolic link resolved; refused unless it lies inside one of `roots`
    (resolved folders). `shown` says which reference it is, for the message. The one rule for every format."""
    try:
        target = (folder / name).resolve()
    except (OSError, ValueError, RuntimeError) as e:   # a NUL in the name, a loop of links
        raise InputError(f"{shown} names no file ({type(e).__name__}: {escaped(str(e))}).") from None
    if not any(target.is_relative_to(root) for root in roots):
        raise InputError(f"{shown} resolves to {escaped(str(target))}, outside "
                         f"{' and '.join(escaped(str(r)) for r in dict.fromkeys(roots))}; a mesh file may name only "
                         "files inside the scene's folder or its own (no absolute path, no '..' or link leading out); "
                         "copy the file there.")
    return target


def reached_files(path: Path, spec: str, textures: bool = True, root: Path | None = None, warn=None) \
        -> dict[tuple[str, ...], Reached]:
    """The mesh file at `path` (named `spec` in the scene) and every file it reaches (`references`), keyed by the
    chain of names that reaches it: (spec,), (spec, "m.mtl"), (spec, "m.mtl", "tex.png"). Names are relative to
    the mesh file's folder, as trimesh resolves them (a glTF URI percent-decoded), and `confined` to `root` (the
    scene's folder; None: the mesh file's folder) or the mesh file's folder. Each resolved file is read once
    through safeio (a regular file; all of them together at most MAX_FILE_BYTES, so one buffer named in several
    spellings is one read). A missing file is an InputError naming it and the file that named it; a glTF image no
    base colour reads is not reached, and `warn` (if given) hears of one that is missing."""
    roots = tuple(dict.fromkeys(r.resolve() for r in (path.parent, root or path.parent)))
    found, read, todo = {}, {}, [((spec,), path, "mesh file")]
    while todo:
        chain, file, what = todo.pop(0)
        if chain in found:
            continue
        real, total = file.resolve(), sum(len(d) for d in read.values())
        if real not in read:
            shown = described(chain, what) + (f" (the files a mesh file reaches hold at most {MAX_FILE_BYTES} bytes "
                                              f"together, {total} read before it)" if total else "")
            try:   # a reference is opened as resolved, not through a link: one there now was swapped in since
                read[real] = read_regular(file, shown, limit=MAX_FILE_BYTES - total, follow=len(chain) == 1)
            except FileNotFoundError:
                raise InputError(f"{escaped(str(file))}: the {described(chain, what)} is not found (a name in a mesh "
                                 "file is relative to the mesh file's folder).") from None
        found[chain] = Reached(what, file, read[real])
        kind = path.suffix[1:].lower() if len(chain) == 1 else "mtl" if what == "material library" else ""
        for name, named in references(kind, read[real], textures, escaped(" > ".join(chain))):
            path_name = unquote(name) if kind in ("gltf", "glb") else name   # a URI's %XX decoded (RFC 3986 §2.1)
            shown = f"{escaped(' > '.join(chain))}: the {named} '{escaped(name)}'" + (
                f" ('{escaped(path_name)}' percent-decoded)" if path_name != name else "")
            todo.append((chain + (name,), confined(path_name, path.parent, roots, shown), named))
    if warn is not None and textures and path.suffix.lower() in (".gltf", ".glb"):
        for message in _missing_unread_pictures(path, found[(spec,)].data, roots, escaped(spec)):
            warn(message)
    return found


def check_picture(data: bytes, shown: str) -> None:
    """Refuse a texture no albedo map can come from: one PIL cannot read, one without pixels, or one of more
    than texture.MAX_PIXELS or a side over MAX_TEXTURE_SIDE (checked from its header, before a pixel is decoded).
    `shown` names it."""
    from PIL import Image

    limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None   # the bound below, with a message that helps
    try:
        with Image.open(io.BytesIO(data)) as im:
            width, height = im.size
            if not 0 < width * height <= texture.MAX_PIXELS or max(width, height) > MAX_TEXTURE_SIDE:
                raise InputError(f"{shown} is a picture of {width} x {height} pixels; accepted: at least 1 and at most "
                                 f"{texture.MAX_PIXELS} pixels, {MAX_TEXTURE_SIDE} a side; scale it down, or set "
                                 'textures = "ignore" on the object.')
            im.load()
    except InputError:
        raise
    except Exception as e:  # PIL raises OSError, SyntaxError, ValueError, ... for what it cannot read
        reason = ("no picture format Pillow reads" if isinstance(e, Image.UnidentifiedImageError)
                  else f"{type(e).__name__}: {escaped(str(e))}")
        raise InputError(f"{shown}: cannot read the picture ({reason}); allowed: a picture Pillow reads (PNG, JPEG, "
                         '...), or set textures = "ignore" on the object.') from None
    finally:
        Image.MAX_IMAGE_PIXELS = limit
