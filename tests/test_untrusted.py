"""Assets are untrusted input (issue 42): the files a mesh file names resolve inside the scene's folder or the mesh
file's own (one rule for every format: references.confined), each read once; bounded work per file; glTF's required
extensions honoured or refused (§3.12) and GLB headers checked; GL limits checked before drawing; vdmexport's
lod.json typed; a lone far copy refused. Each test failed before the fix (exit 0, a traceback, or work without a
bound); the assets are written here, a few hundred bytes each."""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from test_asset_references import QUAD_UV, QUAD_V, _png, gltf_asset, obj_asset, scene
from test_bad_input import assert_input_error, bake, write_scene
from vdmbake.assets import references
from vdmbake.assets.meshes import load_mesh_file
from vdmbake.errors import InputError


def _with(path: Path, edit) -> Path:
    """The glTF at `path` with its JSON tree changed by `edit` (in place)."""
    tree = json.loads(path.read_text())
    edit(tree)
    path.write_text(json.dumps(tree))
    return path


def _buffer_uri(uri: str):
    def edit(tree):
        tree["buffers"][0]["uri"] = uri
    return edit


# --- one rule for file references -------------------------------------------------------------------------------

def _outside(tmp_path: Path) -> Path:
    """tmp/X/secret.bin (the quad's own bytes, so a read would bake) beside the scene's folder tmp/scene."""
    (tmp_path / "X").mkdir()
    (tmp_path / "scene").mkdir()
    gltf_asset(tmp_path / "X")
    os.rename(tmp_path / "X" / "quad.bin", tmp_path / "X" / "secret.bin")
    gltf_asset(tmp_path / "scene")
    return tmp_path / "scene"


@pytest.mark.parametrize("uri", ["/etc/passwd", "../X/secret.bin", "%2e%2e%2fX%2fsecret.bin", "link.bin"])
def test_a_buffer_outside_the_scene_is_refused(tmp_path, uri):
    """Failed before: each was read and baked with exit 0 (/etc/passwd as vertex colours)."""
    d = _outside(tmp_path)
    (d / "link.bin").symlink_to(tmp_path / "X" / "secret.bin")
    _with(d / "quad.gltf", _buffer_uri(uri))
    with pytest.raises(InputError, match=r"quad.gltf: the buffer '.*' resolves to .*, outside .*scene; a mesh file "
                                         "may name only files inside the scene's folder or its own"):
        load_mesh_file(d / "quad.gltf", root=d)


def test_the_bake_refuses_passwd_as_vertex_colours(tmp_path):
    """The finding as a hostile user made it: /etc/passwd read as a normalized COLOR_0 accessor."""
    d = _outside(tmp_path)

    def edit(tree):
        tree["buffers"].append({"uri": "/etc/passwd", "byteLength": 12})
        tree["bufferViews"].append({"buffer": 1, "byteLength": 12})
        tree["accessors"].append({"bufferView": 3, "componentType": 5121, "normalized": True, "count": 4,
                                  "type": "VEC3"})
        tree["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = 3
    _with(d / "quad.gltf", edit)
    out = d / "out.bundle"
    assert_input_error(bake(write_scene(d, scene("quad.gltf")), "-o", out),
                       ["the buffer '/etc/passwd' resolves to /etc/passwd, outside"], out)


@pytest.mark.parametrize("where", ["mtllib", "map_Kd"])
def test_an_obj_reference_outside_is_refused(tmp_path, where):
    """Failed before: `mtllib ../outside/o.mtl` and its map_Kd were read like the glTF's buffers."""
    (tmp_path / "outside").mkdir()
    (tmp_path / "scene").mkdir()
    d = tmp_path / "scene"
    obj_asset(d)
    _png(tmp_path / "outside" / "t.png")
    if where == "mtllib":
        (tmp_path / "outside" / "o.mtl").write_text("newmtl mat\nKd 1 1 1\nmap_Kd t.png\n")
        (d / "quad.obj").write_text((d / "quad.obj").read_text().replace("mtllib m.mtl", "mtllib ../outside/o.mtl"))
    else:
        (d / "m.mtl").write_text("newmtl mat\nKd 1 1 1\nmap_Kd ../outside/t.png\n")
    shown = "the material library '../outside/o.mtl'" if where == "mtllib" else "the texture '../outside/t.png'"
    with pytest.raises(InputError, match=f"{shown} resolves to .*outside"):
        load_mesh_file(d / "quad.obj", root=d)


def _sibling(tmp_path: Path) -> Path:
    """scene/models/quad.gltf whose picture sits in scene/textures: a sibling folder of the scene's tree."""
    models, textures = tmp_path / "models", tmp_path / "textures"
    models.mkdir()
    textures.mkdir()
    gltf_asset(models)
    os.rename(models / "tex.png", textures / "tex.png")
    return _with(models / "quad.gltf", lambda tree: tree["images"][0].update(uri="../textures/tex.png"))


def test_textures_in_a_sibling_folder_of_the_scene_still_load(tmp_path):
    m = load_mesh_file(_sibling(tmp_path), root=tmp_path)
    assert m.texture is not None and m.texture.shape == (4, 4, 3)


def test_the_default_root_is_the_mesh_files_folder(tmp_path):
    with pytest.raises(InputError, match="the texture '../textures/tex.png' resolves to .*outside .*models;"):
        load_mesh_file(_sibling(tmp_path))


def test_one_file_in_several_spellings_is_read_once(tmp_path):
    """Failed before: a buffer named in five spellings was read five times (1.2 GB: MemoryError at 4.6 GB)."""
    gltf_asset(tmp_path)

    def edit(tree):
        tree["buffers"] = [{"uri": u, "byteLength": 92} for u in ("quad.bin", "./quad.bin", "%71uad.bin",
                                                                  "sub/../quad.bin", "quad%2ebin")]
        for k, view in enumerate(tree["bufferViews"]):
            view["buffer"] = k
    (tmp_path / "sub").mkdir()
    _with(tmp_path / "quad.gltf", edit)
    files = references.reached_files(tmp_path / "quad.gltf", "quad.gltf")
    buffers = [f.data for chain, f in files.items() if f.what == "buffer"]
    assert len(buffers) == 5 and all(b is buffers[0] for b in buffers)
    assert len(load_mesh_file(tmp_path / "quad.gltf").faces) == 2


def test_the_files_reached_are_bounded_together(tmp_path, monkeypatch):
    gltf_asset(tmp_path)
    size = sum(len((tmp_path / n).read_bytes()) for n in ("quad.gltf", "quad.bin"))
    monkeypatch.setattr(references, "MAX_FILE_BYTES", size + 10)
    with pytest.raises(InputError, match=r"the texture named by quad.gltf \(the files a mesh file reaches hold at "
                                         rf"most {size + 10} bytes together, {size} read before it\) has"):
        references.reached_files(tmp_path / "quad.gltf", "quad.gltf")


# --- GLB headers -----------------------------------------------------------------------------------------------

def _glb(tmp_path: Path) -> bytes:
    """The quad as a GLB: its JSON chunk (padded with spaces) and its BIN chunk."""
    gltf_asset(tmp_path)
    tree = json.loads((tmp_path / "quad.gltf").read_text())
    data = (tmp_path / "quad.bin").read_bytes()
    del tree["buffers"][0]["uri"], tree["materials"], tree["textures"], tree["images"]
    del tree["meshes"][0]["primitives"][0]["material"]
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    data += b"\0" * (-len(data) % 4)
    body = (len(text).to_bytes(4, "little") + b"JSON" + text + len(data).to_bytes(4, "little") + b"BIN\0" + data)
    return b"glTF" + (2).to_bytes(4, "little") + (12 + len(body)).to_bytes(4, "little") + body


@pytest.mark.parametrize("spoil, match", [
    (lambda b: b"gltf" + b[4:], r"magic b'gltf'"),
    (lambda b: b[:4] + (1).to_bytes(4, "little") + b[8:], "version 1"),
    (lambda b: b + b"\0\0\0\0", r"a length of \d+ bytes where the file has \d+"),
    (lambda b: b[:-4], r"a length of \d+ bytes where the file has \d+"),
    (lambda b: b[:8] + (len(b) - 4).to_bytes(4, "little") + b[12:-4], r"GLB chunk 1 of \d+ bytes at byte \d+ reaches "
                                                                       "past the file's"),
    (lambda b: b[:16] + b"JSOX" + b[20:], r"GLB chunks \[b'JSOX', b'BIN\\x00'\]"),
])
def test_glb_headers_are_checked(tmp_path, spoil, match):
    """Failed before: magic, version and chunk lengths were not read (a GLB of version 1 baked)."""
    good = _glb(tmp_path)
    (tmp_path / "q.glb").write_bytes(good)
    assert len(load_mesh_file(tmp_path / "q.glb").faces) == 2
    (tmp_path / "q.glb").write_bytes(spoil(good))
    with pytest.raises(InputError, match=match):
        load_mesh_file(tmp_path / "q.glb")
