"""The fuzzer's targets for assets as untrusted input (issue 42), run by tests/test_fuzz.py:

* file references: a glTF's buffer or image uri, an OBJ's mtllib or its MTL's map_Kd, named in hostile spellings
  (absolute paths, '..' past the root, percent-encoded escapes, links leading in and out, a link loop, a NUL, the
  same file spelt otherwise), loaded with the scene's folder as the root. The oracle resolves the name as the file
  system does (os.path.realpath): a name resolving outside the root is refused, naming it; every file a load reads
  lies inside; a name resolving to a good file inside (a sibling folder of the scene's tree too) loads.
* glTF node trees: nodes naming children (repeated, out of range, cycles), scenes naming roots or none,
  EXT_mesh_gpu_instancing copies on some nodes, extensionsRequired with or without what is read. The oracle walks
  the tree as glTF 2.0 §3.5 gives it: a tree loads with one quad per copy placed (2 triangles each); anything
  else (a node reached twice, an index out of range, nothing placed, an unknown required extension) is refused.

* compressed glTF (issue 43): the grid of tests/gltf_files.py compressed by Draco (DracoPy) or meshopt (meshopt),
  its compressed bytes changed (a Draco stream cut) and its JSON's declarations (counts, attribute ids, component
  types and types; a meshopt view's count, byteStride, mode, filter) changed. The oracle: the file is refused in
  one line, or loads no more vertices and triangles than the grid has, with finite positions; both decoders run
  in this process, so a crash in one fails the run.

Every example runs within a time limit, so work out of proportion to the file (a node tree's copies multiplying)
fails it."""
from __future__ import annotations

import json
import os
from pathlib import Path
from urllib.parse import unquote

import numpy as np
from hypothesis import strategies as st

import fuzz_assets as A
from fuzz_inputs import _event, one_line, time_limit
from vdmbake.errors import InputError

# ------------------------------------------------------------------------------------------- file references

# The tree each example is laid out in: base/root is the scene's folder (the root), the mesh in root/models.
LAYOUT = {
    "root/models/quad.bin": A.BIN, "root/models/tex.png": A.PNG, "root/models/m.mtl": A.MTL.encode(),
    "root/textures/quad.bin": A.BIN, "root/textures/tex.png": A.OTHER_PNG, "root/textures/m.mtl": A.MTL.encode(),
    "root/models/sub/.keep": b"", "outside/secret.bin": A.BIN, "outside/tex.png": A.PNG, "outside/m.mtl": A.MTL.encode(),
}
LINKS = {"root/models/in.bin": "../textures/quad.bin", "root/models/out.bin": "../../outside/secret.bin",
         "root/models/in.png": "../textures/tex.png", "root/models/out.png": "../../outside/tex.png",
         "root/models/in.mtl": "../textures/m.mtl", "root/models/out.mtl": "../../outside/m.mtl",
         "root/models/loop": "loop", "root/models/up": "..", "root/away": "../outside"}
GOOD = {"buffer": ("root/models/quad.bin", "root/textures/quad.bin"),       # what a slot may name and load
        "image": ("root/models/tex.png", "root/textures/tex.png"),
        "mtllib": ("root/models/m.mtl", "root/textures/m.mtl"),
        "map_Kd": ("root/models/tex.png", "root/textures/tex.png")}
STEMS = {"buffer": ("quad.bin", "secret.bin", "in.bin", "out.bin"), "image": ("tex.png", "in.png", "out.png"),
         "mtllib": ("m.mtl", "in.mtl", "out.mtl"), "map_Kd": ("tex.png", "in.png", "out.png")}
FOLDERS = ["", "./", "sub/../", "../textures/", "../../outside/", "../models/", "../../root/models/", "up/",
           "up/textures/", "up/../../outside/", "../away/", "{root}/models/", "{root}/textures/", "{base}/outside/",
           "/etc/", "/", "file:///etc/", "\\..\\", "loop/", "missing/"]


@st.composite
def reference_case(draw) -> tuple[str, str]:
    """(slot, name): which reference is spelt (a glTF buffer or image uri, an OBJ mtllib or map_Kd) and how; a glTF
    name may be percent-encoded in part ('.' and '/' too, as an escape would be)."""
    slot = draw(st.sampled_from(["buffer", "image", "mtllib", "map_Kd"]))
    name = draw(st.sampled_from(FOLDERS)) + draw(st.sampled_from(STEMS[slot] + ("passwd", "", "..", "x\x00.bin")))
    if slot in ("buffer", "image") and draw(st.booleans()):
        encode = draw(st.lists(st.booleans(), min_size=len(name), max_size=len(name)))
        name = "".join(f"%{ord(c):02x}" if e and c in "./ab%" else c for c, e in zip(name, encode))
    return slot, name


def _lay_out(base: Path) -> None:
    for rel, data in LAYOUT.items():
        (base / rel).parent.mkdir(parents=True, exist_ok=True)
        (base / rel).write_bytes(data)
    for rel, target in LINKS.items():
        os.symlink(target, base / rel)


def _mesh(base: Path, slot: str, name: str) -> Path:
    """root/models/quad.gltf or quad.obj with the reference of `slot` spelt `name`."""
    models = base / "root" / "models"
    if slot in ("buffer", "image"):
        tree = json.loads(json.dumps(A.GLTF))
        (tree["buffers"][0] if slot == "buffer" else tree["images"][0])["uri"] = name
        (models / "quad.gltf").write_text(json.dumps(tree))
        return models / "quad.gltf"
    (models / "quad.obj").write_text(A.OBJ.replace("mtllib m.mtl", f"mtllib {name}") if slot == "mtllib" else A.OBJ)
    if slot == "map_Kd":
        (models / "m.mtl").write_text(A.MTL.replace("map_Kd tex.png", f"map_Kd {name}"))
    return models / "quad.obj"


def _inside(path: str, roots) -> bool:
    return any(path == r or path.startswith(r + os.sep) for r in roots)


def check_reference(base: Path, case) -> None:
    """Load the mesh whose reference is spelt as `case` says, with base/root as the root: as the oracle says."""
    from vdmbake.assets.meshes import load_mesh_file
    from vdmbake.assets.references import reached_files

    slot, name = case
    name = name.replace("{root}", str(base / "root")).replace("{base}", str(base))
    _lay_out(base)
    mesh = _mesh(base, slot, name)
    roots = [os.path.realpath(base / "root"), os.path.realpath(mesh.parent)]
    spelt = unquote(name) if slot in ("buffer", "image") else name
    resolved = os.path.realpath(os.path.join(mesh.parent, spelt)) if "\x00" not in spelt else None
    with time_limit(20, "load_mesh_file"):
        try:
            files = reached_files(mesh, str(mesh), True, base / "root")
            load_mesh_file(mesh, root=base / "root")
        except InputError as e:
            one_line(e)
            _event("refused")
            assert resolved is None or _inside(resolved, roots) or "outside" in str(e), (
                f"{name!r} resolves outside the root to {resolved}, and was refused for another reason: {e}")
            assert not (resolved in {os.path.realpath(base / g) for g in GOOD[slot]} and os.path.isfile(resolved)), (
                f"{name!r} names a good file inside the root ({resolved}) and was refused: {e}")
            return
    _event("loaded")
    assert resolved is not None and _inside(resolved, roots), f"{name!r} resolves to {resolved}, outside, and loaded"
    for f in files.values():
        assert _inside(os.path.realpath(f.path), roots), f"read {f.path}, outside the root"


# -------------------------------------------------------------------------------------------- glTF node trees

DAMAGE = ["none", "none", "none", "repeat", "cycle", "self", "two parents", "out of range", "root twice"]


@st.composite
def node_tree_case(draw) -> dict:
    """A glTF of the quad placed by a random forest of up to 12 nodes (each node's parent an earlier node or none),
    perhaps damaged once (a child named twice, a cycle, a node its own child, a node of two parents, an index out of
    range, a root named twice), some nodes with EXT_mesh_gpu_instancing (1 to 4 copies), the extension required or
    not, sometimes an unknown one required; the roots in one scene, in the second of two, or in no scene."""
    n = draw(st.integers(1, 12))
    tree = json.loads(json.dumps(A.GLTF))
    del tree["materials"], tree["textures"], tree["images"], tree["meshes"][0]["primitives"][0]["material"]
    copies = np.array([[0, 0, 0], [0, 10, 0], [0, 20, 0], [0, 30, 0]], "<f4").tobytes()
    tree["buffers"][0]["byteLength"] += len(copies)
    tree["bufferViews"].append({"buffer": 0, "byteOffset": len(A.BIN), "byteLength": len(copies)})
    tree["accessors"] += [{"bufferView": 3, "componentType": 5126, "count": k, "type": "VEC3"} for k in (1, 2, 3, 4)]
    nodes = [{"translation": [3.0 * i, 0, 0], "children": []} for i in range(n)]
    roots = []
    for i in range(n):
        parent = draw(st.integers(-1, i - 1))
        (roots if parent < 0 else nodes[parent]["children"]).append(i)
        if draw(st.integers(0, 2)):
            nodes[i]["mesh"] = 0
            if draw(st.integers(0, 3)) == 0:
                nodes[i]["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 3 + draw(
                    st.integers(0, 3))}}}
    damage, i, j = draw(st.sampled_from(DAMAGE)), draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1))
    if damage == "repeat" and nodes[i]["children"]:
        nodes[i]["children"].append(nodes[i]["children"][0])
    elif damage in ("cycle", "self"):          # an ancestor of i (or i itself) named as i's child
        nodes[i]["children"].append(i if damage == "self" else min(i, j))
    elif damage == "two parents" and i != j:
        nodes[i]["children"].append(j)
    elif damage == "out of range":
        nodes[i]["children"].append(draw(st.sampled_from([-1, n, 2**31])))
    elif damage == "root twice":
        roots.append(roots[0])
    tree["nodes"] = nodes
    scenes = draw(st.sampled_from(["one", "one", "none", "second"]))
    if scenes == "none":
        del tree["scenes"], tree["scene"]
    else:
        tree["scenes"] = [{"nodes": roots}] if scenes == "one" else [{"nodes": []}, {"nodes": roots}]
        tree["scene"] = 0 if scenes == "one" else 1
    tree["extensionsRequired"] = draw(st.sampled_from([[], [], ["EXT_mesh_gpu_instancing"], ["KHR_x_unknown"]]))
    return {"tree": tree, "bin": A.BIN + copies}


def _placed(tree: dict) -> int | None:
    """The copies of the quad the tree places (glTF 2.0 §3.5: disjoint trees from the default scene's roots, or the
    nodes no node names as a child), or None where the file is to be refused."""
    if any(e != "EXT_mesh_gpu_instancing" for e in tree["extensionsRequired"]):
        return None
    nodes = tree["nodes"]
    if "scenes" in tree:
        roots = tree["scenes"][tree["scene"]]["nodes"]
    else:
        named = {c for node in nodes for c in node["children"]}
        roots = [i for i in range(len(nodes)) if i not in named]
    seen, todo, placed = set(), list(roots), 0
    while todo:
        i = todo.pop()
        if not 0 <= i < len(nodes) or i in seen:
            return None
        seen.add(i)
        node = nodes[i]
        if "mesh" in node:
            ext = node.get("extensions", {}).get("EXT_mesh_gpu_instancing")
            placed += tree["accessors"][ext["attributes"]["TRANSLATION"]]["count"] if ext else 1
        todo += node["children"]
    return placed or None


def check_node_tree(folder: Path, case: dict) -> None:
    """load_mesh_file on the tree: refused (one line) where the oracle refuses it, else two triangles per copy."""
    from vdmbake.assets.meshes import load_mesh_file

    (folder / "quad.bin").write_bytes(case["bin"])
    (folder / "quad.gltf").write_text(json.dumps(case["tree"]))
    want = _placed(case["tree"])
    with time_limit(20, "load_mesh_file"):
        try:
            mesh = load_mesh_file(folder / "quad.gltf", warn=lambda m: None)
        except InputError as e:
            one_line(e)
            _event("refused")
            assert want is None, f"a tree placing {want} copies was refused: {e}"
            return
    _event(f"{want} copies")
    assert want is not None, "a file to be refused loaded"
    assert len(mesh.faces) == 2 * want, (len(mesh.faces), want)


# --------------------------------------------------------------------------- compressed glTF (Draco, meshopt)

@st.composite
def compressed_case(draw) -> dict:
    """The grid of tests/gltf_files.py compressed by Draco (a GLB or not) or meshopt, up to 3 bytes of its streams
    changed, a Draco stream maybe cut short, and maybe one declaration of its JSON changed."""
    codec = draw(st.sampled_from(["draco", "meshopt"]))
    stream = st.tuples(st.integers(0, 10 ** 6), st.integers(0, 255))
    keys = ["count", "componentType", "type", "id"] if codec == "draco" else ["count", "byteStride", "mode", "filter"]
    return {"codec": codec, "glb": codec == "draco" and draw(st.booleans()),
            "bytes": draw(st.lists(stream, max_size=3)),
            "cut": draw(st.none() | st.integers(0, 10 ** 6)),
            "declare": draw(st.none() | st.tuples(st.sampled_from(keys), st.integers(0, 5), st.sampled_from(
                [0, 1, 2, 4, 15, 17, 54, 5121, 5126, "VEC2", "VEC4", "ATTRIBUTES", "TRIANGLES", "OCTAHEDRAL",
                 "QUATERNION", 2 ** 40, -1])))}


def check_compressed(folder: Path, case: dict) -> None:
    """load_mesh_file on the spoilt grid: refused in one line, or at most the grid's 16 vertices and 18 triangles
    with finite positions."""
    import base64

    from gltf_files import draco_grid, meshopt_grid

    from vdmbake.assets.meshes import load_mesh_file

    def spoil(tree, ext):
        if case["codec"] == "meshopt":
            ext = ext[(case["declare"] or ("", 0))[1] % len(ext)]
        elif case["cut"] is not None:
            view = tree["bufferViews"][ext["bufferView"]]
            view["byteLength"] = case["cut"] % (view["byteLength"] + 1)
        if case["declare"] is not None:
            key, which, value = case["declare"]
            if key == "id":
                ext["attributes"][sorted(ext["attributes"])[which % 4]] = value
            elif case["codec"] == "meshopt":
                ext[key] = value
            else:
                tree["accessors"][which % len(tree["accessors"])][key] = value

    if case["codec"] == "meshopt":
        path = meshopt_grid(folder / "m.gltf", spoil=spoil)
    else:
        path = draco_grid(folder / ("d.glb" if case["glb"] else "d.gltf"), glb=case["glb"], spoil=spoil)
    if case["bytes"]:   # the compressed bytes changed in place: the GLB's binary chunk, or buffer 0's data: URI
        data = bytearray(path.read_bytes())
        if case["glb"]:
            at0 = 28 + int.from_bytes(data[12:16], "little")
            for at, value in case["bytes"]:
                data[at0 + at % (len(data) - at0)] = value
        else:
            tree = json.loads(data)
            blob = bytearray(base64.b64decode(tree["buffers"][0]["uri"].partition(",")[2]))
            for at, value in case["bytes"]:
                blob[at % len(blob)] = value
            tree["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
            data = json.dumps(tree).encode()
        path.write_bytes(bytes(data))
    with time_limit(20, "load_mesh_file"):
        try:
            mesh = load_mesh_file(path, warn=lambda m: None)
        except InputError as e:
            one_line(e)
            _event(f"{case['codec']} refused")
            return
    _event(f"{case['codec']} loaded")
    assert len(mesh.vertices) <= 16 and len(mesh.faces) <= 18, (len(mesh.vertices), len(mesh.faces))
    assert np.isfinite(mesh.vertices).all()
