"""The inputs the fuzzer's newer targets start from (tests/fuzz_inputs.py, tests/test_fuzz.py): a tiny textured
OBJ (+ MTL + PNG) and a tiny glTF (+ .bin + PNG) as bytes, with decoy files beside them for mutated names to
reach; a scene with composite sets; a scene whose bundle has octahedral atlases and pyramids. Everything is
small enough that a bake takes a few tens of milliseconds."""
from __future__ import annotations

import io
import json

import numpy as np
from PIL import Image

from scenes import TINY_HEAD

QUAD_V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.1]]
QUAD_UV = [[0, 0], [1, 0], [0, 1], [1, 1]]


def picture(fmt: str = "PNG", size=(4, 3), mode: str = "RGB", seed: int = 0, **save) -> bytes:
    """A small picture of distinct texels (so a flipped or swapped texel shows) in any format PIL writes."""
    rgb = np.random.default_rng(seed).integers(0, 256, (size[1], size[0], 3), np.uint8)
    im = Image.fromarray(rgb, "RGB")
    im = im.convert(mode) if mode != "RGB" else im
    buf = io.BytesIO()
    im.save(buf, fmt, **save)
    return buf.getvalue()


PNG = picture()
OBJ = "\n".join(["mtllib m.mtl", "usemtl mat"] + [f"v {x} {y} {z}" for x, y, z in QUAD_V]
                + [f"vt {s} {t}" for s, t in QUAD_UV] + ["f 1/1 2/2 3/3", "f 2/2 4/4 3/3"]) + "\n"
MTL = "newmtl mat\nKd 1 1 1\nmap_Kd tex.png\n"
BIN = (np.asarray(QUAD_V, "<f4").tobytes() + np.asarray(QUAD_UV, "<f4").tobytes()
       + np.asarray([0, 1, 2, 1, 3, 2], "<u2").tobytes())
GLTF = {
    "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
    "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
    "textures": [{"source": 0}], "images": [{"uri": "tex.png"}],
    "buffers": [{"uri": "quad.bin", "byteLength": len(BIN)}],
    "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in [(0, 48), (48, 32), (80, 12)]],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                   "min": [0, 0, 0], "max": [1, 1, 0.1]},
                  {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
                  {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
}

# Files beside the asset that a mutated name may reach: another picture, a picture in a folder, one with a
# space in its name, text that is no picture, a folder named like a picture, a second MTL, a short buffer.
OTHER_PNG = picture(size=(3, 5), seed=1)
DECOYS = {"other.png": OTHER_PNG, "sub/tex.png": picture(size=(2, 2), seed=2), "two words.png": picture(seed=3),
          "notpng.txt": b"not a picture\n", "dir.png/": None,
          "m2.mtl": b"newmtl mat\nKd 0.5 0.5 0.5\nmap_Kd other.png\n", "short.bin": BIN[:40]}

# Texture names a mutated map_Kd, mtllib or URI may take (besides arbitrary text).
NAMES = ["tex.png", "other.png", "sub/tex.png", "two words.png", "missing.png", "notpng.txt", "dir.png", "../tex.png",
         "/nonexistent/x.png", "", " ", "TEX.PNG", "tex.png ", "\ttex.png", "t\x1b[31mx.png", "m.mtl", "m2.mtl",
         "quad.obj", "quad.gltf", "quad.bin", "short.bin", "%74ex.png", "sub/../tex.png", "./tex.png", "tex.png#x",
         "file:///tex.png", "a\nb.png", "x" * 300 + ".png"]

# Other pictures a texture may be replaced by: valid ones in other formats and modes (the bake must take them
# as PIL decodes them), and edge cases (1 x 1, one row of 70000 texels).
PICTURES = {
    "jpeg": picture("JPEG"), "gif": picture("GIF"), "bmp": picture("BMP"), "tiff": picture("TIFF"),
    "webp": picture("WEBP", lossless=True), "ppm": picture("PPM"), "ico": picture("ICO", size=(16, 16)),
    "rgba": picture(mode="RGBA"), "la": picture(mode="LA"), "palette": picture(mode="P"), "1bit": picture(mode="1"),
    "gray16": picture(mode="I;16"), "cmyk_jpeg": picture("JPEG", mode="CMYK"), "one": picture(size=(1, 1)),
    "wide": picture(size=(70000, 1)), "interlaced": picture(size=(9, 7), optimize=False),
}


def write_files(folder, files: dict) -> None:
    """{relative name: bytes} into `folder` (a name ending in / is a folder; None as data: nothing)."""
    for name, data in files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if name.endswith("/"):
            path.mkdir(exist_ok=True)
        elif data is not None:
            path.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8", "surrogatepass"))


def textured_scene(mesh: str, textures: str | None) -> str:
    extra = "" if textures is None else f'textures = "{textures}"\n'
    return TINY_HEAD + f'[[objects]]\nname = "thing"\nmesh = "{mesh}"\n{extra}techniques = {{ mesh = {{}} }}\n'


# ------------------------------------------------------------------------------------------- composite sets

# Each object's variant labels, as the report spells them (written out here, not asked of the code under test).
COMPOSITE_LABELS = {
    "ball": ["mesh", "coarse@0.5", "coarse@0.5000001"],
    "atoms": ["impostor@direct", "impostor@deferred", "tessellated@0"],
    "ring": ["billboards@axis-hit0.01", "billboards@axis-hier"],
}
# Labels a mutated set may name: near misses of the real ones, and other techniques' labels.
NEAR_LABELS = ["coarse@0.50000010", "coarse@5e-1", "coarse@.5", "coarse@0.5000001000000001",
               "coarse@0.5000000999999999", "coarse@0.50", "coarse@+0.5", "coarse@0.5 ", " mesh", "MESH", "mesh\n",
               "mesh\x00", "coarse", "coarse@",
               "@0.5", "coarse@0.5@0.5", "impostor", "impostor@Direct", "tessellated@0.0", "tessellated@-0",
               "billboards@axis-hier+coarse", "billboards@axis-hit0.010", "billboards", "vdm@8", "", "all",
               "coarse@nan", "coarse@inf", "coarse@1e-400", "\u2028mesh", "mesh\u0085"]
COMPOSITE_SETS = [{"ball": "mesh", "atoms": "impostor@direct", "ring": "billboards@axis-hier"},
                  {"ball": "coarse@0.5000001", "atoms": "tessellated@0", "ring": "billboards@axis-hit0.01"}]
COMPOSITE_OBJECTS = """
[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 12, rings = 6 }
techniques = { mesh = {}, coarse = { ratios = [0.5, 0.5000001] } }

[[objects]]
name = "atoms"
spheres = [[2, 0, 0, 0.5], [2.5, 0, 0, 0.3]]
cylinders = [[2, 0, 0, 2.5, 0, 0, 0.1]]
techniques = { impostor = { shading = ["direct", "deferred"] }, tessellated = { levels = [0] } }

[[objects]]
name = "ring"
primitive = "torus"
params = { segments = 8, rings = 4 }
transform = { translate = [0, 2, 0] }
techniques = { billboards = { resolution = 16, variants = ["axis-hit0.01", "axis-hier"] } }
"""


def toml_value(v) -> str:
    """A value as TOML writes it (inline tables and arrays; no TOML writer is installed)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if v != v else ("inf" if v == float("inf") else "-inf" if v == float("-inf") else repr(v))
    if isinstance(v, str):
        return toml_string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{toml_string(str(k))} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(type(v))


def toml_string(s: str) -> str:
    out = []
    for c in s:
        if c in '"\\':
            out.append("\\" + c)
        elif ord(c) < 0x20 or ord(c) == 0x7f:
            out.append(f"\\u{ord(c):04x}")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'


def composite_scene(sets) -> str:
    """The composite scene with `render.composite = sets` (left out if sets is None)."""
    line = "" if sets is None else f"composite = {toml_value(sets)}\n"
    return TINY_HEAD.replace("shadow_map = 256\n", "shadow_map = 256\n" + line) + COMPOSITE_OBJECTS


# ------------------------------------------------------------------------------ octahedral and pyramid parts

PARTS_SCENE = TINY_HEAD + """
[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 12, rings = 6 }
[objects.techniques]
octahedral = { variants = ["full-3x16-march", "hemi-2x16-virtual"] }
billboards = { resolution = 16, variants = ["greedy-hier"] }

[[objects]]
name = "tile"
primitive = "torus"
params = { segments = 12, rings = 6 }
mesostructure = { height = "bricks", size = 8 }
techniques = { relief = { iterations = [4] } }

[[objects]]
name = "thing"
mesh = "quad.obj"
techniques = { octahedral = { variants = ["full-2x16-march"] } }
"""
PARTS_FILES = {"quad.obj": OBJ, "m.mtl": MTL, "tex.png": PNG}


def parts_under_test(manifest: dict) -> list[str]:
    """The parts of PARTS_SCENE's bundle the part fuzzer damages: every octahedral atlas (one with colour),
    the relief pyramid and the billboards' bordered maps with their pyramids."""
    kinds = ("octahedral", "pyramid", "bordered-billboards")
    return sorted(rel for rel, meta in manifest["parts"].items() if meta["kind"] in kinds)


def dumps_with_raw(data, raw: dict[str, str]) -> str:
    """json.dumps of `data` with each string value that is a key of `raw` written as raw[key], unquoted: a
    number of 5000 digits, which Python's json writes and reads only up to 4300 digits."""
    text = json.dumps(data)
    for marker, literal in raw.items():
        text = text.replace(json.dumps(marker), literal)
    return text
