"""Hardening (issue 14): a reproduction per finding, small and fast. Bad manifests, damaged parts and
scenes vdmrender could not draw end in exit 2 with one line naming the key or file; parts are read once
(regular files of the listed size) and parsed from the bytes hashed; signals clean up and exit 128+N."""
from __future__ import annotations

import copy
import json
import os
import shutil
import signal
import struct
from pathlib import Path

import numpy as np
import pytest

from vdmbake import exr, parts, ply
from vdmbake.bundle import Bundle
from vdmbake.errors import InputError

from test_bad_input import GOOD_SCENE, assert_input_error, bake, render, write_scene

COARSE_SCENE = GOOD_SCENE.replace("techniques = { mesh = {} }", "techniques = { mesh = {}, coarse = { ratios = [0.5] } }") + """
[[objects]]
name = "atoms"
spheres = [[0, 0, 0, 1], [1, 0, 0, 0.5]]
techniques = { impostor = {} }
"""
MESH = "objects/ball/mesh.ply"
NULL = object()   # mutate's result for a manifest that is JSON null


@pytest.fixture(scope="module")
def baked(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hard")
    out = d / "good.bundle"
    r = bake(write_scene(d, COARSE_SCENE), "-o", out)
    assert r.exit_code == 0, r.output
    return out


@pytest.fixture
def bundle(baked, tmp_path) -> Path:
    dst = tmp_path / "in.bundle"
    shutil.copytree(baked, dst)
    return dst


def rewrite(bundle: Path, mutate) -> None:
    """Replace the manifest by mutate(manifest) (or the manifest mutate changed in place)."""
    m = json.loads((bundle / "manifest.json").read_text())
    new = mutate(m)
    (bundle / "manifest.json").write_text(json.dumps(None if new is NULL else m if new is None else new))


def refused(bundle: Path, needles) -> None:
    with pytest.raises(InputError) as e:
        Bundle(bundle)
    msg = str(e.value)
    assert "\n" not in msg
    for n in [needles] if isinstance(needles, str) else needles:
        assert n in msg, msg


def put(path, value):
    def f(m):
        x = m
        for k in path[:-1]:
            x = x[k]
        if value is KeyError:
            del x[path[-1]]
        else:
            x[path[-1]] = value
    return f


# ------------------------------------------------------------------------------ the manifest's structure

MANIFEST_CASES = {
    "array": (lambda m: [], "JSON array"),
    "null": (lambda m: NULL, "JSON null"),
    "string": (lambda m: "x", "JSON string"),
    "format_version_true": (put(["format_version"], True), "version True"),
    "format_version_float": (put(["format_version"], 2.0), "version 2.0"),
    "no_objects": (put(["objects"], KeyError), "'objects'"),
    "no_parts": (put(["parts"], KeyError), "'parts'"),
    "no_scene": (put(["scene"], KeyError), "'scene'"),
    "parts_array": (put(["parts"], []), "'parts'"),
    "object_unlisted_part": (put(["objects", "ball", "mesh"], "objects/ball/nope.ply"), "'objects.ball.mesh'"),
    "object_missing": (put(["objects", "ball"], KeyError), "'objects'"),
    "object_part_int": (put(["objects", "ball", "mesh"], 3), "'objects.ball.mesh'"),
    "object_kind": (put(["objects", "ball", "kind"], "quadrics"), "'objects.ball.kind'"),
    "techniques_array": (put(["objects", "ball", "techniques"], []), "'objects.ball.techniques'"),
    "part_entry_string": (put(["parts", MESH], "x"), f"'parts.{MESH}'"),
    "part_sha_int": (put(["parts", MESH, "sha256"], 5), f"'parts.{MESH}.sha256'"),
    "part_kind_unknown": (put(["parts", MESH, "kind"], "teapot"), f"'parts.{MESH}.kind'"),
    "part_kind_other": (put(["parts", MESH, "kind"], "quadrics"), f"'parts.{MESH}.spheres'"),
    "part_bytes_missing": (put(["parts", MESH, "bytes"], KeyError), f"'parts.{MESH}.bytes'"),
    "part_faces_zero": (put(["parts", MESH, "faces"], 0), f"'parts.{MESH}.faces'"),
    "centre_nan": (put(["objects", "ball", "centre"], [float("nan"), 0, 0]), "'objects.ball.centre'"),
    "radius_zero": (put(["objects", "ball", "radius"], 0), "'objects.ball.radius'"),
    "radius_inf": (put(["objects", "ball", "radius"], float("inf")), "'objects.ball.radius'"),
    "coarse_ratio_not_baked": (lambda m: m["scene"]["objects"][0]["techniques"]["coarse"].update(ratios=[0.5, 0.25]),
                               "coarse@0.25"),
    "coarse_entry_empty": (put(["objects", "ball", "techniques", "coarse"], {}), "'objects.ball.techniques.coarse'"),
    "scene_object_extra": (lambda m: m["scene"]["objects"].append(dict(m["scene"]["objects"][0], name="ghost")),
                           "ghost"),
    "scene_bad_value": (lambda m: m["scene"]["objects"][0].update(name=7), "objects[0].name"),
}


@pytest.mark.parametrize("case", MANIFEST_CASES)
def test_manifest_validated_before_anything_else(bundle, case):
    mutate, needle = MANIFEST_CASES[case]
    rewrite(bundle, mutate)
    refused(bundle, needle)


def test_deeply_nested_manifest(bundle):
    (bundle / "manifest.json").write_text("[" * 100000 + "]" * 100000)
    refused(bundle, "unreadable manifest")


def test_bad_manifest_through_the_cli(bundle, tmp_path):
    rewrite(bundle, put(["objects", "ball", "centre"], [float("nan"), 0, 0]))
    out = tmp_path / "out"
    assert_input_error(render(bundle, "-o", out, "--no-flip"), ["objects.ball.centre"], out)


def test_mesostructure_size_changed(tmp_path):
    scene = GOOD_SCENE.replace("techniques = { mesh = {} }", 'mesostructure = { height = "bricks", size = 8 }\n'
                               "techniques = { bump = {} }")
    out = tmp_path / "m.bundle"
    assert bake(write_scene(tmp_path, scene), "-o", out).exit_code == 0
    rewrite(out, lambda m: m["scene"]["objects"][0]["mesostructure"].update(size=16))
    refused(out, "size")


# ------------------------------------------------------------------------------------------ the parts

def test_part_parsed_from_the_bytes_hashed(bundle, monkeypatch):
    """A re-bake swapping the part between its checksum and its parse cannot mix bundles: the part is
    read once and the very bytes hashed are parsed (the issue's 9.42 dLuv mix)."""
    b = Bundle(bundle)
    before = b.read(MESH, parts.MESH)
    unpack = parts.MESH.unpack

    def swap_then_unpack(data, meta, origin):
        (bundle / MESH).write_bytes(b"ply\nswapped by a concurrent bake\n")
        return unpack(data, meta, origin)

    monkeypatch.setattr(parts, "MESH", parts.PartKind("mesh", ".ply", parts.MESH.pack, swap_then_unpack, parts.MeshMeta))
    again = b.read(MESH, parts.MESH)
    assert np.array_equal(again.vertices, before.vertices) and np.array_equal(again.faces, before.faces)
    with pytest.raises(InputError, match="bytes where the manifest records"):   # the swap is seen on the next read
        b.read(MESH, parts.MESH)


def test_part_swapped_after_the_manifest_was_read(bundle, baked):
    """A whole bundle swapped in after the manifest was read: the parts no longer match it (exit 2),
    and the reference cache key is the checksum of the bytes actually parsed."""
    b = Bundle(bundle)
    data = (bundle / MESH).read_bytes()
    (bundle / MESH).write_bytes(data[:-12] + bytes(12))   # same size, other bytes
    with pytest.raises(InputError, match="checksum mismatch"):
        b.read(MESH, parts.MESH)


@pytest.fixture
def alarm():
    """Fail instead of hanging (a FIFO)."""
    signal.signal(signal.SIGALRM, lambda *a: pytest.fail("hung"))
    signal.alarm(10)
    yield
    signal.alarm(0)


def test_fifo_part_is_refused_without_blocking(bundle, alarm):
    (bundle / MESH).unlink()
    os.mkfifo(bundle / MESH)
    with pytest.raises(InputError, match="not a regular file"):
        Bundle(bundle).read(MESH, parts.MESH)


def test_fifo_scene_file_is_refused(tmp_path, alarm):
    os.mkfifo(tmp_path / "scene.toml")
    out = tmp_path / "x.bundle"
    assert_input_error(bake(tmp_path / "scene.toml", "-o", out), "not a regular file", out)


def test_huge_sparse_part_is_refused_before_reading(bundle):
    with open(bundle / MESH, "r+b") as f:
        f.truncate(64 << 30)       # sparse: no disk used
    with pytest.raises(InputError, match=f"{64 << 30} bytes where the manifest records"):
        Bundle(bundle).read(MESH, parts.MESH)


def _maps(size=8):
    n = np.zeros((size, size, 3), np.float32)
    n[..., 2] = 1
    return parts.MesostructureMaps(np.ones((size, size), np.float32), n)


def test_exr_header_claiming_a_huge_image():
    data, meta = parts.MESOSTRUCTURE.pack(_maps())
    i = data.index(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
    # 2^20 x 8 pixels from an 845-byte file (the binding opens it and would allocate the pixels)
    bad = data[:i + 8] + struct.pack("<ii", 2**20 - 1, 7) + data[i + 16:]
    with pytest.raises(InputError, match="unreadable EXR.*claim"):
        parts.MESOSTRUCTURE.unpack(bad, meta, "bad.exr")


@pytest.mark.parametrize("damage", ["truncated", "renamed", "nan", "size"])
def test_exr_contents_checked(damage):
    maps = _maps()
    meta = {"size": 8}
    if damage == "nan":
        maps.heights[3, 3] = np.nan
    if damage == "size":
        meta = {"size": 16}
    data, _ = parts.MESOSTRUCTURE.pack(maps)
    if damage == "truncated":
        data = data[: len(data) // 2]
    if damage == "renamed":
        data = data.replace(b"normal.X", b"normal.Q")
    with pytest.raises(InputError):
        parts.MESOSTRUCTURE.unpack(data, meta, "bad.exr")


@pytest.mark.parametrize("damage", ["index", "negative", "nan", "count"])
def test_ply_contents_checked(damage):
    from vdmbake import primitives
    from vdmbake.primitives import PRIMITIVES

    m = primitives.build("sphere", PRIMITIVES["sphere"][1]())
    meta = {"vertices": len(m.vertices), "faces": len(m.faces)}
    if damage == "index":
        m.faces[5, 1] = len(m.vertices) + 100
    if damage == "negative":
        m.faces[5, 1] = -1
    if damage == "nan":
        m.vertices[2, 0] = np.nan
    if damage == "count":
        meta["faces"] += 1
    with pytest.raises(InputError):
        parts.MESH.unpack(ply.to_bytes(m), meta, "bad.ply")
