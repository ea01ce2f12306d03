"""Fuzzing the inputs a user hands the tools (hypothesis): scene files and bundle manifests; since issue 21
also the files a mesh file names (MTL, textures, glTF buffers and images, with `textures = "use"/"ignore"`),
a --baseline report.json, composite sets, and the contents and metadata of octahedral and pyramid parts;
since issue 32 part cache entries (as hostile files: a bake through them must always succeed, with the bundle
a bake without the cache makes), the cache's stats.log and glTF accessors.

Each example mutates a valid input (values replaced by arbitrary data: huge integers, NaN, Inf,
1e-200, strings with newlines, deep nesting; keys deleted or added; TOML text edited character-wise;
names pointed elsewhere; pictures truncated, bit-flipped or given other sizes in their headers; EXR
tables dropped, renamed, reordered, reshaped) and checks the contract: the tool accepts it or refuses
it with an InputError of one line (exit 2), never another exception, never a hang (time_limit); what
it accepts is usable and is what the input says: a scene round-trips through the manifest with every
number finite, a manifest's parts all read (or are refused), its cameras can be made, a texture bakes
to the albedo map a reader of the asset sees, a baseline compares, a part matches its metadata.
`make test` runs a few hundred examples (tests/test_fuzz.py); `make fuzz` runs VDM_FUZZ_EXAMPLES
(1000) of each, randomised. The assets the newer targets start from are in tests/fuzz_assets.py."""
from __future__ import annotations

import base64
import copy
import io
import json
import math
import os
import signal
import struct
import tomllib
import zlib
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, assume, event, settings
from hypothesis import strategies as st

import fuzz_assets as A
from vdmbake.errors import InputError
from vdmbake.schema import show

EXAMPLES = int(os.environ.get("VDM_FUZZ_EXAMPLES", "150"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize="VDM_FUZZ_EXAMPLES" not in os.environ,
                    suppress_health_check=list(HealthCheck), database=None)


def _deep(n: int):
    out = []
    for _ in range(n):
        out = [out]
    return out


SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(), st.sampled_from([0, -1, 1, 2**31, 2**63, 10**400, -10**400]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e-200, -1e-200, 5e-324, 1e308, -0.0, 0.5, 1.0, 1e9, 1e-9]),
    st.text(max_size=12), st.sampled_from(["", "a\nb", "sphere", "bricks", "mesh", "all", "../x", "x" * 300]))
VALUES = st.one_of(
    st.recursive(SCALARS, lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=8), c, max_size=4),
                 max_leaves=8),
    st.builds(_deep, st.sampled_from([50, 400])))


def _paths(node):
    """Every key path into `node`, depth first in document order (the empty path first). A stack, not recursion:
    a nested `yield from` costs each path one step per level, and _deep values are 400 levels deep."""
    stack = [((), node)]
    while stack:
        prefix, node = stack.pop()
        yield prefix
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        stack.extend(reversed([(prefix + (k,), v) for k, v in items]))


@st.composite
def mutated(draw, base, where=None, values=VALUES):
    """`base` with one to three edits: a value replaced, a key or item deleted, a key added (at the paths
    `where` accepts, if given; new values drawn from `values`)."""
    data = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(data) if p and (where is None or where(p))]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = data
        for k in path[:-1]:
            parent = parent[k]
        op = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
        if op == "replace":
            parent[path[-1]] = draw(values)
        elif op == "delete":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[draw(st.text(max_size=8))] = draw(values)
        else:
            parent.append(draw(values))
    return data


def one_line(e: InputError) -> None:
    msg = str(e)
    assert msg and "\n" not in msg, repr(msg)


def _floats(node):
    if isinstance(node, float):
        yield node
    elif isinstance(node, dict):
        for v in node.values():
            yield from _floats(v)
    elif isinstance(node, (list, tuple)):
        for v in node:
            yield from _floats(v)


def check_scene_data(data) -> None:
    """A scene as parsed data: refused in one line, or accepted, finite, and round-tripping."""
    from vdmbake.scene import parse_scene_dict

    try:
        scene = parse_scene_dict(data, "fuzz.toml")
    except InputError as e:
        one_line(e)
        return
    resolved = scene.to_dict()
    assert all(math.isfinite(x) for x in _floats(resolved)), resolved
    assert all(math.isfinite(x) for x in scene.light.direction) and abs(sum(x * x for x in scene.light.direction) - 1) < 1e-9
    assert parse_scene_dict(json.loads(json.dumps(resolved)), "manifest") == scene


def check_scene_text(path: Path, text: str) -> None:
    from vdmbake.scene import load_scene

    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    try:
        load_scene(path)
    except InputError as e:
        one_line(e)


def check_manifest(bundle: Path, manifest) -> None:
    """A bundle with this manifest: refused in one line, or every part reads (or is refused in one
    line), and every object's cameras and the memory guard work from what was accepted."""
    from vdmbake.bundle.directory import Bundle
    from vdmbake.bundle.parts import KINDS
    from vdmrender.common.camera import cameras_for
    from vdmrender.render import held_geometry

    (bundle / "manifest.json").write_text(json.dumps(manifest))
    try:
        b = Bundle(bundle)
    except InputError as e:
        one_line(e)
        return
    for rel, meta in b.manifest["parts"].items():
        try:
            b.read(rel, KINDS[meta["kind"]])
        except InputError as e:
            one_line(e)
    try:   # a mesostructure's base mesh is read for its displaced reference's size
        held_geometry(b)
    except InputError as e:
        one_line(e)
    for obj in b.scene.objects:
        entry = b.manifest["objects"][obj.name]
        for cam in cameras_for(b.scene.camera, entry["centre"], entry["radius"], 8, 8):
            eye, d = cam.pixel_rays()
            assert np.isfinite(d).all() and np.isfinite(eye).all() and 0 < cam.near < cam.far


# =========================================================================================================
# The targets of issue 21: textures and the files a mesh file names, baselines, composite sets, octahedral
# and pyramid parts. Same contract; each check below also says what "usable" means for what it accepts.
# =========================================================================================================


def examples(default: int) -> settings:
    """SETTINGS with `default` examples inside `make test` (derandomised); VDM_FUZZ_EXAMPLES wins (make fuzz)."""
    return SETTINGS if "VDM_FUZZ_EXAMPLES" in os.environ else settings(SETTINGS, max_examples=default)


class Quiet(tuple):
    """A fixture's value (a tuple) that a failing example shows by its name, not its contents."""

    def __new__(cls, name: str, values):
        self = super().__new__(cls, values)
        self.name = name
        return self

    def __repr__(self) -> str:
        return f"<{self.name}>"


class Hang(BaseException):
    """An example ran past its time limit (a BaseException: no `except Exception` in the code under test
    swallows it, and CliRunner lets it through)."""


@contextmanager
def time_limit(seconds: float, what: str):
    """Fail an example that runs longer than `seconds` (a hang, or work out of proportion to the input)."""
    def expired(signum, frame):
        raise Hang(f"{what} still running after {seconds} s")

    old = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def check_cli(result, out: Path) -> bool:
    """A vdmbake run under CliRunner: exit 0 (True; the bundle is there, nothing hidden left beside it) or exit 2
    through the one-paragraph error path, nothing written (False). Anything else fails."""
    from helpers import leftovers

    assert result.exit_code in (0, 2), (result.exit_code, result.output[-3000:], repr(result.exception))
    assert leftovers(out) == [], leftovers(out)
    if result.exit_code == 0:
        assert (out / "manifest.json").is_file(), result.output[-2000:]
        return True
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    err = result.stderr
    assert "Traceback" not in result.output and "Traceback" not in err, err[-3000:]
    lines = err.rstrip("\n").splitlines()
    assert lines and lines[-1].startswith("error: ") and err.count("error:") == 1, err[-3000:]
    assert not out.exists(), f"{out} written by a bake that failed"
    return False


def check_bundle_reads(out: Path):
    """A bundle vdmbake just wrote: it opens and every part reads, no InputError allowed (the bake reads each
    part back before it commits, so anything the renderer refuses here is a bake bug). Returns the Bundle."""
    from vdmbake.bundle.directory import Bundle
    from vdmbake.bundle.parts import KINDS

    b = Bundle(out)
    for rel, meta in b.manifest["parts"].items():
        b.read(rel, KINDS[meta["kind"]])
    return b


# ------------------------------------------------------------------------- 1. textures and references

IDX = st.sampled_from([0, 1, -1, 2, 2**31, 2**63, 10**30, 0.0, 0.5, True, None, "0", [0], {}]).map(copy.deepcopy)
TEXT_EDITS = st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 3), st.text(max_size=6)), min_size=1, max_size=3)


def _edit_text(text: str, edits) -> str:
    if isinstance(text, bytes):      # a file already replaced by bytes: left as it is
        return text
    for at, cut, insert in edits:
        at %= len(text) + 1
        text = text[:at] + insert + text[at + cut:]
    return text


def _lines(text: str, key: str, fn) -> str:
    """Every line of `text` whose first word is `key` replaced by fn(line) (None: deleted; a list: several)."""
    if isinstance(text, bytes):
        return text
    out = []
    for line in text.split("\n"):
        words = line.split(None, 1)
        new = fn(line) if words and words[0] == key else line
        out += [] if new is None else new if isinstance(new, list) else [new]
    return "\n".join(out)


NAME_TEXT = st.sampled_from(A.NAMES) | st.text(max_size=10)
MTL_NAMES = st.sampled_from(["m.mtl", "m2.mtl", "missing.mtl", "m.mtl m2.mtl", "m2.mtl m.mtl", "tex.png", "quad.obj",
                             "dir.png", "", "../m.mtl", "sub/../m.mtl", "M.MTL", " m.mtl", "m.mtl # note", "m.mtl\t",
                             "two words.png"]) | st.text(max_size=10)
MAP_OPTIONS = st.sampled_from(["-s 1 1 1", "-o 0.5 0.5 0", "-clamp on", "-bm 2", "-blendu off", "-mm 0 1",
                               "-imfchan r", "-texres 64", "-s", "-o nan", "-", "--"])


@st.composite
def png_edit(draw, data: bytes) -> bytes:
    """`data` (a picture, or any file) truncated, with bytes flipped, with other sizes (and bit depth) in its PNG
    header, replaced by a picture of another format or size, or emptied."""
    op = draw(st.sampled_from(["truncate", "flip", "header", "header", "replace", "empty"]))
    if not data and op in ("truncate", "flip"):
        return data
    if op == "truncate":
        return data[:draw(st.integers(0, len(data) - 1))]
    if op == "flip":
        b = bytearray(data)
        for _ in range(draw(st.integers(1, 3))):
            b[draw(st.integers(0, len(b) - 1))] ^= draw(st.integers(1, 255))
        return bytes(b)
    if op == "header":      # IHDR's width and height, with or without a CRC that matches them
        if data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR":
            return data
        side = (st.sampled_from([0, 1, 2, 3, 4, 5, 8193, 65536, 100000, 2**31 - 1, 2**32 - 1])
                | st.integers(0, 2**32 - 1))
        ihdr = bytearray(data[16:29])
        ihdr[0:8] = struct.pack(">II", draw(side), draw(side))
        if draw(st.booleans()):
            ihdr[8] = draw(st.sampled_from([1, 2, 4, 8, 16, 3, 0, 255]))          # bit depth
        crc = struct.pack(">I", zlib.crc32(b"IHDR" + bytes(ihdr))) if draw(st.booleans()) else data[29:33]
        return data[:16] + bytes(ihdr) + crc + data[33:]
    if op == "replace":
        return A.PICTURES[draw(st.sampled_from(sorted(A.PICTURES)))]
    return b""


@st.composite
def obj_case(draw):
    """(files, touched): the textured OBJ's files with one to three edits, and what the edits touched
    ('obj', 'mtl', 'png')."""
    files = {"quad.obj": A.OBJ, "m.mtl": A.MTL, "tex.png": A.PNG}
    touched = set()
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["mtllib", "mtllib", "usemtl", "no_uv", "obj_chars", "eol",
                                   "map_Kd", "map_Kd", "options", "two_maps", "other_maps", "Kd", "newmtl", "mtl_chars",
                                   "mtl_bytes", "png", "png", "png"]))
        obj, mtl = files["quad.obj"], files["m.mtl"]
        if op == "mtllib":
            how = draw(st.sampled_from(["name", "name", "keyword", "twice", "delete", "last"]))
            if how == "name":
                obj = _lines(obj, "mtllib", lambda line: f"mtllib {draw(MTL_NAMES)}")
            elif how == "keyword":
                obj = _lines(obj, "mtllib", lambda line: draw(st.sampled_from(["MTLLIB", "mtllib\t", "mtllib:", "mtl"]))
                             + " m.mtl")
            elif how == "twice":
                extra = f"mtllib {draw(MTL_NAMES)}"
                obj = _lines(obj, "mtllib", lambda line: [line, extra] if draw(st.booleans()) else [extra, line])
            elif how == "delete":
                obj = _lines(obj, "mtllib", lambda line: None)
            else:
                obj = _lines(obj, "mtllib", lambda line: None) + line_of(obj, "mtllib")
            touched.add("obj")
        elif op == "usemtl":
            obj = _lines(obj, "usemtl", lambda line: None if draw(st.booleans()) else f"usemtl {draw(NAME_TEXT)}")
            touched.add("obj")
        elif op == "no_uv":
            obj = _lines(obj, "vt", lambda line: None)
            touched.add("obj")
        elif op == "obj_chars":
            obj = _edit_text(obj, draw(TEXT_EDITS))
            touched.add("obj")
        elif op == "eol":
            which = draw(st.sampled_from(["quad.obj", "m.mtl"]))
            if isinstance(files[which], bytes):
                continue
            text = files[which].replace("\n", draw(st.sampled_from(["\r\n", "\r", "\n\n", " \n", "\t\n"])))
            files[which] = ("\ufeff" if draw(st.booleans()) else "") + text
            touched |= {"obj"} if which == "quad.obj" else {"mtl", "mtl-text"}
            continue
        elif op == "map_Kd":
            mtl = _lines(mtl, "map_Kd", lambda line: f"map_Kd {draw(NAME_TEXT)}")
            touched.add("mtl")
        elif op == "options":
            mtl = _lines(mtl, "map_Kd", lambda line: f"map_Kd {draw(MAP_OPTIONS)} " + line.split(None, 1)[1]
                         if len(line.split(None, 1)) == 2 else line)
            touched.add("mtl")
        elif op == "two_maps":
            extra = f"map_Kd {draw(NAME_TEXT)}"
            mtl = _lines(mtl, "map_Kd", lambda line: [line, extra] if draw(st.booleans()) else [extra, line])
            touched.add("mtl")
        elif op == "other_maps":
            key = draw(st.sampled_from(["map_Ka", "map_Ks", "map_Bump", "bump", "map_d", "norm", "disp", "map_kd",
                                        "MAP_KD"]))
            mtl = mtl if isinstance(mtl, bytes) else mtl + f"{key} {draw(NAME_TEXT)}\n"
            touched.add("mtl")
        elif op == "Kd":
            mtl = _lines(mtl, "Kd", lambda line: "Kd " + draw(st.sampled_from(
                ["nan nan nan", "1e400 0 0", "-1 2 3", "1", "", "0.5 0.5 0.5", "a b c"])))
            extra = draw(st.sampled_from(["", "d 0.5\n", "Tr 1\n", "Ns nan\n", "illum 99\n"]))
            mtl = mtl if isinstance(mtl, bytes) else mtl + extra
            touched.add("mtl")
        elif op == "newmtl":
            how = draw(st.sampled_from(["rename", "delete", "twice"]))
            mtl = _lines(mtl, "newmtl", lambda line: None if how == "delete" else [line, line] if how == "twice"
                         else f"newmtl {draw(NAME_TEXT)}")
            touched.add("mtl")
        elif op == "mtl_chars":
            mtl = _edit_text(mtl, draw(TEXT_EDITS))
            touched.add("mtl")
        elif op == "mtl_bytes":
            mtl = draw(st.sampled_from([b"", bytes(range(256)), A.PNG, b"map_Kd \xff\xfe.png\n",
                                        b"map_Kd tex.png\x00\n",
                                        "newmtl mat\nmap_Kd t\u00e9x.png\n".encode("latin-1")]))
            touched.add("mtl")
        else:
            files["tex.png"] = draw(png_edit(files["tex.png"]))
            touched.add("png")
        if op in ("newmtl", "mtl_chars", "mtl_bytes") or (op == "eol" and "mtl" in touched):
            touched.add("mtl-text")      # the MTL's structure itself edited: which map applies is not known here
        files["quad.obj"], files["m.mtl"] = obj, mtl
    return files, touched


def line_of(text: str, key: str) -> str:
    return "".join(f"\n{line}" for line in text.split("\n") if line.split(None, 1)[:1] == [key])


GLTF_TEXTURE_OPS = ("image_uri", "indices", "factor", "images")


@st.composite
def gltf_case(draw):
    """(files, touched): the glTF's files with one to three edits; touched: 'gltf' (geometry, buffers, the
    JSON itself), 'gltf-texture' (images, textures, materials), 'png'."""
    tree, data, png = copy.deepcopy(A.GLTF), A.BIN, A.PNG
    touched, text_edits = set(), None
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["image_uri", "image_uri", "indices", "factor", "image_view", "images",
                                   "buffer_uri", "byte_length", "view", "accessor", "accessor", "attributes",
                                   "primitive", "node", "tree", "tree", "bin", "json_text", "png", "png"]))
        touched |= ({"png"} if op == "png" else {"gltf-texture"} if op in GLTF_TEXTURE_OPS else {"gltf"}
                    | ({"gltf-texture"} if op == "image_view" else set()))
        try:   # an op on what an earlier op removed or retyped: skipped
            if op == "image_uri":
                tree["images"][0]["uri"] = draw(NAME_TEXT | st.sampled_from([
                    "data:image/png;base64," + base64.b64encode(A.PNG).decode(),
                    "data:image/png;base64," + base64.b64encode(A.PNG[:40]).decode(),
                    "data:image/png;base64,!!!", "data:,",
                    "data:image/png;base64," + base64.b64encode(b"\0" * 64).decode(),
                    "data:image/png;base64," + base64.b64encode(A.PICTURES["wide"]).decode()]) | IDX)
                touched.add("gltf-texture")
            elif op == "indices":
                where = draw(st.sampled_from(["texture", "source", "sampler", "texcoord"]))
                material = tree["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]
                if where == "texture":
                    material["index"] = draw(IDX)
                elif where == "source":
                    tree["textures"][0]["source"] = draw(IDX)
                elif where == "sampler":
                    tree["textures"][0]["sampler"] = draw(IDX)
                    tree["samplers"] = draw(st.sampled_from([[], [{}], [{"wrapS": 33071, "magFilter": 1}]]))
                else:
                    material["texCoord"] = draw(IDX)
                touched.add("gltf-texture")
            elif op == "factor":
                tree["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = draw(st.sampled_from([
                    [1, 1, 1, 1], [0.5, 0.25, 1, 1], [0, 0, 0, 0], [2, -1, 1e308, 1], [1, 1], "red", None,
                    [float("nan")] * 4]))
                touched.add("gltf-texture")
            elif op == "image_view":    # an image inside a buffer: the PNG appended to the .bin, or a bomb's header
                picture = draw(st.sampled_from([A.PNG, A.PNG[:40], A.PICTURES["gif"], A.PICTURES["wide"],
                                                b"\x89PNG\r\n\x1a\n" + b"\0" * 30]))
                pad = (-len(data)) % 4
                tree["bufferViews"].append({"buffer": 0, "byteOffset": len(data) + pad, "byteLength": len(picture)})
                data = data + b"\0" * pad + picture
                tree["buffers"][0]["byteLength"] = len(data)
                tree["images"][0] = {"bufferView": len(tree["bufferViews"]) - 1,
                                     "mimeType": draw(st.sampled_from(["image/png", "image/jpeg", "text/plain"]))}
                touched.update({"gltf-texture", "gltf"})
            elif op == "images":
                how = draw(st.sampled_from(["none", "empty", "two", "textures_empty", "no_material", "no_textures"]))
                if how == "none":
                    del tree["images"]
                elif how == "empty":
                    tree["images"] = []
                elif how == "two":
                    tree["images"].append({"uri": draw(NAME_TEXT)})
                    tree["textures"].append({"source": 1})
                elif how == "textures_empty":
                    tree["textures"] = []
                elif how == "no_material":
                    del tree["meshes"][0]["primitives"][0]["material"]
                else:
                    del tree["textures"]
                touched.add("gltf-texture")
            elif op == "buffer_uri":
                tree["buffers"][0]["uri"] = draw(NAME_TEXT | IDX | st.sampled_from([
                    "data:application/octet-stream;base64," + base64.b64encode(A.BIN).decode(),
                    "data:application/octet-stream;base64,AAAA", "quad%2Ebin", "short.bin"]))
                touched.add("gltf")
            elif op == "byte_length":
                tree["buffers"][0]["byteLength"] = draw(st.sampled_from([0, 1, len(data) - 1, len(data) + 1, 2**31,
                                                                         2**63, -1,
                                                                         10**30, 92.5]) | IDX)
                touched.add("gltf")
            elif op == "view":
                view = tree["bufferViews"][draw(st.integers(0, 2))]
                view[draw(st.sampled_from(["byteOffset", "byteLength", "byteStride", "buffer"]))] = draw(
                    st.sampled_from([0, 1, 3, 4, 12, 92, 93, 255, 256, 2**31, -4, 2**63]) | IDX)
                touched.add("gltf")
            elif op == "accessor":
                acc = tree["accessors"][draw(st.integers(0, 2))]
                key = draw(st.sampled_from(["count", "componentType", "type", "byteOffset", "bufferView", "normalized",
                                            "min", "max", "sparse"]))
                acc[key] = draw({
                    "count": st.sampled_from([0, 1, 3, 5, 7, 2**31, 2**63, -1]),
                    "componentType": st.sampled_from([5120, 5121, 5122, 5123, 5125, 5126, 5130, 0, -1]),
                    "type": st.sampled_from(["SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT4", "vec3", ""]),
                    "byteOffset": st.sampled_from([1, 2, 4, 44, 48, 2**31, -4]),
                    "bufferView": st.sampled_from([1, 2, 3, -1, 2**31]),
                    "normalized": st.booleans(),
                    "min": st.sampled_from([[0], [], [float("nan")] * 3]),
                    "max": st.sampled_from([[1e308] * 3, [-1, -1, -1]]),
                    "sparse": st.sampled_from([{"count": 1, "indices": {"bufferView": 2, "componentType": 5123},
                                                "values": {"bufferView": 0}}, {"count": 2**31}, {}]),
                }[key] | IDX)
                touched.add("gltf")
            elif op == "attributes":
                attrs = tree["meshes"][0]["primitives"][0]["attributes"]
                key = draw(st.sampled_from(["POSITION", "TEXCOORD_0", "TEXCOORD_1", "NORMAL", "COLOR_0"]))
                if key in attrs and draw(st.booleans()):
                    del attrs[key]
                else:
                    attrs[key] = draw(st.integers(0, 2) | IDX)
                touched.add("gltf")
            elif op == "primitive":   # what read_gltf reads beyond a triangle list: modes, morph targets, weights
                prim, mesh = tree["meshes"][0]["primitives"][0], tree["meshes"][0]
                key = draw(st.sampled_from(["mode", "targets", "weights", "second"]))
                if key == "mode":
                    prim["mode"] = draw(st.sampled_from([0, 1, 2, 3, 4, 5, 6, 7, -1, 2**63]) | IDX)
                elif key == "targets":
                    prim["targets"] = draw(st.sampled_from([[{"POSITION": 0}], [{"NORMAL": 0}], [{"COLOR_0": 1}],
                                                            [{"POSITION": 1}], [{}], [], {}]) | IDX)
                elif key == "weights":
                    mesh["weights"] = draw(st.sampled_from([[0.5], [float("nan")], [1e308], [], [1, 2], "x"]) | IDX)
                else:   # points or lines beside the triangles (left out, named)
                    mesh["primitives"].append({**copy.deepcopy(prim), "mode": draw(st.sampled_from([0, 1, 3]))})
                touched.add("gltf")
            elif op == "node":        # the node tree: transforms, children, cycles, node weights
                node = tree["nodes"][0]
                key = draw(st.sampled_from(["matrix", "rotation", "scale", "translation", "children", "weights"]))
                node[key] = draw({
                    "matrix": st.sampled_from([[0.0] * 16, [1e308] * 16, [float("nan")] * 16, [1] * 15,
                                               [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]]),
                    "rotation": st.sampled_from([[0, 0, 0, 0], [0, 0, 0, 1], [1, 1, 1, 1], [float("nan")] * 4, [1]]),
                    "scale": st.sampled_from([[0, 0, 0], [-1, 1, 1], [1e308] * 3, [1, 1]]),
                    "translation": st.sampled_from([[1e308, 0, 0], [float("inf")] * 3, [0, 0]]),
                    "children": st.sampled_from([[0], [1], [-1], [0, 0], "x"]),
                    "weights": st.sampled_from([[0.25], [float("nan")], []]),
                }[key] | IDX)
                touched.add("gltf")
            elif op == "tree":
                tree = draw(mutated(tree))
                touched.add("gltf")
            elif op == "bin":
                data = draw(png_edit(data)) if draw(st.booleans()) else data[:draw(st.integers(0, len(data)))]
                touched.add("gltf")
            elif op == "json_text":
                text_edits = draw(TEXT_EDITS)
                touched.add("gltf")
            else:
                png = draw(png_edit(png))
                touched.add("png")
        except (KeyError, IndexError, TypeError, AttributeError):
            pass
    try:
        text = json.dumps(tree, allow_nan=True)
    except (ValueError, RecursionError):   # a 5000-digit integer or deep nesting that json cannot write
        text = "{"
    if text_edits:
        text = _edit_text(text, text_edits)
    return {"quad.gltf": text, "quad.bin": data, "tex.png": png}, touched


TEXTURES_SETTING = st.sampled_from([None, '"use"', '"ignore"'] * 4 + ['"Ignore"', "1", '"none"', "[]"])


def check_textured_bake(folder: Path, mesh: str, files: dict, touched: set, textures) -> None:
    """Bake a textured asset's (damaged) files: exit 0 or 2 as check_cli says, and when it bakes, the bundle
    reads whole and its albedo map is the texture a reader of the asset sees:
    * textures = "ignore" with only textures, MTL and image references damaged: it bakes, without albedo map
      and without any texture among its inputs;
    * only the picture damaged: refused, or baked with the picture's texels as PIL decodes them;
    * the material still plainly names a texture for the faces (_names_a_used_texture): refused, or baked with an
      albedo map (a texture that cannot be used is an error, not a mesh silently baked without it);
    * whatever was damaged: what it baked agrees with trimesh reading the asset from disk itself (albedo map or
      none, the same texels): the files the bake lists for trimesh are the files trimesh asks for.
    A textures setting other than "use" or "ignore" is refused."""
    from helpers import bake

    A.write_files(folder, {**A.DECOYS, **files})
    scene = folder / "scene.toml"
    scene.write_text(A.textured_scene(mesh, None) if textures is None else
                     A.textured_scene(mesh, None).replace("techniques =", f"textures = {textures}\ntechniques ="))
    out = folder / "x.bundle"
    with time_limit(30, "vdmbake of a textured asset"):
        result = bake(scene, "-o", out)
    ok = check_cli(result, out)
    _event("baked" if ok else "refused: " + _reason(result.stderr))
    mode = {None: "use", '"use"': "use", '"ignore"': "ignore"}.get(textures)
    if mode is None:
        assert not ok, f"textures = {textures} accepted"
        return
    geometry = {"obj", "gltf"} & touched
    if mode == "ignore" and not geometry:
        assert ok, (touched, result.stderr[-2000:])
    if not ok:
        return
    b = check_bundle_reads(out)
    entry, inputs = b.manifest["objects"]["thing"], b.manifest["inputs"]
    albedo = b.read(entry["albedo_map"], _kind("albedo-map")) if "albedo_map" in entry else None
    _event(f"textures {mode}: {'an' if albedo is not None else 'no'} albedo map")
    if mode == "ignore":
        assert albedo is None, "textures = \"ignore\" baked an albedo map"
        assert set(inputs) <= {mesh, f"{mesh} > quad.bin"} or geometry, inputs
        return
    if touched == {"png"}:
        assert albedo is not None, "an asset whose picture reads baked without its albedo map"
        assert np.array_equal(albedo, _decoded(files["tex.png"])), "albedo map differs from the picture's texels"
    if _names_a_used_texture(mesh, files, touched):
        assert albedo is not None, ("the asset's material names a texture, and the bake made no albedo map of it "
                                    "nor refused it (a texture that cannot be used is an error)")
    oracle = _gltf_albedo(folder / mesh) if mesh.endswith(".gltf") else _trimesh_albedo(folder / mesh)
    if oracle is not False:
        assert (albedo is None) == (oracle is None), (
            f"trimesh reading {mesh} from disk finds {'no' if oracle is None else 'a'} texture, the bake "
            f"{'none' if albedo is None else 'one'} (inputs {sorted(inputs)})")
        if albedo is not None:
            assert albedo.shape == oracle.shape and np.array_equal(albedo, oracle), (albedo.shape, oracle.shape)


def _names_a_used_texture(mesh: str, files: dict, touched: set) -> bool:
    """True where the asset, as damaged, plainly names a texture for the faces (so it bakes with an albedo map
    or is refused): the geometry, its UVs and the material assignment untouched, and
    OBJ: its MTL (edited line by line, not character-wise) still has a `map_Kd NAME` line;
    glTF: the primitive's material has a baseColorTexture whose texture's source is an image of the file."""
    import re

    if touched & {"obj", "gltf", "mtl-text"}:
        return False
    if mesh.endswith(".obj"):
        mtl = files["m.mtl"]
        return isinstance(mtl, str) and re.search(r"(?m)^map_Kd[ \t]+\S", mtl) is not None
    try:
        tree = json.loads(files["quad.gltf"])
        m = tree["meshes"][0]["primitives"][0]["material"]
        index = tree["materials"][m]["pbrMetallicRoughness"]["baseColorTexture"]["index"]
        source = tree["textures"][index]["source"]
        tree["images"][source]
        return all(type(i) is int and i >= 0 for i in (m, index, source))
    except (KeyError, IndexError, TypeError, ValueError):
        return False


def _event(text: str) -> None:
    """hypothesis' event() (its statistics), also from a check called outside a hypothesis test."""
    try:
        event(text)
    except Exception:
        pass


def _reason(stderr: str) -> str:
    """The gist of an error message, for hypothesis' statistics (--hypothesis-show-statistics)."""
    import re

    message = stderr.strip().splitlines()[-1] if stderr.strip() else ""
    message = re.sub(r"^error: \S*?(scene\.toml|quad\.\w+|x\.bundle)\S*:? ", "", message)
    for gist in ("which is not a variant", "names no object", "names no variant", "repeats an earlier set",
                 "not found", "cannot read the picture", "cannot read the mesh", "not a regular file", "names no image",
                 "picture of", "texture coordinates", "no area", "is empty", "has value", "unknown key"):
        if gist in message:
            return gist
    return re.sub(r"[0-9]+", "N", message[:50])


def _kind(name: str):
    from vdmbake.bundle.parts import KINDS

    return KINDS[name]


def _decoded(data: bytes) -> np.ndarray:
    from PIL import Image

    from vdmbake.common import texture

    with Image.open(io.BytesIO(data)) as im:
        return texture.from_image(im)


def _gltf_albedo(path: Path):
    """The picture a glTF's primitive names as its base colour, decoded from the bytes its image's URI gives (a file
    beside it, the URI percent-decoded as RFC 3986 says; or a data: URI), read without the bake's reader or trimesh
    (which reads neither percent-encoded URIs nor every node tree as glTF 2.0 does): None where the primitive names
    no texture or has no UVs to read one at, False where this oracle cannot tell (an image in a bufferView, a sampler
    wrapping other than REPEAT, whose picture the reader lays out over its UVs: tests/test_gltf_published.py checks
    those point by point; anything unreadable)."""
    import urllib.parse

    try:
        tree = json.loads(path.read_text())
        prim = tree["meshes"][0]["primitives"][0]
        if "material" not in prim:
            return None
        info = tree["materials"][prim["material"]].get("pbrMetallicRoughness", {}).get("baseColorTexture")
        if info is None:
            return None
        texture = tree["textures"][info["index"]]
        image = tree["images"][texture["source"]]
        if "TEXCOORD_0" not in prim["attributes"]:
            return None
        sampler = tree["samplers"][texture["sampler"]] if "sampler" in texture else {}
        if "bufferView" in image or {sampler.get("wrapS", 10497), sampler.get("wrapT", 10497)} != {10497}:
            return False
        uri = image["uri"]
        data = base64.b64decode(uri.partition(",")[2]) if uri.startswith("data:") else \
            (path.parent / urllib.parse.unquote(uri)).read_bytes()
        return _decoded(data)
    except Exception:
        return False


def _trimesh_albedo(path: Path):
    """The albedo map trimesh gives the asset read from disk with its own resolver (None: no texture), or
    False where trimesh cannot read it or has no UVs to read a texture at."""
    import trimesh

    from vdmbake.assets.meshes import base_colour_map

    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
        visual = getattr(loaded, "visual", None)
        uv = getattr(visual, "uv", None)
        if uv is None or len(uv) != len(loaded.vertices):
            return None
        return base_colour_map(visual)
    except Exception:
        return False


# ------------------------------------------------------------------------------------------ 2. baselines

BASELINE_ROW_KEYS = ("object", "label", "median_ms", "spread_ms", "mean_dluv", "p95_dluv", "flip_mean", "counters")
BASELINE_VALUES = VALUES | st.sampled_from([
    math.nan, math.inf, -math.inf, 10**4000, -1, 2**63, 2**63 - 1, 1e300, 1.0000001e300, -1e300, 5e-324, "1.0", "",
    "x" * 201, "a\nb", "\x7f", "\u2028", "\x85", True, [], {}, [1, 2], [32, 32, 32], [[32, 32]], [32.0, 32.0],
    [0, 32], {"fragments": -1}, {"": 1}, {"x" * 65: 1}, {"a\n": 1}, {"fragments": 2**63}, {"fragments": 1.5},
]).map(copy.deepcopy)
BASELINE_EDGES = {
    "median_ms": [0, 0.0, 5e-324, 1e-300, 1e300, 1, 2**53 + 1],
    "spread_ms": [None, 0, 1e300, 5e-324],
    "mean_dluv": [None, 1e300, -1e300, -0.0, 5e-324],
    "p95_dluv": [None, 1e300, -1e300],
    "flip_mean": [None, 0.5, -1e300],
    "counters": [None, {}, {"fragments": 2**63 - 1}, {"fragments": 0, "new": 1}, {"\u00e9" * 64: 1}],
    "object": ["ball", "b" * 200, "\u00e9", "\u2028", "ball "],
    "label": ["mesh", "coarse@0.5", "l" * 200, "|", "mesh\u0085"],
    "time": [None, "gpu", "wall", "\u00e9"],
    "device": [None, "other", "d" * 200],
    "resolution": [None, [1, 1], [2**31 - 1, 2**31 - 1], [64, 32]],
}
RAW = "\x00raw\x00"      # a value written into the JSON text as it is (see A.dumps_with_raw)
RAW_LITERALS = st.sampled_from(["NaN", "Infinity", "-Infinity", "9" * 5000, "-" + "9" * 5000, "1" + "0" * 5000 + ".5",
                                "1e400", "-1e400", "1E+2", "-0", "0x10", "01", "1.", ".5", "+1", "true", "null",
                                '"\\ud800"', '"\\u0000"']) | st.builds(
    lambda n: "[" * n + "]" * n,
    st.sampled_from([50, 400, 850, 900, 950, 980, 990, 995, 1000, 5000, 100000]) | st.integers(800, 1000))


def _baseline_paths(path) -> bool:
    """The paths of a report that baseline.load reads (the rest of a report it ignores)."""
    if not path or path[0] not in ("time", "device", "resolution", "rows", "budget"):   # budget.repeats: issue 32
        return False
    return path[0] != "rows" or len(path) <= 2 or (len(path) >= 3 and path[2] in BASELINE_ROW_KEYS)


@st.composite
def baseline_text(draw, fuzz_report: Quiet):
    """A report.json's text (str or bytes) with one to three edits: values retyped (NaN, Inf, huge integers,
    deep nesting), keys removed, rows of the wrong shape, and the JSON text itself damaged. `fuzz_report` is
    test_fuzz's fixture: (a real run's report,)."""
    report, = fuzz_report
    data = copy.deepcopy(report)
    raw, text_ops = {}, []
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["tree", "tree", "tree", "edge", "edge", "edge", "rows", "raw", "raw", "text",
                                   "whole"]))
        if op == "edge" and isinstance(data, dict) and isinstance(data.get("rows"), list) and data["rows"]:
            # values a report may well hold, at the ends of what load() accepts: what compare() must then take
            row = data["rows"][draw(st.integers(0, len(data["rows"]) - 1))]
            key = draw(st.sampled_from(list(BASELINE_EDGES)))
            target = data if key in ("time", "device", "resolution") else row if isinstance(row, dict) else {}
            if draw(st.integers(0, 5)) == 0:
                target.pop(key, None)
            else:
                target[key] = copy.deepcopy(draw(st.sampled_from(BASELINE_EDGES[key])))
        elif op == "tree":
            data = draw(mutated(data, _baseline_paths, BASELINE_VALUES))
        elif op == "rows":
            rows = data.get("rows") if isinstance(data, dict) else None
            how = draw(st.sampled_from(["row", "row", "rows", "many", "duplicate", "empty"]))
            if how == "row" and isinstance(rows, list) and rows:
                row = report["rows"][0]
                rows[draw(st.integers(0, len(rows) - 1))] = copy.deepcopy(draw(st.sampled_from(
                    [[], [row], list(row.values()), "row", 1, None, {}, {"rows": []}, [[]]])))
            elif how == "rows" and isinstance(data, dict):
                data["rows"] = copy.deepcopy(draw(st.sampled_from([{}, [[]], {"0": report["rows"][0]}, "rows", 0, None,
                                                                   [None]])))
            elif how == "many" and isinstance(rows, list) and 0 < len(rows) <= 10:
                # aliases: the same rows, edited as one
                data["rows"] = (rows * 2000)[:draw(st.sampled_from([100, 2000]))]
            elif how == "duplicate" and isinstance(rows, list) and rows:
                data["rows"] = rows + [copy.deepcopy(rows[0])]
            elif isinstance(data, dict):
                data["rows"] = []
        elif op == "raw" and isinstance(data, dict):
            paths = [p for p in _paths(data) if _baseline_paths(p)]
            if paths:
                path = draw(st.sampled_from(paths))
                parent = data
                for k in path[:-1]:
                    parent = parent[k]
                marker = f"{RAW}{len(raw)}"
                parent[path[-1]] = marker
                raw[marker] = draw(RAW_LITERALS)
        elif op == "text":
            text_ops.append(draw(st.sampled_from(["truncate", "flip", "edit", "bom", "utf16", "latin1", "dupkey"])))
        elif op == "whole":
            return draw(st.sampled_from(["", "null", "[]", "1", '"report"', "{}", '{"rows": null}', '{"rows": []}',
                                         '{"rows": [{}]}', "\ufeff{}", "{" * 3000]))
    try:
        text = A.dumps_with_raw(data, raw)
    except (ValueError, RecursionError):   # a 5000-digit integer or deep nesting json cannot write
        return draw(RAW_LITERALS)
    for op in text_ops:
        if op == "truncate":
            text = text[:draw(st.integers(0, max(0, len(text) - 1)))]
        elif op == "flip" and text:
            at = draw(st.integers(0, len(text) - 1))
            char = draw(st.sampled_from(['"', "{", "]", ",", ":", "\\", "\x00", "\n", "9", "\u00e9"]))
            text = text[:at] + char + text[at + 1:]
        elif op == "edit":
            text = _edit_text(text, draw(TEXT_EDITS))
        elif op == "bom":
            text = "\ufeff" + text
        elif op == "dupkey" and text.startswith("{"):
            text = '{"rows": 1, "device": ["x"], ' + text[1:]
        elif op in ("utf16", "latin1"):
            return text.encode("utf-16" if op == "utf16" else "latin-1", "replace")
    return text


def check_baseline(path: Path, text, new: dict) -> None:
    """vdmrender.deciding.baseline.load on a (damaged) report: an InputError of one line naming --baseline; or a baseline
    whose every value compare() reads has its type, and which compare(), table() and to_csv() take without error
    against `new` (a real run's report) and against itself, in both roles. A hang fails by time_limit."""
    from vdmrender.deciding import baseline
    from vdmrender.reporting import report

    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass"))
    with time_limit(20, "baseline.load"):
        try:
            old = baseline.load(path)
        except InputError as e:
            one_line(e)
            assert "--baseline" in str(e), str(e)
            _event("refused")
            old = None
    if old is None:
        return
    _event("accepted")
    for row in old["rows"]:
        assert isinstance(row["object"], str) and isinstance(row["label"], str), row
        median = row["median_ms"]
        assert isinstance(median, float | int) and math.isfinite(median) and median >= 0, row
        for k in ("spread_ms", "mean_dluv", "p95_dluv", "flip_mean"):
            assert row[k] is None or (isinstance(row[k], float | int) and not isinstance(row[k], bool)
                                      and math.isfinite(row[k])), (k, row[k])
        assert row["counters"] is None or all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < 2**63
                                              for v in row["counters"].values()), row["counters"]
    with time_limit(20, "baseline.compare"):
        for a, b in ((old, new), (old, old), (new, old)):
            for thresholds in ((None, None), (0.0, 1.25), (1e-9, 1e-9), (1e300, 1e300)):
                for across in (False, True):
                    block = baseline.compare(a, b, *thresholds, across)
                    report.baseline_table(block)
                    report.baseline_csv(block)
                    json.dumps(report.finite(block), allow_nan=False)


# ------------------------------------------------------------------------------------ 3. composite sets

ALL_LABELS = [label for labels in A.COMPOSITE_LABELS.values() for label in labels]
LABEL = st.sampled_from(ALL_LABELS) | st.sampled_from(A.NEAR_LABELS) | st.text(max_size=12)
OBJECT_KEY = (st.sampled_from(list(A.COMPOSITE_LABELS) + ["Ball", "ball ", "", "a.b", "ball\n", "render", "\u00e9"])
              | st.text(max_size=6))
TOML_SCALARS = st.one_of(st.booleans(), st.integers(-2**63, 2**63 - 1), st.floats(), st.text(max_size=8),
                         st.sampled_from([10**30, "", "mesh"]))
TOML_VALUES = st.recursive(
    TOML_SCALARS, lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=6), c, max_size=3), max_leaves=6)


@st.composite
def composite_sets(draw):
    """render.composite for A.composite_scene: the scene's two valid sets with one to three edits (labels
    near the real ones, other objects' labels, names of no object, sets emptied, repeated, dropped, added),
    or replaced whole by a value of another type; None: the key left out."""
    sets = copy.deepcopy(A.COMPOSITE_SETS)
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["label", "label", "real_label", "real_label", "key", "drop_key", "add_key",
                                   "drop_set", "drop_set", "repeat_set", "empty_set", "new_set", "new_set", "new_set",
                                   "value_type", "whole"]))
        if not isinstance(sets, list):
            break
        pick = (lambda: draw(st.integers(0, len(sets) - 1))) if sets else None
        if op in ("label", "real_label") and pick:
            s = sets[pick()]
            if isinstance(s, dict) and s:
                s[draw(st.sampled_from(sorted(s)))] = draw(LABEL if op == "label" else st.sampled_from(ALL_LABELS))
        elif op == "key" and pick:
            s = sets[pick()]
            if isinstance(s, dict) and s:
                old = draw(st.sampled_from(sorted(s)))
                s[draw(OBJECT_KEY)] = s.pop(old)
        elif op == "drop_key" and pick:
            s = sets[pick()]
            if isinstance(s, dict) and s:
                del s[draw(st.sampled_from(sorted(s)))]
        elif op == "add_key" and pick:
            s = sets[pick()]
            if isinstance(s, dict):
                s[draw(OBJECT_KEY)] = draw(LABEL)
        elif op == "drop_set" and pick:
            del sets[pick()]
        elif op == "repeat_set" and pick:
            sets.append(copy.deepcopy(sets[pick()]))
        elif op == "empty_set":
            sets.append({})
        elif op == "new_set":   # a set of real labels, each object's or any object's
            mixed = draw(st.booleans())
            sets.append({name: draw(st.sampled_from(ALL_LABELS if mixed else labels))
                         for name, labels in A.COMPOSITE_LABELS.items()})
        elif op == "value_type" and pick:
            s = sets[pick()]
            if isinstance(s, dict) and s:
                s[draw(st.sampled_from(sorted(s)))] = draw(TOML_VALUES)
            else:
                sets[pick()] = draw(TOML_VALUES)
        elif op == "whole":
            return draw(st.none() | TOML_VALUES | st.sampled_from([[], [{}], [[]], "mesh", {}, [{"ball": "mesh"}]]))
    return sets


def _has_nan(v) -> bool:
    return any(x != x for x in _floats(v))


def check_composite_bake(folder: Path, sets) -> None:
    """The composite scene with `sets` as its render.composite, parsed (check_scene_data: refused in one line or
    round-tripping) and baked (check_cli: exit 0 or 2). What is accepted names every object of the scene once with
    one of its own labels (the labels written out in A.COMPOSITE_LABELS, not asked of the code), has no empty or
    repeated set, and survives the manifest: the bundle opens and its scene holds the same sets."""
    from helpers import bake

    text = A.composite_scene(sets)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise AssertionError(f"the fuzzer wrote TOML that does not parse: {e}\n{text[:2000]}") from None
    if not _has_nan(sets):
        assert data["render"].get("composite") == sets, (data["render"].get("composite"), sets)
    check_scene_data(data)
    scene = folder / "scene.toml"
    scene.write_text(text)
    out = folder / "x.bundle"
    with time_limit(60, "vdmbake of the composite scene"):
        result = bake(scene, "-o", out)
    ok = check_cli(result, out)
    _event("baked" if ok else "refused: " + _reason(result.stderr))
    if not ok:
        return
    accepted = [] if sets is None else sets
    assert isinstance(accepted, list) and (sets is None or accepted), sets
    for i, s in enumerate(accepted):
        assert isinstance(s, dict) and set(s) == set(A.COMPOSITE_LABELS), (i, s)
        assert all(s[name] in A.COMPOSITE_LABELS[name] for name in s), (i, s)
        assert s not in accepted[:i], f"set {i} repeats an earlier one: {s}"
    b = check_bundle_reads(out)
    assert b.manifest["scene"]["render"].get("composite", []) == accepted, b.manifest["scene"]["render"]
    assert list(b.scene.render.composite) == accepted


# ------------------------------------------------------------------------ 4. octahedral and pyramid parts

TABLE_NAMES = st.sampled_from(["samples", "atlas", "L00", "L01", "L02", "L03", "L04", "L09", "L1", "L001", "l00",
                               "L00 ", "bb000", "bb001", "bb004", "bb005", "bb000.samples", "bb000.L00", "bb000.L01",
                               "bb000.L05", "bb000.", "bb000.L00.x", "atlas2", "Atlas", "x"])
CHANNEL_NAMES = st.sampled_from(["depth.Z", "min.Z", "max.Z", "normal.U", "normal.V", "normal.X", "A", "albedo.R",
                                 "albedo.G", "depth.z", "Z", "extra.X", "albedo.A"])
TEXEL_VALUES = st.sampled_from([math.nan, math.inf, -math.inf, 1e30, -1e30, 3.4e38, -1.0, 2.0, 0.0, 0.5, 65504.0, -0.0,
                                1e-45, 1.0])
BIG_NUMBERS = st.sampled_from(["9" * 5000, "-" + "9" * 5000, "1" + "0" * 5000 + ".5", "1e5000", "-1e5000", "3" * 4000,
                               "1" + "0" * 4000 + ".0"])


def _meta_values(key: str, meta: dict):
    """Values of a part's metadata key near the ones that matter: off by one, at the schema's bounds, the other
    mode, a frame that is not orthonormal (determinant 1, or -1), sizes of zero or beyond float32."""
    n = meta.get(key)
    near = [n - 1, n + 1, 2 * n, n // 2, 0, -n, float(n)] if isinstance(n, int) and not isinstance(n, bool) else []
    c, s = math.cos(0.5), math.sin(0.5)
    table = {
        "views": [1, 2, 64, 65, 2**31], "resolution": [15, 16, 17, 4096, 4097], "levels": [0, 1, 64, 65],
        "boards": [2**31 - 1, 2**31], "rays": [-1, 2**31 - 1, 2**31, 2**63],
        "hemi": [True, False, 0, 1, "false"], "pyramids": [True, False, 0, "true"], "albedo": [True, False, 1, "true"],
        "mode": ["wrap", "clamp", "WRAP", "", "mirror"],
        "basis": [[[1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 1, 0], [1, 0, 0], [0, 0, 1]],
                  [[2, 0, 0], [0, 0.5, 0], [0, 0, 1]], [[1, 1, 0], [0, 1, 0], [0, 0, 1]],
                  [[c, -s, 0], [s, c, 0], [0, 0, 1]], [[1, 0, 0], [0, 1, 0]], [[1, 0, 0], [0, 1, 0], [0, 0, 1.0005]],
                  [[1, 0, 0], [0, 1, 0], [0, 0, math.nan]], [[-1, 0, 0], [0, -1, 0], [0, 0, 1]]],
        "centre": [[0, 0, 0], [1e30, 0, 0], [1e300, 0, 0], [0, 0], [math.nan, 0, 0]],
        "radius": [0, -1, 1e-300, 1e300, 1e30, 0.5, 5e-324], "capture": [0, -1, 1e-300, 1e300, 1e30, 0.5, 5e-324],
    }
    return st.sampled_from(near + table.get(key, [])).map(copy.deepcopy) if near or key in table else VALUES


@st.composite
def part_case(draw, bundle: Quiet):
    """A damaged part of A.PARTS_SCENE's bundle (a DamagedPart: the part, its file's bytes, its manifest metadata,
    raw literals for the manifest's text, what was done). `bundle` is test_fuzz's parts_bundle: the manifest, each
    part's EXR tables and manifest entry. The tables are edited (levels dropped, renamed, swapped, reordered;
    channels dropped, renamed, added; shapes cropped, padded, transposed; types changed; texels set to NaN, Inf,
    huge or out of range; a level's min and max swapped, or an interval shrunk) and encoded again, or the file's
    bytes damaged; the metadata's own keys get values of other sizes, modes and types, and 5000-digit numbers.
    The entry's sha256 and bytes are check_part's to make agree with the file. Damage that only reorders the
    file's tables changes nothing a reader may see."""
    from vdmbake.formats import exr

    parts = bundle[1]
    rel = draw(st.sampled_from(sorted(parts)))
    tables0, meta0 = parts[rel]
    tables = {name: dict(chans) for name, chans in tables0.items()}
    meta, raw, damage = copy.deepcopy(meta0), {}, []
    byte_ops = []
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["drop_table", "rename_table", "swap_tables", "reorder", "drop_channel",
                                   "rename_channel", "add_channel", "shape", "shape", "dtype", "texel", "texel",
                                   "channel_value", "minmax", "bytes", "meta", "meta", "meta", "meta_big", "meta_drop",
                                   "meta_add"]))
        names = list(tables)
        damage.append(op)
        if op == "drop_table" and len(names) > 1:
            name = draw(st.sampled_from(names))
            del tables[name]
            damage[-1] += f" {name}"
        elif op == "rename_table":
            old, new = draw(st.sampled_from(names)), draw(TABLE_NAMES)
            tables[new] = tables.pop(old)
            damage[-1] += f" {old} -> {new}"
        elif op == "swap_tables" and len(names) > 1:
            a, b = draw(st.sampled_from(names)), draw(st.sampled_from(names))
            tables[a], tables[b] = tables[b], tables[a]
            damage[-1] += f" {a} <-> {b}"
        elif op == "reorder":
            order = draw(st.permutations(names))
            tables = {name: tables[name] for name in order}
            damage[-1] += f" {order}"
        elif op in ("drop_channel", "rename_channel", "add_channel", "shape", "dtype", "texel", "channel_value",
                    "minmax"):
            name = draw(st.sampled_from(names))
            chans = dict(tables[name])
            cname = draw(st.sampled_from(sorted(chans)))
            damage[-1] += f" {name}/{cname}"
            if op == "drop_channel" and len(chans) > 1:
                del chans[cname]
            elif op == "rename_channel":
                new = draw(CHANNEL_NAMES)
                chans[new] = chans.pop(cname)
                damage[-1] += f" -> {new}"
            elif op == "add_channel":
                new = draw(CHANNEL_NAMES)
                chans[new] = np.zeros_like(chans[cname])
                damage[-1] += f" + {new}"
            elif op == "shape":
                how = draw(st.sampled_from(["crop_row", "crop_col", "pad_row", "pad_col", "transpose", "one",
                                            "double"]))
                fn = {"crop_row": lambda a: a[:-1], "crop_col": lambda a: a[:, :-1],
                      "pad_row": lambda a: np.concatenate([a, a[-1:]]),
                      "pad_col": lambda a: np.concatenate([a, a[:, -1:]], 1),
                      "transpose": lambda a: a.T, "one": lambda a: a[:1, :1],
                      "double": lambda a: np.repeat(np.repeat(a, 2, 0), 2, 1)}[how]
                chans = {c: fn(a) for c, a in chans.items()}
                damage[-1] += f" {how}"
            elif op == "dtype":
                dtype = draw(st.sampled_from([np.float16, np.uint32, np.float32]))
                damage[-1] += f" {dtype.__name__}"
                with np.errstate(all="ignore"):
                    chans[cname] = np.nan_to_num(chans[cname], nan=0, posinf=0, neginf=0).astype(dtype)
            elif op in ("texel", "channel_value"):
                a = chans[cname].astype(np.float32).copy()
                v = draw(TEXEL_VALUES)
                if a.size == 0:
                    pass
                elif op == "texel":
                    i, j = draw(st.integers(0, a.shape[0] - 1)), draw(st.integers(0, a.shape[1] - 1))
                    a[i, j] = v
                    damage[-1] += f"[{i}, {j}] = {v}"
                else:
                    a[...] = v
                    damage[-1] += f" = {v}"
                chans[cname] = a
            elif op == "minmax" and {"min.Z", "max.Z"} <= set(chans) and chans["min.Z"].shape == chans["max.Z"].shape \
                    and chans["min.Z"].size:
                lo, hi = chans["min.Z"].copy(), chans["max.Z"].copy()
                if draw(st.booleans()):
                    chans["min.Z"], chans["max.Z"] = hi, lo
                    damage[-1] += " swapped"
                else:          # one cell's interval shrunk to its middle: it no longer holds the surface
                    i, j = draw(st.integers(0, lo.shape[0] - 1)), draw(st.integers(0, lo.shape[1] - 1))
                    lo[i, j] = hi[i, j] = 0.5 * (float(lo[i, j]) + float(hi[i, j])) if lo[i, j] < hi[i, j] else lo[i, j]
                    damage[-1] += f" [{i}, {j}] shrunk"
                    chans["min.Z"], chans["max.Z"] = lo, hi
            tables[name] = chans
        elif op == "bytes":
            byte_ops.append(draw(st.sampled_from(["truncate", "flip", "flip", "header"])))
            damage[-1] += f" {byte_ops[-1]}"
        elif op in ("meta", "meta_big", "meta_drop"):
            keys = [k for k in meta if k not in ("kind", "sha256", "bytes")]
            if keys:
                key = draw(st.sampled_from(keys))
                if op == "meta":
                    meta[key] = draw(_meta_values(key, meta0))
                    damage[-1] += f" {key} = {show(meta[key])}"
                elif op == "meta_big":
                    marker = f"{RAW}{len(raw)}"
                    meta[key] = marker
                    raw[marker] = draw(BIG_NUMBERS)
                    damage[-1] += f" {key} = {raw[marker][:12]}... ({len(raw[marker])} characters)"
                else:
                    del meta[key]
                    damage[-1] += f" {key}"
        elif op == "meta_add":
            key = draw(st.sampled_from(["levels", "views", "mode", "resolution", "albedo", "size", "x"]))
            meta[key] = draw(VALUES)
            damage[-1] += f" {key} = {show(meta[key])}"
    try:
        data = exr.to_bytes(tables)
    except Exception:         # what the writer cannot write (no table, an empty or 1-D table): not a file to test
        assume(False)
    for op in byte_ops:
        b = bytearray(data)
        if not b:
            break
        if op == "truncate":
            b = b[:draw(st.integers(0, len(b) - 1))]
        elif op == "flip":
            for _ in range(draw(st.integers(1, 4))):
                b[draw(st.integers(0, len(b) - 1))] ^= draw(st.integers(1, 255))
        else:                 # the header: the first few hundred bytes, where the windows and part names are
            b[draw(st.integers(0, min(len(b), 400) - 1))] ^= draw(st.integers(1, 255))
        data = bytes(b)
    return DamagedPart(rel, data, meta, raw, damage)


@dataclass
class DamagedPart:
    """part_case's example; shown (in a failure) as the part and what was done to it, not its bytes."""
    rel: str
    data: bytes
    meta: dict
    raw: dict
    damage: list

    def __repr__(self) -> str:
        return f"DamagedPart({self.rel!r}, damage={self.damage!r}, {len(self.data)} bytes)"


def _bounds(p, empties: bool) -> bool:
    """Every level's intervals hold the surface the samples make: a level-0 cell's interval holds its four
    corner samples (the bilinear patch lies within them), a cell above holds those of the level-0 cells it
    covers; what the tracer relies on to skip a cell (looser intervals only cost it time). Where `empties`
    (a billboard's pyramid), level-0 cells marked empty ([1e30, -1e30]) have no surface."""
    from vdmbake.common import pyramid

    corners = pyramid.corners(p.samples, p.mode)
    true = np.stack([corners.min(-1), corners.max(-1)], -1)
    if empties:
        true[p.levels[0][..., 0] >= pyramid.HUGE] = (pyramid.HUGE, -pyramid.HUGE)
    for level in p.levels:
        if level.shape != true.shape:
            return False
        if not (np.all(level[..., 0] <= true[..., 0]) and np.all(level[..., 1] >= true[..., 1])):
            return False
        true = pyramid._reduce(true)
    return True


def check_part(folder: Path, manifest: dict, case: "DamagedPart", original) -> None:
    """A bundle whose part `rel` is `data` with the manifest entry `meta` (sha256 and bytes made to agree, so the
    part kind's own checks are what is tested): the manifest refused in one line, or the part read through
    Bundle(...).read with its kind refused in one line, or accepted as what its metadata says it is:
    octahedral: atlas N R x N R, finite, an orthonormal right-handed basis, colour iff the metadata says so;
    pyramid: the mode and number of levels the metadata says, finite, intervals that hold the surface;
    bordered-billboards: one set of maps per board, finite, pyramids iff the metadata says so, with intervals
    that hold their surface. Damage that only reorders the file's tables reads as the original part."""
    import hashlib

    from vdmbake.bundle.directory import Bundle
    from vdmbake.bundle.parts import KINDS

    rel, data, meta, raw, damage = case.rel, case.data, case.meta, case.raw, case.damage
    damage = [d.split(" ")[0] for d in damage]
    m = copy.deepcopy(manifest)
    m["parts"][rel] = {**meta, "kind": manifest["parts"][rel]["kind"], "sha256": hashlib.sha256(data).hexdigest(),
                       "bytes": len(data)}
    (folder / rel).parent.mkdir(parents=True, exist_ok=True)
    (folder / rel).write_bytes(data)
    (folder / "manifest.json").write_text(A.dumps_with_raw(m, raw))
    preserving = set(damage) == {"reorder"}
    with time_limit(30, f"reading part {rel}"):
        try:
            b = Bundle(folder)
            kind = KINDS[b.manifest["parts"][rel]["kind"]]
            value = b.read(rel, kind)
        except InputError as e:
            one_line(e)
            assert not preserving, f"a part whose tables were only reordered is refused: {e}"
            _event(f"{manifest['parts'][rel]['kind']}: refused")
            return
    _event(f"{kind.name}: accepted")
    meta = b.manifest["parts"][rel]
    if kind.name == "octahedral":
        side = meta["views"] * meta["resolution"]
        for name in ("depth", "coverage"):
            a = getattr(value, name)
            assert a.shape == (side, side) and np.isfinite(a).all(), (name, a.shape, side)
        assert value.normal.shape == (side, side, 2) and np.isfinite(value.normal).all()
        assert (value.albedo is not None) == bool(meta.get("albedo")), meta.get("albedo")
        assert value.albedo is None or (value.albedo.shape == (side, side, 3) and np.isfinite(value.albedo).all())
        basis = np.asarray(value.basis, np.float64)
        assert np.allclose(basis @ basis.T, np.eye(3), atol=1e-3) and np.linalg.det(basis) > 0, (
            f"accepted basis {basis.tolist()}: not a right-handed orthonormal frame")
        assert value.views == meta["views"] and value.resolution == meta["resolution"]
        assert math.isfinite(value.radius) and value.radius > 0 and math.isfinite(value.capture) and value.capture > 0
        assert np.isfinite(value.centre).all()
    elif kind.name == "pyramid":
        assert value.mode == meta["mode"] and value.top + 1 == meta["levels"], (value.mode, value.top, meta)
        assert np.isfinite(value.samples).all() and all(np.isfinite(a).all() for a in value.levels)
        assert _bounds(value, empties=False), "accepted a pyramid whose intervals do not hold its surface"
    else:
        assert len(value) == meta["boards"], (len(value), meta["boards"])
        for i, board in enumerate(value):
            assert board.maps.ndim == 3 and board.maps.shape[2] == 4 and np.isfinite(board.maps).all()
            assert (board.pyramid is not None) == bool(meta["pyramids"])
            if board.pyramid is not None:
                assert board.pyramid.samples.shape == board.maps.shape[:2]
                assert _bounds(board.pyramid, empties=True), (
                    f"accepted board {i}'s pyramid whose intervals do not hold its surface")
    if preserving:
        _same(value, original)


def _same(a, b) -> None:
    """Two values of a part kind hold the same arrays and numbers."""
    if isinstance(a, (list, tuple)):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y)
    elif isinstance(a, np.ndarray):
        assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    elif hasattr(a, "__dataclass_fields__"):
        for f in a.__dataclass_fields__:
            _same(getattr(a, f), getattr(b, f))
    else:
        assert a == b, (a, b)


# =========================================================================================================
# The targets of issue 32: the part cache as input (entries as hostile files, stats.log lines) and glTF
# accessors. Same contract; a hostile cache entry is stricter still: it is never the bake's failure.
# =========================================================================================================

CACHE_SCENE = """
[render]
resolution = [32, 32]

[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 12, rings = 6 }
techniques = { mesh = {}, coarse = { ratios = [0.5] } }
"""
HOSTILE_NAMES = ["../../../outside/evil.ply", "OUTSIDE/evil.ply", "mesh.ply", "coarse-0.5.ply/../../x.ply", "",
                 ".hidden.ply", "a\nb.ply", "coarse-x.exr", "sub/coarse-1.ply", "coarse-\x00.ply", "..", "coarse"]


def cache_entry_bytes(key: str, header, blobs: list[bytes]) -> bytes:
    """An entry as PartCache.put writes it, with valid checksums, from a header (any JSON, or its bytes) and the
    parts' bytes."""
    import hashlib

    from vdmbake.library.cache import MAGIC

    head = header if isinstance(header, bytes) else json.dumps(header, separators=(",", ":")).encode()
    body = b"".join([len(head).to_bytes(8, "little"), head, *blobs])
    return MAGIC + b" " + hashlib.sha256(body).hexdigest().encode() + b"\n" + body


@st.composite
def cache_entry_case(draw, fixture: Quiet):
    """(key, op, what): one entry of the fixture's cache made hostile. op 'bytes' (flipped, cut, grown or other
    bytes: a miss by its checksum), 'name' (a part renamed, with valid checksums: outside the bundle, another
    step's, not plain), 'header' (the header's JSON mutated, valid checksums), 'file' (a FIFO, a link to a
    device or to another entry, a folder, a deeply nested header), 'swap' (another key's entry)."""
    from vdmbake.library.cache import PartCache

    _, _, entries = fixture
    key = draw(st.sampled_from(sorted(entries)))
    data = entries[key]
    op = draw(st.sampled_from(["bytes", "name", "name", "header", "header", "file", "swap"]))
    if op == "bytes":
        at = draw(st.integers(0, len(data) - 1))
        how = draw(st.sampled_from(["flip", "cut", "grow", "random"]))
        what = (data[:at] + bytes([data[at] ^ 0x40]) + data[at + 1:] if how == "flip" else data[:at] if how == "cut"
                else data + draw(st.binary(min_size=1, max_size=64)) if how == "grow"
                else draw(st.binary(max_size=256)))
    elif op in ("name", "header"):
        e = PartCache._parse(key, data)
        header = {"key": key, "entry": e.entry, "log": e.log,
                  "parts": [{"name": n, "kind": k, "meta": m, "bytes": len(d),
                             "sha256": __import__("hashlib").sha256(d).hexdigest()} for n, k, m, d in e.parts]}
        if op == "name":
            k = draw(st.integers(0, len(header["parts"]) - 1))
            old, new = header["parts"][k]["name"], draw(st.sampled_from(HOSTILE_NAMES) | st.text(max_size=12))
            header["parts"][k]["name"] = new
            if draw(st.booleans()):       # the block names it too, as a crafted entry would
                header["entry"] = json.loads(json.dumps(header["entry"]).replace(
                    json.dumps("@part:" + old), json.dumps("@part:" + new)))
        else:
            header = draw(mutated(header))
        what = cache_entry_bytes(key, header, [d for *_, d in e.parts])
    elif op == "file":
        what = draw(st.sampled_from(["fifo", "device", "link", "folder", "deep"]))
    else:
        what = entries[draw(st.sampled_from(sorted(entries)))]
    return key, op, what


def check_cache_bake(folder: Path, fixture: Quiet, case) -> None:
    """The fixture's scene baked through its cache with one entry made hostile (cache_entry_case): exit 0 within a
    time limit, whatever the entry (a cache is never the reason a bake fails), nothing written outside the bundle
    and the cache, and the bundle the one a bake without the cache makes (byte for byte, but timing.json); where
    the header's JSON was mutated with valid checksums (an entry that may be another valid bake: what a shared
    cache still trusts, docs/library.md), the bundle opens and every part reads."""
    from click.testing import CliRunner

    from vdmbake.cli import main as bake_main
    from vdmbake.library.cache import PartCache

    scene, plain, entries = fixture
    key, op, what = case
    cache = PartCache(folder / "cache")
    for k, data in entries.items():
        cache.path(k).parent.mkdir(parents=True, exist_ok=True)
        cache.path(k).write_bytes(data)
    p = cache.path(key)
    p.unlink()
    if op == "file":
        if what == "fifo":
            os.mkfifo(p)
        elif what == "device":
            p.symlink_to("/dev/zero")
        elif what == "link":
            p.symlink_to(cache.path(next(k for k in sorted(entries) if k != key)))
        elif what == "folder":
            p.mkdir()
        else:
            p.write_bytes(cache_entry_bytes(key, b"[" * 100000 + b"]" * 100000, []))
    else:
        p.write_bytes(what)
    (folder / "outside").mkdir()
    (folder / "s.toml").write_text(scene)
    before = {q for q in folder.rglob("*") if "cache" not in q.relative_to(folder).parts}
    with time_limit(60, "a bake through a hostile cache"):
        r = CliRunner().invoke(bake_main, [str(folder / "s.toml"), "-o", str(folder / "b.bundle"), "--cache",
                                           str(folder / "cache")], env={"VDM_CACHE": None})
    assert r.exit_code == 0, (op, r.output[-3000:], repr(r.exception))
    after = {q for q in folder.rglob("*") if "cache" not in q.relative_to(folder).parts
             and "b.bundle" not in q.relative_to(folder).parts}
    assert after == before, sorted(map(str, after - before))
    if op == "header":
        check_bundle_reads(folder / "b.bundle")
        _event("header mutated: " + ("same bundle" if bundle_files(folder / "b.bundle") == plain else "other bundle"))
    else:
        assert bundle_files(folder / "b.bundle") == plain, op
        _event(f"{op}: same bundle")


def bundle_files(bundle: Path) -> dict:
    """Every file of a bundle but timing.json, as bytes."""
    return {q.relative_to(bundle).as_posix(): q.read_bytes() for q in sorted(bundle.rglob("*"))
            if q.is_file() and q.name != "timing.json"}


COUNTERS = ("hits", "misses", "corrupt", "stored", "evicted", "parts_from_cache", "bytes_from_cache")


@st.composite
def stats_lines(draw) -> list[bytes]:
    """stats.log lines: counts as vdmbake writes them, and lines no bake writes (other JSON, counts of the wrong
    type or sign, a torn write's bytes, nested text)."""
    good = st.fixed_dictionaries({k: st.integers(0, 10**6) for k in COUNTERS}).map(
        lambda d: json.dumps({"time": 1.0, "host": "h", "pid": 1, **d}).encode())
    bad = st.one_of(
        st.builds(lambda k, v: json.dumps({k: v}).encode(), st.sampled_from(COUNTERS),
                  st.sampled_from([-1, 1.5, "3", True, None, 2**63, 10**400, [1], {"a": 1}])),
        VALUES.map(lambda v: json.dumps(v).encode()), st.binary(max_size=40),
        st.sampled_from([b"\xff\xfe{\"hits", b'{"hits": 1', b"NaN", b"\xc3", b"   ", b"{}"]))
    return draw(st.lists(good | bad, max_size=12))


def _stats_oracle(lines: list[bytes]) -> tuple[int, int, dict]:
    """(bakes, skipped, sums) as the documented rule reads stats.log: a line of UTF-8 JSON, an object whose
    counters are integers from 0 to 2^63 (absent: 0), is a bake's counts; any other non-blank line is skipped."""
    bakes = skipped = 0
    sums = dict.fromkeys(COUNTERS, 0)
    for line in b"\n".join(lines).split(b"\n"):
        if not line.strip():
            continue
        try:
            rec = json.loads(line.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError):
            rec = None
        if not isinstance(rec, dict) or not all(type(rec.get(k, 0)) is int and 0 <= rec.get(k, 0) < 2**63
                                                for k in COUNTERS):
            skipped += 1
            continue
        bakes += 1
        for k in COUNTERS:
            sums[k] += rec.get(k, 0)
    return bakes, skipped, sums


def check_stats(folder: Path, lines: list[bytes]) -> None:
    """--cache-stats over these stats.log lines: exit 0 within a time limit, the counts of the lines that are
    counts, and every other line counted as skipped."""
    from click.testing import CliRunner

    from vdmbake.cli import main as bake_main

    (folder / "stats.log").write_bytes(b"\n".join(lines) + b"\n")
    with time_limit(20, "--cache-stats"):
        r = CliRunner().invoke(bake_main, ["--cache", str(folder), "--cache-stats", "--json"],
                               env={"VDM_CACHE": None})
    assert r.exit_code == 0, (r.output[-2000:], repr(r.exception))
    st_ = json.loads(r.stdout)
    bakes, skipped, sums = _stats_oracle(lines)
    assert (st_["bakes"], st_["skipped_lines"]) == (bakes, skipped), (st_, bakes, skipped)
    assert {k: st_[k] for k in COUNTERS} == sums
    _event(f"{'some' if skipped else 'no'} lines skipped")


# glTF accessors: the fuzz assets' quad with a COLOR_0 accessor (VEC3 float) of its own view; edits of the
# accessors' and views' layout keys to values at and past the spec's bounds.
def _with_colour() -> tuple[dict, bytes]:
    tree, data = copy.deepcopy(A.GLTF), A.BIN + b"\0" * (-len(A.BIN) % 4)
    colour = np.full((4, 3), 0.5, "<f4").tobytes()
    tree["bufferViews"].append({"buffer": 0, "byteOffset": len(data), "byteLength": len(colour)})
    tree["accessors"].append({"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC3"})
    tree["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = 3
    data += colour
    tree["buffers"][0]["byteLength"] = len(data)
    return tree, data


LAYOUT = st.sampled_from([0, 1, 2, 3, 4, 5, 6, 8, 11, 12, 16, 24, 48, 252, 256, 2**31, 2**63, -1, -12, 1.5, "4",
                          None, True, 10**400])


@st.composite
def accessor_case(draw) -> tuple[dict, bytes]:
    """(glTF JSON, its .bin): one to three edits of an accessor's count, byteOffset, componentType, type, normalized
    or bufferView, a view's byteStride, byteOffset, byteLength or buffer, the buffer's bytes."""
    tree, data = _with_colour()
    for _ in range(draw(st.integers(1, 3))):
        what = draw(st.sampled_from(["accessor", "accessor", "view", "view", "bin", "attribute"]))
        if what == "accessor":
            a = tree["accessors"][draw(st.integers(0, 3))]
            key = draw(st.sampled_from(["count", "byteOffset", "componentType", "type", "normalized", "bufferView"]))
            a[key] = draw(LAYOUT | st.sampled_from([5120, 5121, 5122, 5123, 5125, 5126, 5130, "VEC2", "VEC3",
                                                    "VEC4", "SCALAR", "MAT4"]))
        elif what == "view":
            v = tree["bufferViews"][draw(st.integers(0, 3))]
            v[draw(st.sampled_from(["byteStride", "byteOffset", "byteLength", "buffer"]))] = draw(LAYOUT)
        elif what == "bin":
            data = data[:draw(st.integers(0, len(data)))]
        else:
            attrs = tree["meshes"][0]["primitives"][0]["attributes"]
            attrs[draw(st.sampled_from(["COLOR_0", "TEXCOORD_0", "NORMAL", "POSITION"]))] = draw(LAYOUT)
    return tree, data


def _laid_out(tree: dict, data: bytes) -> bool:
    """Whether every accessor the primitive reads lies inside its view and buffer, its elements apart (glTF 2.0
    §3.6.2.4), its attributes of one count: the oracle for what load_mesh_file may accept."""
    sizes = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
    widths = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
    prim = tree["meshes"][0]["primitives"][0]
    counts = []
    for name, i in [*prim["attributes"].items(), ("indices", prim.get("indices"))]:
        if i is None and name == "indices":
            continue
        a = tree["accessors"][i]
        size, width = sizes[a["componentType"]], widths[a["type"]]
        v = tree["bufferViews"][a["bufferView"]]
        stride = v.get("byteStride", size * width)
        end = a.get("byteOffset", 0) + stride * (a["count"] - 1) + size * width
        if stride < size * width or end > v["byteLength"] or v.get("byteOffset", 0) + v["byteLength"] > len(data):
            return False
        if name != "indices":
            counts.append(a["count"])
    return len(set(counts)) == 1


def check_accessors(folder: Path, case) -> None:
    """load_mesh_file on the edited glTF: an InputError of one line within a time limit, or a mesh whose
    accessors the oracle finds laid out as the spec says, with finite vertices and one colour per vertex."""
    from vdmbake.assets.meshes import load_mesh_file

    tree, data = case
    (folder / "quad.bin").write_bytes(data)
    (folder / "tex.png").write_bytes(A.PNG)
    (folder / "quad.gltf").write_text(json.dumps(tree))
    with time_limit(20, "load_mesh_file"):
        try:
            mesh = load_mesh_file(folder / "quad.gltf")
        except InputError as e:
            one_line(e)
            _event("refused")
            return
    _event("accepted")
    assert _laid_out(tree, data), "accepted an accessor out of its layout"
    assert np.isfinite(mesh.vertices).all()
    assert mesh.colors is None or (len(mesh.colors) == len(mesh.vertices) and np.isfinite(mesh.colors).all())


# Scheduler addresses (`vdmbake --scheduler`): what check_address and the reachability check make of them,
# without starting Dask. Hosts are this machine's or malformed: no example waits on a name server.
ADDRESS = st.builds(
    lambda scheme, host, port, tail: f"{scheme}{host}{port}{tail}",
    st.sampled_from(["tcp://", "tls://", "local:", "local", "inproc://", "ucx://", "", "TCP://", "tcp:/"]),
    st.sampled_from(["127.0.0.1", "[::1]", "", "999.1.1.1", "127.0.0.1\n", "a b", "[::1", "0.0.0.0"]),
    st.sampled_from([":0", ":1", ":65535", ":65536", ":-1", ":" + "9" * 30, ":x", "", ":8786:1", "1024", "1025",
                     "100000", "0", "-2", "2"]),
    st.sampled_from(["", "/", "/x", "\x00", " "]))


def check_address_text(address: str) -> None:
    """check_address, then (for what it accepts over TCP) the reachability check: each refuses with an InputError
    of one line or accepts, never hanging; local:N is accepted only for 1 to MAX_LOCAL. The hang guard stays under
    Dask's own 30 s of retries, which the plain connect replaces; that the connect is bounded by CONNECT_S is
    test_cluster_trust's (a wall time here would be the loaded machine's)."""
    import re

    from vdmbake import cluster

    with time_limit(20, "the scheduler address checks"):
        try:
            cluster.check_address(address)
            m = cluster.LOCAL.fullmatch(address)
            assert not m or 1 <= int(m[1]) <= cluster.MAX_LOCAL, address
            if not m:
                cluster._reachable(address)
        except InputError as e:
            one_line(e)
            _event("refused")
            return
    _event("accepted")
    assert re.fullmatch(r"local:\d+", address) or not address.startswith("local"), address
