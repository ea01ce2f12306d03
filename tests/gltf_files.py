"""glTF files rebuilt in the tests from the numbers of published Khronos glTF-Sample-Models (no package on PyPI or
npm ships those models; nothing is downloaded at test time): each generator writes a file like the named sample,
with the same structure (primitives, materials, accessors, modes) and the values written out here, so a test can
state the colour, position or normal the file means. Also the in-memory glTF writer they and the glTF tests build
on (Gltf), a mesh read from a file drawn and traced (drawn_and_traced), and the Khronos validator's report
(validate)."""
from __future__ import annotations

import base64
import io
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
from PIL import Image

from vdmbake.common.mesh import TriMesh
from vdmbake.common import texture
from vdmbake.formats.gltf import COMPONENT_OF
from vdmrender.gpu import gl
from vdmrender.common import images
from vdmrender.comparing import metrics
from vdmrender.tracing import reference
from vdmrender.passes.raster import RasterMesh

from exports import MODULES, ROOT

VALIDATOR = MODULES / "gltf-validator"
QUAD = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)          # glTF's v runs down the picture
BG = (0.05, 0.05, 0.06)
PICTURE = (np.arange(16 * 3).reshape(4, 4, 3) * 5).astype(np.uint8)  # 16 distinct texels, row 0 the picture's top
CLAMP, MIRROR, REPEAT = 33071, 33648, 10497   # glTF samplers' wrap modes (the GL enums)


class Gltf:
    """A glTF file built up in memory: one buffer, accessors, meshes of quads, materials, nodes."""

    def __init__(self):
        self.blob = b""
        self.tree = {"asset": {"version": "2.0"}, "accessors": [], "bufferViews": [], "meshes": [], "nodes": [],
                     "scenes": [{"nodes": []}], "scene": 0}

    def accessor(self, a: np.ndarray, normalized: bool = False) -> int:
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.tree["bufferViews"].append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": a.nbytes})
        self.blob += np.ascontiguousarray(a).tobytes()
        acc = {"bufferView": len(self.tree["bufferViews"]) - 1, "count": len(a),
               "componentType": COMPONENT_OF[a.dtype.char],
               "type": "SCALAR" if a.ndim == 1 else f"VEC{a.shape[1]}"}
        if normalized:
            acc["normalized"] = True
        if a.ndim == 2 and a.shape[1] == 3 and a.dtype == np.float32:   # POSITION needs its bounds
            acc["min"], acc["max"] = a.min(0).tolist(), a.max(0).tolist()
        self.tree["accessors"].append(acc)
        return len(self.tree["accessors"]) - 1

    def material(self, factor=None, picture=None, info=None, sampler=None) -> int:
        """A material of `factor` and (if `picture`, an (H, W, 3) uint8) a base-colour texture whose textureInfo
        gets `info`'s keys, sampled by `sampler`."""
        pbr = {} if factor is None else {"baseColorFactor": list(factor)}
        if picture is not None:
            png = io.BytesIO()
            Image.fromarray(np.asarray(picture, np.uint8)).save(png, "PNG")
            self.tree.setdefault("images", []).append(
                {"uri": "data:image/png;base64," + base64.b64encode(png.getvalue()).decode()})
            tex = {"source": len(self.tree["images"]) - 1}
            if sampler is not None:
                self.tree.setdefault("samplers", []).append(sampler)
                tex["sampler"] = len(self.tree["samplers"]) - 1
            self.tree.setdefault("textures", []).append(tex)
            pbr["baseColorTexture"] = {"index": len(self.tree["textures"]) - 1, **(info or {})}
        self.tree.setdefault("materials", []).append({"pbrMetallicRoughness": pbr})
        return len(self.tree["materials"]) - 1

    def primitive(self, colour=None, material=None, uv=None, mode=None) -> dict:
        """A quad (two triangles, or its corners for a `mode` of points), its COLOR_0 `colour` given per vertex
        (normalized where it is of integers)."""
        p = {"attributes": {"POSITION": self.accessor(QUAD)},
             "indices": self.accessor(np.array([0, 1, 2, 0, 2, 3], np.uint16))}
        if colour is not None:
            colour = np.asarray(colour)
            p["attributes"]["COLOR_0"] = self.accessor(colour, normalized=colour.dtype.kind == "u")
        if uv is not None:
            p["attributes"]["TEXCOORD_0"] = self.accessor(np.asarray(uv, np.float32))
        if material is not None:
            p["material"] = material
        if mode is not None:
            p["mode"] = mode
            del p["indices"]
        return p

    def mesh(self, *primitives) -> int:
        self.tree["meshes"].append({"primitives": list(primitives)})
        return len(self.tree["meshes"]) - 1

    def node(self, root: bool = True, **node) -> int:
        self.tree["nodes"].append(node)
        if root:
            self.tree["scenes"][0]["nodes"].append(len(self.tree["nodes"]) - 1)
        return len(self.tree["nodes"]) - 1

    def write(self, path, buffer: str = "data"):
        """The file at `path`, its buffer a data: URI, a file of that name, or (`glb`) the GLB's binary chunk."""
        self.tree["buffers"] = [{"byteLength": len(self.blob)}]
        if buffer == "data":
            self.tree["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                              + base64.b64encode(self.blob).decode())
        elif buffer != "glb":
            self.tree["buffers"][0]["uri"] = buffer
            (path.parent / buffer).write_bytes(self.blob)
        text = json.dumps(self.tree).encode()
        if buffer != "glb":
            path.write_bytes(text)
            return path
        text += b" " * (-len(text) % 4)
        blob = self.blob + b"\0" * (-len(self.blob) % 4)
        chunks = (len(text).to_bytes(4, "little") + b"JSON" + text + len(blob).to_bytes(4, "little") + b"BIN\0" + blob)
        path.write_bytes(b"glTF" + (2).to_bytes(4, "little") + (12 + len(chunks)).to_bytes(4, "little") + chunks)
        return path


def drawn_and_traced(ctx, m, stored, cam, light, material, truth) -> tuple[dict, dict]:
    """The mesh read from a file drawn (its stored part) and traced (the reference) from `cam`, each compared
    with `truth`, the frame its file's own numbers give (metrics.compare)."""
    target = gl.Target(ctx, cam.width, cam.height)
    r = RasterMesh(ctx, stored, light, material, 256)
    try:
        r.render(cam, target)
        drawn = metrics.compare(images.encode(target.read(), BG), truth)
    finally:
        r.release()
        target.release()
    return drawn, metrics.compare(images.encode(reference.MeshReference(m, light, material).render(cam), BG), truth)


def albedo_at(m: TriMesh, points) -> np.ndarray:
    """(N, 3) linear albedo of the loaded mesh at surface points (on its faces), as the reference reads it."""
    points = np.asarray(points, np.float64)
    out = []
    for p in points:
        tri = m.vertices[m.faces]
        e1, e2, d = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], p - tri[:, 0]
        n = np.cross(e1, e2)
        area = (n * n).sum(1)
        b1 = (np.cross(d, e2) * n).sum(1) / np.where(area > 0, area, 1)
        b2 = (np.cross(e1, d) * n).sum(1) / np.where(area > 0, area, 1)
        inside = (area > 0) & (b1 >= -1e-9) & (b2 >= -1e-9) & (b1 + b2 <= 1 + 1e-9) & (np.abs((d * n).sum(1)) < 1e-9)
        f = int(np.flatnonzero(inside)[0])
        out.append(texture.surface_albedo(m, np.array([f]), np.array([[1 - b1[f] - b2[f], b1[f], b2[f]]]), None)[0])
    return np.array(out)


def validate(path: Path) -> dict:
    """The Khronos glTF validator's report (npm gltf-validator, installed by make's set-up)."""
    node = shutil.which("node")
    assert node and VALIDATOR.is_dir(), "the glTF validator is installed by `make test` (npm gltf-validator)"
    r = subprocess.run([node, str(ROOT / "tools" / "validate_gltf.cjs"), str(path)], capture_output=True, text=True,
                       env={**os.environ, "GLTF_VALIDATOR": str(VALIDATOR)})
    assert r.returncode in (0, 1), r.stderr
    return json.loads(r.stdout)

# four sRGB texels per picture (rows top to bottom as in the file), one picture per textured primitive
PICTURES = [np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 0]]], np.uint8),
            np.array([[[255, 255, 255], [0, 0, 0]], [[128, 128, 128], [64, 32, 16]]], np.uint8),
            np.array([[[10, 200, 30], [200, 10, 30]], [[30, 10, 200], [250, 250, 250]]], np.uint8)]


def texture_coordinate_test(path, pictures=PICTURES, factor_only=(0.85, 0.425, 0.2, 1.0)):
    """TextureCoordinateTest-like: one quad per picture, each its own material and texture, side by side (node k
    at x = 2k), and a factor-only quad beside them (x = 2 * len(pictures))."""
    g = Gltf()
    for k, picture in enumerate(pictures):
        g.node(mesh=g.mesh(g.primitive(material=g.material(picture=picture), uv=UV)), translation=[2.0 * k, 0, 0])
    if factor_only is not None:
        g.node(mesh=g.mesh(g.primitive(material=g.material(list(factor_only)))),
               translation=[2.0 * len(pictures), 0, 0])
    return g.write(path)


def factor_only_engine(path, factors=(0.85, 0.425)):
    """2CylinderEngine-like: one mesh of several primitives whose materials have a baseColorFactor only (grey
    values of the sample's materials); primitive k moved to z = k by its own positions."""
    g = Gltf()
    prims = []
    for k, f in enumerate(factors):
        p = g.primitive(material=g.material([f, f, f, 1.0]))
        p["attributes"]["POSITION"] = g.accessor(QUAD + np.float32([0, 0, k]))
        prims.append(p)
    g.node(mesh=g.mesh(*prims))
    return g.write(path)


def simple_sparse_accessor(path, zeros=False):
    """SimpleSparseAccessor: a strip of 14 vertices (x 0..6, y 0 and 1) and 12 triangles, whose POSITION accessor
    has a sparse part replacing vertices 8, 10 and 12 by (1, 2, 0), (3, 3, 0), (5, 4, 0) (`zeros`: the base is
    no bufferView, so every other vertex is at the origin, and two triangles join the origin and the moved ones)."""
    g = Gltf()
    base = np.array([[x, y, 0] for y in (0, 1) for x in range(7)], np.float32)
    tri = [[0, 12, 8], [0, 10, 8]] if zeros else []   # zeros: the strip has no area left; triangles of the moved ones
    for x in range(0 if zeros else 6):
        tri += [[x, x + 1, x + 8], [x, x + 8, x + 7]]
    p = {"attributes": {"POSITION": g.accessor(base)}, "indices": g.accessor(np.array(tri, np.uint16).ravel())}
    index, values = g.accessor(np.array([8, 10, 12], np.uint16)), g.accessor(np.float32([[1, 2, 0], [3, 3, 0],
                                                                                        [5, 4, 0]]))
    acc = g.tree["accessors"][p["attributes"]["POSITION"]]
    acc["sparse"] = {"count": 3, "indices": {"bufferView": g.tree["accessors"][index]["bufferView"],
                                             "componentType": 5123},
                     "values": {"bufferView": g.tree["accessors"][values]["bufferView"]}}
    acc["max"] = [6, 4, 0]
    if zeros:
        del acc["bufferView"]
    g.node(mesh=g.mesh(p))
    return g.write(path)


def sparse_colour(path):
    """A quad whose COLOR_0 is zeros but for a sparse part setting vertices 1 and 3 to (0.2, 0.4, 0.8)."""
    g = Gltf()
    p = g.primitive()
    index, values = g.accessor(np.array([1, 3], np.uint8)), g.accessor(np.float32([[0.2, 0.4, 0.8]] * 2))
    g.tree["accessors"].append({"componentType": 5126, "count": 4, "type": "VEC3", "sparse": {
        "count": 2, "indices": {"bufferView": g.tree["accessors"][index]["bufferView"], "componentType": 5121},
        "values": {"bufferView": g.tree["accessors"][values]["bufferView"]}}})
    p["attributes"]["COLOR_0"] = len(g.tree["accessors"]) - 1
    g.node(mesh=g.mesh(p))
    return g.write(path)


def simple_morph(path, weights=(0.5, 0.25), node_weights=None):
    """SimpleMorph/MorphPrimitivesTest-like: a quad with two morph targets, target 0 lifting vertex 2 by
    (0, 0, 1) and turning its NORMAL, target 1 moving vertex 0 by (-1, 0, 0), at the mesh's default `weights`
    (`node_weights`: the node's, which override them)."""
    g = Gltf()
    p = g.primitive()
    p["attributes"]["NORMAL"] = g.accessor(np.float32([[0, 0, 1]] * 4))
    lift = np.zeros((4, 3), np.float32)
    lift[2] = [0, 0, 1]
    turn = np.zeros((4, 3), np.float32)
    turn[2] = [1, 0, -1]
    left = np.zeros((4, 3), np.float32)
    left[0] = [-1, 0, 0]
    p["targets"] = [{"POSITION": g.accessor(lift), "NORMAL": g.accessor(turn)}, {"POSITION": g.accessor(left)}]
    m = g.mesh(p)
    g.tree["meshes"][m]["weights"] = list(weights)
    node = {"mesh": m} if node_weights is None else {"mesh": m, "weights": list(node_weights)}
    g.node(**node)
    return g.write(path)


HEXAGON = np.float32([[0, 0, 0]] + [[np.cos(a), np.sin(a), 0] for a in np.radians(np.arange(0, 360, 60))])


def primitive_modes(path, modes=(6, 5, 0, 1)):
    """MeshPrimitiveModes-like: one mesh with a primitive per mode, each on its own vertices (moved along x):
    TRIANGLE_FAN (6) a hexagon around its centre, TRIANGLE_STRIP (5) a zig-zag band of 4 triangles, POINTS
    (0), LINES (1), LINE_LOOP (2), LINE_STRIP (3) the hexagon's rim; every triangle faces +z."""
    g = Gltf()
    prims = []
    for k, mode in enumerate(modes):
        if mode == 6:
            v, idx = HEXAGON, [0, 1, 2, 3, 4, 5, 6, 1]
        elif mode == 5:   # bottom, top, bottom, top...: (0, 1, 2) then (1, 3, 2) counter-clockwise seen from +z
            v = np.float32([[i // 2, 1 - i % 2, 0] for i in range(6)])
            idx = list(range(6))
        else:
            v, idx = HEXAGON[1:], list(range(6))
        p = {"attributes": {"POSITION": g.accessor(v + np.float32([3 * k, 0, 0]))},
             "indices": g.accessor(np.array(idx, np.uint16)), "mode": mode}
        prims.append(p)
    g.node(mesh=g.mesh(*prims))
    return g.write(path)


def prism(path, sides=12, rings=4, hard=True):
    """A closed prism of `sides` flat sides (radius 1, height 2, each side a grid of `rings` x 2 quads) and two
    caps, every side and cap on its own vertices with NORMAL: the face's normal (`hard`), else the radial
    direction on the sides. sides = 4 is a hard-edged Box."""
    g = Gltf()
    verts, norms, tris = [], [], []

    def grid(corner, du, dv, n, nu, nv, normal_at=None):
        base = len(verts)
        for j in range(nv + 1):
            for i in range(nu + 1):
                p = corner + du * i / nu + dv * j / nv
                verts.append(p)
                norms.append(n if normal_at is None else normal_at(p))
        for j in range(nv):
            for i in range(nu):
                a = base + j * (nu + 1) + i
                tris.extend([[a, a + 1, a + nu + 2], [a, a + nu + 2, a + nu + 1]])

    angles = np.radians(np.arange(sides) * 360 / sides + 180 / sides)
    ring = np.c_[np.cos(angles), np.sin(angles), np.zeros(sides)]
    for s in range(sides):
        a, b = ring[s], ring[(s + 1) % sides]
        n = np.cross(b - a, [0, 0, 1])
        grid(np.r_[a[:2], -1], b - a, np.array([0, 0, 2.0]), n / np.linalg.norm(n), 2, rings,
             None if hard else lambda p: np.r_[p[:2] / np.linalg.norm(p[:2]), 0])
    for z, sign in ((1, 1), (-1, -1)):
        base = len(verts)
        verts += [np.array([0, 0, z])] + [np.r_[r[:2], z] for r in ring]
        norms += [np.array([0, 0, sign])] * (sides + 1)
        for s in range(sides):
            t = [base, base + 1 + s, base + 1 + (s + 1) % sides]
            tris.append(t if sign > 0 else t[::-1])
    p = {"attributes": {"POSITION": g.accessor(np.float32(verts)), "NORMAL": g.accessor(np.float32(norms))},
         "indices": g.accessor(np.array(tris, np.uint16).ravel())}
    g.node(mesh=g.mesh(p))
    return g.write(path)


def box_vertex_colors(path):
    """BoxVertexColors-like: a box (prism of 4 sides) with a COLOR_0 per vertex from its position (x, y, z mapped
    from [-1, 1] to [0, 1]) as normalized unsigned shorts."""
    out = prism(path, sides=4, rings=1)
    import base64
    import json

    tree = json.loads(out.read_text())
    blob = base64.b64decode(tree["buffers"][0]["uri"].partition(",")[2])
    acc = tree["accessors"][0]
    view = tree["bufferViews"][acc["bufferView"]]
    pos = np.frombuffer(blob, "<f4", acc["count"] * 3, view["byteOffset"]).reshape(-1, 3)
    colour = np.round((pos + 1) / 2 * 65535).astype("<u2")
    blob += b"\0" * (-len(blob) % 4)
    tree["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": colour.nbytes})
    blob += colour.tobytes()
    tree["accessors"].append({"bufferView": len(tree["bufferViews"]) - 1, "componentType": 5123, "normalized": True,
                              "count": len(colour), "type": "VEC3"})
    tree["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = len(tree["accessors"]) - 1
    tree["buffers"][0] = {"byteLength": len(blob),
                          "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}
    out.write_text(json.dumps(tree))
    return out


def draco_grid(path, draco=True, glb=False, spoil=None):
    """A 4 x 4 grid of vertices (18 triangles) with NORMAL, TEXCOORD_0 and COLOR_0 (normalized unsigned bytes), as a
    plain file or with KHR_draco_mesh_compression (encoded by DracoPy, order preserved, positions to 16 bits, the
    rest lossless): the same geometry either way. `spoil(tree, extension)` edits the compressed file's JSON."""
    import DracoPy

    x, y = np.meshgrid(np.arange(4.0), np.arange(4.0))
    pos = np.column_stack([x.ravel(), y.ravel(), 0.1 * np.sin(x.ravel() + y.ravel())]).astype(np.float32)
    normal = np.column_stack([np.full(16, 0.1), np.zeros(16), np.ones(16)]) / np.hypot(0.1, 1.0)
    uv = pos[:, :2] / 3.0
    colour = (np.arange(48).reshape(16, 3) * 5).astype(np.uint8)
    quads = [(r * 4 + c, r * 4 + c + 1, r * 4 + c + 5, r * 4 + c + 4) for r in range(3) for c in range(3)]
    faces = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], np.uint32)
    g = Gltf()
    names = {"POSITION": pos, "NORMAL": normal.astype(np.float32), "TEXCOORD_0": uv.astype(np.float32),
             "COLOR_0": colour}
    if not draco:
        prim = {"attributes": {k: g.accessor(v, normalized=k == "COLOR_0") for k, v in names.items()},
                "indices": g.accessor(faces.ravel().astype(np.uint16))}
    else:
        data = DracoPy.encode(pos, faces, quantization_bits=16, preserve_order=True, colors=colour,
                              tex_coord=uv.astype(np.float64), normals=normal)
        ids = {{0: "POSITION", 1: "NORMAL", 2: "COLOR_0", 3: "TEXCOORD_0"}[a["attribute_type"]]: a["unique_id"]
               for a in DracoPy.decode(data).attributes}
        g.blob += b"\0" * (-len(g.blob) % 4)
        g.tree["bufferViews"].append({"buffer": 0, "byteOffset": len(g.blob), "byteLength": len(data)})
        g.blob += data
        accessors = g.tree["accessors"]
        prim = {"attributes": {}, "extensions": {"KHR_draco_mesh_compression": {
            "bufferView": len(g.tree["bufferViews"]) - 1, "attributes": ids}}}
        for name, v in names.items():
            accessors.append({"componentType": 5121 if name == "COLOR_0" else 5126, "count": 16,
                              "type": f"VEC{v.shape[1]}", **({"normalized": True} if name == "COLOR_0" else {})})
            prim["attributes"][name] = len(accessors) - 1
        accessors[prim["attributes"]["POSITION"]].update(min=pos.min(0).tolist(), max=pos.max(0).tolist())
        accessors.append({"componentType": 5123, "count": faces.size, "type": "SCALAR"})
        prim["indices"] = len(accessors) - 1
        g.tree["extensionsUsed"] = g.tree["extensionsRequired"] = ["KHR_draco_mesh_compression"]
        if spoil is not None:
            spoil(g.tree, prim["extensions"]["KHR_draco_mesh_compression"])
    g.node(mesh=g.mesh(prim))
    return g.write(path, "glb" if glb else "data")


def meshopt_grid(path, spoil=None, octahedral=False):
    """draco_grid's grid, plain, then each bufferView compressed with EXT_meshopt_compression by the `meshopt`
    package's encoder (ATTRIBUTES for the attributes, COLOR_0 as VEC4 bytes so its rows are 4 bytes; TRIANGLES for
    the indices), the compressed bytes in buffer 0 and a fallback buffer 1 without data, as gltfpack writes it;
    `octahedral`: NORMAL as gltfpack's default, normalized bytes in rows of 4 through the OCTAHEDRAL filter (8
    bits, KHR_mesh_quantization). `spoil(tree, view_extensions)` edits the JSON; the file's buffer 0 is a data:
    URI."""
    import base64
    import json

    import meshopt

    tree = json.loads(draco_grid(path, draco=False).read_text())
    blob = base64.b64decode(tree["buffers"][0]["uri"].partition(",")[2])
    colour = tree["accessors"][tree["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"]]
    view = tree["bufferViews"][colour["bufferView"]]
    rgb = np.frombuffer(blob, np.uint8, view["byteLength"], view["byteOffset"]).reshape(-1, 3)
    rgba = np.column_stack([rgb, np.full(len(rgb), 255, np.uint8)])
    blob += rgba.tobytes()
    view.update(byteOffset=len(blob) - rgba.nbytes, byteLength=rgba.nbytes)
    colour["type"] = "VEC4"
    filters = {}
    if octahedral:
        normal = tree["accessors"][tree["meshes"][0]["primitives"][0]["attributes"]["NORMAL"]]
        view = tree["bufferViews"][normal["bufferView"]]
        n = np.frombuffer(blob, "<f4", 3 * normal["count"], view["byteOffset"]).reshape(-1, 3)
        rows = meshopt.encode_filter_oct(np.column_stack([n, np.ones(len(n))]), 4, 8)
        blob += rows.tobytes()
        view.update(byteOffset=len(blob) - rows.nbytes, byteLength=rows.nbytes, byteStride=4)
        normal.update(componentType=5120, normalized=True)
        filters[normal["bufferView"]] = "OCTAHEDRAL"
    packed, exts = b"", []
    for v, view in enumerate(tree["bufferViews"]):
        a = next(a for a in tree["accessors"] if a["bufferView"] == v)
        stride = view["byteStride"] if "byteStride" in view else {5126: 4, 5121: 1, 5123: 2}[a["componentType"]] * (
            int(a["type"][-1]) if a["type"] != "SCALAR" else 1)
        rows = np.frombuffer(blob, np.uint8, view["byteLength"], view["byteOffset"]).reshape(a["count"], stride)
        indices = a["type"] == "SCALAR"
        data = meshopt.encode_gltf_buffer(rows.view(np.uint16).ravel() if indices else rows,
                                          "TRIANGLES" if indices else "ATTRIBUTES")
        packed += b"\0" * (-len(packed) % 4)
        exts.append({"buffer": 0, "byteOffset": len(packed), "byteLength": len(data), "byteStride": stride,
                     "count": a["count"], "mode": "TRIANGLES" if indices else "ATTRIBUTES",
                     **({"filter": filters[v]} if v in filters else {})})
        packed += data
        view.update(buffer=1, extensions={"EXT_meshopt_compression": exts[-1]})
    tree["buffers"] = [{"byteLength": len(packed)},
                       {"byteLength": len(blob), "extensions": {"EXT_meshopt_compression": {"fallback": True}}}]
    tree["extensionsUsed"] = tree["extensionsRequired"] = ["EXT_meshopt_compression", "KHR_mesh_quantization"]
    if spoil is not None:
        spoil(tree, exts)
    tree["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(packed).decode()
    path.write_text(json.dumps(tree))
    return path
