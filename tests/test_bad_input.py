"""Bad input: exit code 2, one clear paragraph on stderr naming the file/key/value, no traceback,
and nothing half-written left behind (no -o target, no hidden `.NAME.tmp-*` sibling)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from vdmbake.bundle.directory import FORMAT_VERSION

from helpers import assert_input_error, bake, leftovers, render, write_scene
from scenes import BALL, CAMERA, GOOD_SCENE, RENDER

def mesh_object(path: str) -> str:
    return f"""
[[objects]]
name = "thing"
mesh = "{path}"
techniques = {{ mesh = {{}} }}
"""


@pytest.fixture(scope="module")
def baked(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("baked")
    scene = write_scene(d, GOOD_SCENE)
    out = d / "good.bundle"
    r = bake(scene, "-o", out)
    assert r.exit_code == 0, r.output
    return out


@pytest.fixture
def bundle(baked, tmp_path) -> Path:
    """A private copy of a good bundle, free to be damaged."""
    dst = tmp_path / "in.bundle"
    shutil.copytree(baked, dst)
    return dst


# ----------------------------------------------------------------------------- vdmbake: the scene

def test_scene_file_missing(tmp_path):
    out = tmp_path / "x.bundle"
    r = bake(tmp_path / "no_such_scene.toml", "-o", out)
    assert_input_error(r, ["no_such_scene.toml", "not found"], out)


def test_malformed_toml(tmp_path):
    scene = write_scene(tmp_path, "[render\nresolution = [32, 32]\n", "broken.toml")
    out = tmp_path / "x.bundle"
    assert_input_error(bake(scene, "-o", out), ["broken.toml", "malformed TOML", "line 1"], out)


SCENE_CASES = {
    "unknown_top_level_key": ("colour_space = 'srgb'\n" + GOOD_SCENE, ["'colour_space'", "top level"]),
    "unknown_render_key": (RENDER + "bogus_knob = 3\n" + CAMERA + BALL, ["render.bogus_knob", "allowed keys"]),
    "unknown_technique": (GOOD_SCENE.replace("{ mesh = {} }", "{ mesh = {}, hologram = {} }"),
                          ["'hologram'", "known techniques"]),
    "resolution_zero": (GOOD_SCENE.replace("[32, 32]", "[0, 32]"), ["render.resolution", "[0, 32]"]),
    "resolution_huge": (GOOD_SCENE.replace("[32, 32]", "[100000, 100000]"),
                        ["render.resolution", "[100000, 100000]", "8192"]),
    "mesh_and_primitive": (GOOD_SCENE.replace('primitive = "sphere"', 'primitive = "sphere"\nmesh = "a.obj"'),
                           ["'ball'", "exactly one source"]),
    "neither_mesh_nor_primitive": (RENDER + CAMERA + '[[objects]]\nname = "ball"\ntechniques = { mesh = {} }\n',
                                   ["'ball'", "exactly one source"]),
    "duplicate_object_names": (GOOD_SCENE + BALL, ["two objects are named 'ball'"]),
    "bad_primitive_name": (GOOD_SCENE.replace('"sphere"', '"icosahedron"'),
                           ["objects[0].primitive", "'icosahedron'", "'sphere'"]),
    "vdm_refine_negative": (GOOD_SCENE.replace("{ mesh = {} }", "{ vdm = { k = [8], refine = [0, -1] } }")
                            + '[objects.mesostructure]\nheight = "bricks"\n',
                            ["refine", "[0, -1]", "an integer in [0, 64]"]),
}


@pytest.mark.parametrize("case", list(SCENE_CASES))
def test_bad_scene(tmp_path, case):
    text, needles = SCENE_CASES[case]
    scene = write_scene(tmp_path, text)
    out = tmp_path / "x.bundle"
    assert_input_error(bake(scene, "-o", out), ["scene.toml", *needles], out)


# ------------------------------------------------------------------------------ vdmbake: the mesh

def _missing(d: Path) -> str:
    return "missing.obj"


def _garbage(d: Path) -> str:
    (d / "x.ply").write_bytes(bytes(range(256)) * 8)
    return "x.ply"


def _empty(d: Path) -> str:
    (d / "empty.obj").write_text("# three vertices, no faces\nv 0 0 0\nv 1 0 0\nv 0 1 0\n")
    return "empty.obj"


def _nan(d: Path) -> str:
    (d / "nan.obj").write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n")
    return "nan.obj"


def _no_package(d: Path) -> str:
    return "pkg:no_such_package_vdm/meshes/bunny.ply"


MESH_CASES = {
    "missing": (_missing, ["missing.obj", "file not found"]),
    "garbage": (_garbage, ["x.ply", "cannot read the mesh"]),
    "empty": (_empty, ["empty.obj", "empty", "0 faces"]),
    "nan_vertex": (_nan, ["nan.obj", "NaN", "vertex 0"]),
    "missing_package": (_no_package, ["no_such_package_vdm", "not installed"]),
}


@pytest.mark.parametrize("case", list(MESH_CASES))
def test_bad_mesh(tmp_path, case):
    make, needles = MESH_CASES[case]
    spec = make(tmp_path)
    scene = write_scene(tmp_path, RENDER + CAMERA + mesh_object(spec))
    out = tmp_path / "x.bundle"
    assert_input_error(bake(scene, "-o", out), needles, out)


# ---------------------------------------------------------------------------- vdmbake: the output

def test_output_under_a_regular_file(tmp_path):
    scene = write_scene(tmp_path, GOOD_SCENE)
    afile = tmp_path / "afile"
    afile.write_text("precious\n")
    out = afile / "x.bundle"
    assert_input_error(bake(scene, "-o", out), ["x.bundle", "cannot write the bundle"])
    assert afile.is_file() and afile.read_text() == "precious\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "scene.toml"]


def test_output_is_a_regular_file(tmp_path):
    scene = write_scene(tmp_path, GOOD_SCENE)
    out = tmp_path / "x.bundle"
    out.write_text("precious\n")
    assert_input_error(bake(scene, "-o", out), ["x.bundle", "not a bundle"])
    assert out.read_text() == "precious\n"
    assert leftovers(out) == []


# -------------------------------------------------------------------------------------- vdmrender

def test_render_not_a_bundle(tmp_path):
    d = tmp_path / "plain"
    d.mkdir()
    (d / "notes.txt").write_text("hello\n")
    out = tmp_path / "r"
    assert_input_error(render(d, "-o", out), ["plain", "not a bundle", "manifest.json"], out)


def test_render_future_format_version(bundle, tmp_path):
    mf = bundle / "manifest.json"
    m = json.loads(mf.read_text())
    m["format_version"] = 999
    mf.write_text(json.dumps(m))
    out = tmp_path / "r"
    assert_input_error(render(bundle, "-o", out), ["manifest.json", "version 999", f"version {FORMAT_VERSION}"], out)


def test_render_corrupted_part(bundle, tmp_path, gl_context_ok):
    part = bundle / "objects" / "ball" / "mesh.ply"
    data = bytearray(part.read_bytes())
    data[-1] ^= 0x01                      # a face index in the binary body: still a well-formed PLY
    part.write_bytes(bytes(data))
    out = tmp_path / "r"
    assert_input_error(render(bundle, "-o", out), ["mesh.ply", "checksum mismatch"], out)


def test_render_part_path_leaves_bundle(bundle, tmp_path):
    mf = bundle / "manifest.json"
    m = json.loads(mf.read_text())
    rel = m["objects"]["ball"]["mesh"]
    m["parts"] = {("../../etc/passwd" if k == rel else k): v for k, v in m["parts"].items()}
    m["objects"]["ball"]["mesh"] = "../../etc/passwd"
    mf.write_text(json.dumps(m))
    out = tmp_path / "r"
    assert_input_error(render(bundle, "-o", out), ["'../../etc/passwd'", "leaves the bundle"], out)


def _snapshot(d: Path) -> dict:
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def test_render_refuses_foreign_output_dir(bundle, tmp_path, gl_context_ok):
    out = tmp_path / "mywork"
    (out / "sub").mkdir(parents=True)
    (out / "thesis.tex").write_text("\\chapter{Results}\n")
    (out / "sub" / "data.bin").write_bytes(b"\x00\x01\x02")
    before = _snapshot(out)
    r = render(bundle, "-o", out)
    assert_input_error(r, ["mywork", "not a vdmrender output folder"])
    assert _snapshot(out) == before
    assert sorted(p.name for p in out.iterdir()) == ["sub", "thesis.tex"]
    assert leftovers(out) == []


def test_render_unknown_technique(bundle, tmp_path):
    out = tmp_path / "r"
    assert_input_error(render(bundle, "-o", out, "--technique", "unknown_name"),
                       ["'unknown_name'", "known techniques"], out)


def test_render_resolution_usage_error(bundle, tmp_path):
    out = tmp_path / "r"
    r = render(bundle, "-o", out, "--resolution", "0x10")
    assert r.exit_code == 2, r.output
    assert isinstance(r.exception, SystemExit)
    assert "Traceback" not in r.output
    assert "--resolution" in r.stderr and "0x10" in r.stderr
    assert not out.exists() and leftovers(out) == []
