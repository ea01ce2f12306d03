"""Issue 43: published glTF files that were refused now read. Each test builds its tiny file here (no download) and
fails on main at 20e813d: a missing picture the renderer never reads (BoomBox's occlusion), KHR_texture_transform
and TEXCOORD_1 on the base colour (TextureTransformTest), Draco-compressed geometry (KHR_draco_mesh_compression)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from tests.test_asset_references import gltf_asset
from tests.test_gltf_read import QUAD, UV, Gltf
from vdmbake.assets.meshes import load_mesh_file
from vdmbake.common import texture
from vdmbake.errors import InputError


def _with(path, change):
    tree = json.loads(path.read_text())
    change(tree)
    path.write_text(json.dumps(tree))
    return path


# ------------------------------------------------------------------ 4. only what is drawn is required

def _unread_picture(tree, uri="missing_occlusion.png"):
    """BoomBox-like: the material's occlusion, metallic-roughness and normal pictures name a file that is not there."""
    tree["images"].append({"uri": uri})
    tree["textures"].append({"source": 1})
    m = tree["materials"][0]
    m["occlusionTexture"] = m["normalTexture"] = {"index": 1}
    m["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {"index": 1}


def test_a_missing_picture_that_is_not_drawn_is_a_warning(tmp_path):
    _with(tmp_path / gltf_asset(tmp_path), _unread_picture)
    heard = []
    m = load_mesh_file(tmp_path / "quad.gltf", warn=heard.append)
    assert m.texture is not None
    assert len(heard) == 1 and "image 1 'missing_occlusion.png'" in heard[0] and "not found" in heard[0], heard


def test_a_present_picture_that_is_not_drawn_is_not_read(tmp_path):
    _with(tmp_path / gltf_asset(tmp_path), lambda t: _unread_picture(t, "occlusion.png"))
    (tmp_path / "occlusion.png").write_bytes(b"not a picture")   # never opened, so never refused
    heard = []
    assert load_mesh_file(tmp_path / "quad.gltf", warn=heard.append).texture is not None
    assert heard == []


def test_a_missing_base_colour_picture_is_still_refused(tmp_path):
    gltf_asset(tmp_path)
    (tmp_path / "tex.png").unlink()
    with pytest.raises(InputError, match="tex.png"):
        load_mesh_file(tmp_path / "quad.gltf")
