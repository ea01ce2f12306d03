"""Files a mesh file reaches (issue 21): an OBJ's `mtllib` and its MTL's `map_Kd`, a glTF's buffer and image
URIs. Each is read with the checks of the scene's own files (regular file, size bound: a FIFO is refused at
once), goes into the input hash (an edit re-bakes), and a texture that cannot be used is an error naming it
and the file that named it, unless the object says `textures = "ignore"`. Assets are written here, tiny."""
from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from helpers import assert_input_error, bake, gltf_asset, obj_asset, png, scene, write_scene

BIN = Path(sys.executable).parent


def _png_header(path: Path, width: int, height: int) -> None:
    """A PNG of just its header (no pixels): what a reader sees before it decodes anything."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    chunk = lambda kind, data: (struct.pack(">I", len(data)) + kind + data  # noqa: E731
                                + struct.pack(">I", zlib.crc32(kind + data)))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))


def manifest(out: Path) -> dict:
    return json.loads((out / "manifest.json").read_text())


# ------------------------------------------------------------------------------- the input hash

def _edit_texture(d: Path) -> None:
    png(d / "tex.png", (20, 200, 40))


def _edit_mtl(d: Path) -> None:
    (d / "m.mtl").write_text((d / "m.mtl").read_text() + "Ns 10\n")


def _edit_bin(d: Path) -> None:
    data = bytearray((d / "quad.bin").read_bytes())
    data[44:48] = struct.pack("<f", 0.2)          # the last vertex's z
    (d / "quad.bin").write_bytes(bytes(data))


EDITS = {
    "obj_map_Kd": (obj_asset, _edit_texture, "quad.obj > m.mtl > tex.png"),
    "obj_mtl": (obj_asset, _edit_mtl, "quad.obj > m.mtl"),
    "gltf_bin": (gltf_asset, _edit_bin, "quad.gltf > quad.bin"),
    "gltf_image": (gltf_asset, _edit_texture, "quad.gltf > tex.png"),
}


@pytest.mark.parametrize("case", list(EDITS))
def test_editing_a_referenced_file_rebakes(tmp_path, case):
    make, edit, key = EDITS[case]
    path, out = write_scene(tmp_path, scene(make(tmp_path))), tmp_path / "x.bundle"
    assert bake(path, "-o", out).exit_code == 0
    before = manifest(out)
    assert key in before["inputs"], before["inputs"]
    assert "albedo_map" in before["objects"]["thing"]
    assert "up to date" in bake(path, "-o", out).output
    edit(tmp_path)
    r = bake(path, "-o", out)
    assert r.exit_code == 0 and "up to date" not in r.output and "inputs or settings changed" in r.output, r.output
    assert manifest(out)["inputs"][key] != before["inputs"][key]


# --------------------------------------------------------------------------- unusable textures

def _missing(d: Path) -> None:
    (d / "tex.png").unlink()


def _garbage(d: Path) -> None:
    (d / "tex.png").write_bytes(bytes(range(256)) * 4)


def _empty(d: Path) -> None:
    (d / "tex.png").write_bytes(b"")


def _directory(d: Path) -> None:
    (d / "tex.png").unlink()
    (d / "tex.png").mkdir()


def _zero(d: Path) -> None:
    _png_header(d / "tex.png", 0, 0)


def _huge_header(d: Path) -> None:
    _png_header(d / "tex.png", 100000, 100000)


def _over_the_bound(d: Path) -> None:
    _png_header(d / "tex.png", 12000, 12000)     # the 0.4 MB PNG of the finding decoded to 432 MB


def _truncated(d: Path) -> None:
    Image.fromarray(np.random.default_rng(0).integers(0, 256, (64, 64, 3), np.uint8)).save(d / "tex.png")
    data = (d / "tex.png").read_bytes()
    (d / "tex.png").write_bytes(data[:len(data) // 2])


BAD_TEXTURES = {
    "missing": (_missing, "not found"),
    "garbage": (_garbage, "cannot read the picture"),
    "empty": (_empty, "cannot read the picture"),
    "directory": (_directory, "not a regular file"),
    "zero_size": (_zero, "cannot read the picture"),
    "huge_header": (_huge_header, "100000 x 100000"),
    "over_the_bound": (_over_the_bound, "12000 x 12000"),
    "truncated": (_truncated, "cannot read the picture"),
}


@pytest.mark.parametrize("case", list(BAD_TEXTURES))
@pytest.mark.parametrize("asset", ["obj", "gltf"])
def test_unusable_texture_is_an_error_naming_both_files(tmp_path, case, asset):
    damage, needle = BAD_TEXTURES[case]
    mesh, referrer = (obj_asset(tmp_path), "m.mtl") if asset == "obj" else (gltf_asset(tmp_path), "quad.gltf")
    damage(tmp_path)
    out = tmp_path / "x.bundle"
    assert_input_error(bake(write_scene(tmp_path, scene(mesh)), "-o", out), ["tex.png", referrer, needle], out)


def test_gltf_texture_index_out_of_range(tmp_path):
    out = tmp_path / "x.bundle"
    assert_input_error(bake(write_scene(tmp_path, scene(gltf_asset(tmp_path, texture_index=3))), "-o", out),
                       ["quad.gltf", "texture 3"], out)


def test_texture_name_with_control_characters_stays_one_line(tmp_path):
    out = tmp_path / "x.bundle"
    mesh = obj_asset(tmp_path, texture_name="t\x1b[31mx.png")
    assert_input_error(bake(write_scene(tmp_path, scene(mesh)), "-o", out), ["t\\x1b[31mx.png", "m.mtl"], out)


@pytest.mark.parametrize("asset", ["obj", "gltf"])
def test_textures_ignore_bakes_untextured(tmp_path, asset):
    mesh = obj_asset(tmp_path) if asset == "obj" else gltf_asset(tmp_path)
    _garbage(tmp_path)
    out = tmp_path / "x.bundle"
    r = bake(write_scene(tmp_path, scene(mesh, 'textures = "ignore"\n')), "-o", out)
    assert r.exit_code == 0, r.output
    m = manifest(out)
    assert "albedo_map" not in m["objects"]["thing"]
    assert not any(k.endswith("tex.png") for k in m["inputs"]), m["inputs"]


# -------------------------------------------------------------------------- FIFOs through references

def _fifo(path: Path) -> None:
    if path.exists():
        path.unlink()
    os.mkfifo(path)


FIFOS = {
    "mtllib": (obj_asset, "m.mtl", "quad.obj"),
    "map_Kd": (obj_asset, "tex.png", "m.mtl"),
    "gltf_buffer": (gltf_asset, "quad.bin", "quad.gltf"),
    "gltf_image": (gltf_asset, "tex.png", "quad.gltf"),
}


@pytest.mark.parametrize("case", list(FIFOS))
def test_fifo_through_a_reference_is_refused_at_once(tmp_path, case):
    make, fifo, referrer = FIFOS[case]
    path, out = write_scene(tmp_path, scene(make(tmp_path))), tmp_path / "x.bundle"
    _fifo(tmp_path / fifo)
    try:
        r = subprocess.run([str(BIN / "vdmbake"), str(path), "-o", str(out)], capture_output=True, text=True,
                           timeout=30)
    except subprocess.TimeoutExpired:
        pytest.fail(f"vdmbake blocked on the FIFO {fifo}")
    assert r.returncode == 2, r.stderr[-2000:]
    assert "Traceback" not in r.stderr and "not a regular file" in r.stderr
    assert fifo in r.stderr and referrer in r.stderr
    assert not out.exists()


# ------------------------------------------------------------------------------------------ UVs

@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_non_finite_uv_on_a_textured_mesh(tmp_path, bad):
    out = tmp_path / "x.bundle"
    mesh = obj_asset(tmp_path, uv=[[0, 0], [bad, 0], [0, 1], [1, 1]])
    assert_input_error(bake(write_scene(tmp_path, scene(mesh)), "-o", out), ["quad.obj", "texture coordinates"], out)
