"""The bundle: manifest and checksums, up-to-date checks, determinism, only the parts the
techniques need, atomic writes, safe part paths, and the PLY and EXR formats it uses."""
from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import vdmbake
import vdmbake.bake as bake_mod
import vdmbake.kernels.coarse as coarse_mod
from vdmbake.formats import exr, ply
from vdmbake.bundle import parts
from vdmbake.bundle.directory import FORMAT, FORMAT_VERSION, Bundle
from vdmbake.cli import main as vdmbake_main
from vdmbake.errors import InputError
from vdmbake.common.mesh import TriMesh
from vdmbake.scene import load_scene

from scenes import TINY_HEAD as HEAD

TET_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def ball(techniques: str = "{ mesh = {} }", name: str = "ball", segments: int = 16, rings: int = 8,
         material: str = "") -> str:
    return f"""
[[objects]]
name = "{name}"
primitive = "sphere"
params = {{ segments = {segments}, rings = {rings} }}
techniques = {techniques}
{material}
"""


TET = """
[[objects]]
name = "tet"
mesh = "tet.obj"
techniques = { mesh = {} }
"""


def write_scene(d: Path, body: str) -> Path:
    (d / "tet.obj").write_text(TET_OBJ)
    p = d / "scene.toml"
    p.write_text(HEAD + body)
    return p


def bake(*args):
    r = CliRunner().invoke(vdmbake_main, [str(a) for a in args])
    return r


def bake_ok(*args):
    r = bake(*args)
    assert r.exit_code == 0, (r.output, r.exception)
    return r


def manifest(b: Path) -> dict:
    return json.loads((b / "manifest.json").read_text())


def files(d: Path) -> dict[str, Path]:
    return {p.relative_to(d).as_posix(): p for p in sorted(d.rglob("*")) if p.is_file()}


def leftovers(out: Path) -> list[str]:
    return sorted(p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}."))


def stamps(d: Path) -> dict:
    """(inode, mtime_ns) of the directory and of every file in it."""
    return {rel: (p.stat().st_ino, p.stat().st_mtime_ns) for rel, p in {".": d, **files(d)}.items()}


def verify_all(b: Path) -> Bundle:
    bundle = Bundle(b)
    for rel in bundle.manifest["parts"]:
        bundle.read_bytes(rel)
    return bundle


# ------------------------------------------------------------------------------------- manifest

def test_manifest_fields_and_part_hashes(tmp_path):
    scene = write_scene(tmp_path, ball("{ mesh = {}, coarse = { ratios = [0.5] } }") + TET)
    out = tmp_path / "s.bundle"
    bake_ok(scene, "-o", out)
    m = manifest(out)
    assert m["format"] == FORMAT == "vdm-bundle"
    assert m["format_version"] == FORMAT_VERSION == 2
    assert m["tool_version"] == vdmbake.__version__
    expected_hash = bake_mod.input_hash(load_scene(scene), tmp_path)[0]
    assert len(m["input_hash"]) == 64 and m["input_hash"] == expected_hash
    # The input mesh file's content hash is recorded.
    assert m["inputs"] == {"tet.obj": hashlib.sha256(TET_OBJ.encode()).hexdigest()}

    parts = m["parts"]
    assert set(parts) == {"objects/ball/mesh.ply", "objects/ball/coarse-0.5.ply", "objects/tet/mesh.ply"}
    on_disk = set(files(out)) - {"manifest.json", "timing.json"}
    assert on_disk == set(parts)
    for rel, meta in parts.items():
        data = (out / rel).read_bytes()
        assert meta["sha256"] == hashlib.sha256(data).hexdigest(), rel
        assert meta["bytes"] == len(data)
    assert m["objects"]["tet"]["mesh"] == "objects/tet/mesh.ply"
    assert parts["objects/tet/mesh.ply"]["faces"] == 4
    assert m["stats"]["parts"] == 3
    timing = json.loads((out / "timing.json").read_text())
    assert set(timing["objects_s"]) == {"ball", "tet"}


# ----------------------------------------------------------------------------------- up to date

def test_rebake_unchanged_is_noop_and_force_rebakes(tmp_path):
    scene = write_scene(tmp_path, ball() + TET)
    out = tmp_path / "s.bundle"
    bake_ok(scene, "-o", out)
    before, mf_before = stamps(out), (out / "manifest.json").read_bytes()

    r = bake_ok(scene, "-o", out)
    assert "up to date" in r.stderr
    assert "baked" not in r.output
    assert stamps(out) == before

    r = bake_ok(scene, "-o", out, "--force")
    assert "up to date" not in r.stderr
    assert "baked" in r.stdout
    after = stamps(out)
    assert set(after) == set(before)
    # A new directory with new files: manifest.json is a different inode.
    assert after["manifest.json"][0] != before["manifest.json"][0]
    assert after["."][0] != before["."][0]
    assert (out / "manifest.json").read_bytes() == mf_before     # same inputs, same manifest bytes
    assert leftovers(out) == []


@pytest.mark.parametrize("change", ["albedo", "mesh_file"])
def test_changed_input_rebakes(tmp_path, change):
    scene = write_scene(tmp_path, ball() + TET)
    out = tmp_path / "s.bundle"
    bake_ok(scene, "-o", out)
    old = manifest(out)
    before = stamps(out)

    if change == "albedo":
        scene.write_text(HEAD + ball(material="material = { albedo = [0.5, 0.25, 0.125] }") + TET)
    else:
        (tmp_path / "tet.obj").write_text(TET_OBJ.replace("v 0 0 1", "v 0 0 2"))
    r = bake_ok(scene, "-o", out)
    assert "up to date" not in r.stderr and "baked" in r.stdout
    new = manifest(out)
    assert new["input_hash"] != old["input_hash"]
    assert stamps(out)["manifest.json"] != before["manifest.json"]
    if change == "albedo":
        assert new["scene"]["objects"][0]["material"]["albedo"] == [0.5, 0.25, 0.125]
    else:
        assert new["inputs"]["tet.obj"] != old["inputs"]["tet.obj"]
        assert new["parts"]["objects/tet/mesh.ply"]["sha256"] != old["parts"]["objects/tet/mesh.ply"]["sha256"]
    verify_all(out)


# -------------------------------------------------------------------------------------- determinism

def test_bake_is_deterministic(tmp_path):
    scene = write_scene(tmp_path, ball("{ mesh = {}, coarse = { ratios = [0.5, 0.25] } }", segments=32, rings=16)
                        + TET)
    a, b = tmp_path / "a.bundle", tmp_path / "b.bundle"
    bake_ok(scene, "-o", a, "--force")
    bake_ok(scene, "-o", b, "--force")
    fa, fb = files(a), files(b)
    assert set(fa) == set(fb)
    assert "timing.json" in fa and len(fa) >= 5
    differing = [rel for rel in fa if rel != "timing.json" and fa[rel].read_bytes() != fb[rel].read_bytes()]
    assert differing == []


# ----------------------------------------------------------------------------- only what is asked

def test_mesh_only_has_no_coarse_parts(tmp_path):
    scene = write_scene(tmp_path, ball("{ mesh = {} }"))
    out = tmp_path / "s.bundle"
    bake_ok(scene, "-o", out)
    m = manifest(out)
    assert list(m["parts"]) == ["objects/ball/mesh.ply"]
    assert {p["kind"] for p in m["parts"].values()} == {"mesh"}
    assert "coarse" not in m["objects"]["ball"]
    assert not any("coarse" in rel for rel in files(out))


def test_coarse_ratios_give_exactly_those_parts(tmp_path):
    scene = write_scene(tmp_path, ball("{ mesh = {}, coarse = { ratios = [0.5, 0.25] } }", segments=32, rings=16))
    out = tmp_path / "s.bundle"
    bake_ok(scene, "-o", out)
    bundle = verify_all(out)
    m = bundle.manifest
    meshes = {rel for rel, p in m["parts"].items() if p["kind"] == "mesh"}
    assert meshes == {"objects/ball/mesh.ply", "objects/ball/coarse-0.5.ply", "objects/ball/coarse-0.25.ply"}
    assert m["objects"]["ball"]["techniques"]["coarse"] == {"meshes": [
        {"ratio": 0.5, "mesh": "objects/ball/coarse-0.5.ply"}, {"ratio": 0.25, "mesh": "objects/ball/coarse-0.25.ply"}]}
    full = len(bundle.read("objects/ball/mesh.ply", parts.MESH).faces)
    assert full == 1024
    for ratio in (0.5, 0.25):
        rel = f"objects/ball/coarse-{ratio:g}.ply"
        faces = len(bundle.read(rel, parts.MESH).faces)
        assert m["parts"][rel]["faces"] == faces
        assert abs(faces - ratio * full) <= 0.05 * ratio * full, (ratio, faces, full)


# ---------------------------------------------------------------------------------- interruption

def _interrupt(monkeypatch, where: str, exc: type[BaseException]) -> dict:
    """Make the bake fail midway, after some parts were already written to the temporary directory."""
    seen = {}
    if where == "bake_object":
        original = bake_mod._bake_object

        def failing(writer, *args):
            if writer.parts:                              # the second object: the first one's parts exist
                seen["tmp"] = writer.stage.tmp
                seen["tmp_files"] = sorted(files(writer.stage.tmp))
                raise exc("interrupted")
            return original(writer, *args)
        monkeypatch.setattr(bake_mod, "_bake_object", failing)
    else:
        original = coarse_mod.simplify

        def failing(mesh, ratio):
            if ratio == 0.25:
                raise exc("interrupted")
            return original(mesh, ratio)
        monkeypatch.setattr(coarse_mod, "simplify", failing)
    return seen


SCENE_2 = ball("{ mesh = {}, coarse = { ratios = [0.5, 0.25] } }") + TET


@pytest.mark.parametrize("where", ["bake_object", "simplify"])
@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_interrupted_bake_leaves_nothing(tmp_path, monkeypatch, where, exc):
    scene = write_scene(tmp_path, SCENE_2)
    out = tmp_path / "s.bundle"
    seen = _interrupt(monkeypatch, where, exc)
    with pytest.raises(exc, match="interrupted"):
        bake_mod.bake(scene, out)
    if where == "bake_object":
        assert seen["tmp_files"] and seen["tmp"].parent == tmp_path    # parts had been written, in a sibling
    assert not out.exists()
    assert leftovers(out) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml", "tet.obj"]


@pytest.mark.parametrize("where", ["bake_object", "simplify"])
def test_interrupted_bake_keeps_previous_bundle(tmp_path, monkeypatch, where):
    scene = write_scene(tmp_path, SCENE_2)
    out = tmp_path / "s.bundle"
    bake_ok(scene, "-o", out)
    old_files = {rel: p.read_bytes() for rel, p in files(out).items()}
    # A changed input, so the bake is not skipped as up to date; then it fails midway.
    scene.write_text(HEAD + SCENE_2.replace("segments = 16", "segments = 20"))
    _interrupt(monkeypatch, where, RuntimeError)
    with pytest.raises(RuntimeError, match="interrupted"):
        bake_mod.bake(scene, out)
    assert {rel: p.read_bytes() for rel, p in files(out).items()} == old_files
    bundle = verify_all(out)
    assert bundle.read("objects/ball/mesh.ply", parts.MESH).faces.shape == (256, 3)
    assert leftovers(out) == []


def test_refuses_to_overwrite_foreign_directory(tmp_path):
    scene = write_scene(tmp_path, ball())
    out = tmp_path / "mywork"
    (out / "sub").mkdir(parents=True)
    (out / "notes.txt").write_text("keep me\n")
    (out / "sub" / "data.bin").write_bytes(b"\x00\xff")
    before = {rel: p.read_bytes() for rel, p in files(out).items()}
    r = bake(scene, "-o", out)
    assert r.exit_code == 2, r.output
    assert isinstance(r.exception, SystemExit)
    assert "Traceback" not in r.output
    assert "mywork" in r.stderr and "not a bundle" in r.stderr
    assert {rel: p.read_bytes() for rel, p in files(out).items()} == before
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "sub"]
    assert leftovers(out) == []


def test_empty_existing_directory_is_fine(tmp_path):
    scene = write_scene(tmp_path, ball())
    out = tmp_path / "empty"
    out.mkdir()
    bake_ok(scene, "-o", out)
    verify_all(out)


# -------------------------------------------------------------------------------------- part paths

@pytest.fixture
def small_bundle(tmp_path) -> Path:
    scene = write_scene(tmp_path, ball())
    out = tmp_path / "in.bundle"
    bake_ok(scene, "-o", out)
    return out


@pytest.mark.parametrize("rel", ["/etc/passwd", "../outside.ply", "objects/../../outside.ply",
                                 "objects/ball/../../../etc/passwd", "..", ""])
def test_part_path_rejects_escapes(small_bundle, rel):
    with pytest.raises(InputError, match="leaves the bundle"):
        Bundle(small_bundle).part_path(rel)


def test_part_path_accepts_inside(small_bundle):
    b = Bundle(small_bundle)
    assert b.part_path("objects/ball/mesh.ply") == (small_bundle / "objects/ball/mesh.ply").resolve()
    (small_bundle / "alias.ply").symlink_to("objects/ball/mesh.ply")     # a symlink that stays inside
    assert b.part_path("alias.ply") == (small_bundle / "objects/ball/mesh.ply").resolve()


@pytest.mark.parametrize("kind", ["file", "directory", "prefix_sibling"])
def test_part_path_rejects_symlinks_outside(small_bundle, tmp_path, kind):
    outside = tmp_path / ("in.bundle2" if kind == "prefix_sibling" else "outside")   # shares a string prefix
    outside.mkdir()
    (outside / "x.ply").write_bytes(b"ply\n")
    if kind == "file":
        (small_bundle / "evil.ply").symlink_to(outside / "x.ply")
        rel = "evil.ply"
    else:
        (small_bundle / "objects" / "link").symlink_to(outside, target_is_directory=True)
        rel = "objects/link/x.ply"
    with pytest.raises(InputError, match="resolves outside"):
        Bundle(small_bundle).part_path(rel)


def test_listed_part_symlinked_outside_is_refused_on_open(small_bundle, tmp_path):
    part = small_bundle / "objects/ball/mesh.ply"
    copy = tmp_path / "copy.ply"
    shutil.copyfile(part, copy)          # identical bytes: the checksum alone would not catch it
    part.unlink()
    part.symlink_to(copy)
    with pytest.raises(InputError, match="resolves outside"):
        Bundle(small_bundle)


# ------------------------------------------------------------------------------------------ PLY

def _mesh(with_uv: bool, n: int = 50, f: int = 80) -> TriMesh:
    rng = np.random.default_rng(7)
    v = rng.normal(size=(n, 3)) * 3.1 + np.array([1e5, -2e5, 3e5])
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    faces = rng.integers(0, n, size=(f, 3)).astype(np.int64)
    uvs = rng.random((n, 2)) if with_uv else None
    return TriMesh(v, faces, normals, uvs)


@pytest.mark.parametrize("with_uv", [False, True])
def test_ply_round_trip(with_uv):
    m = _mesh(with_uv)
    # The positions carry more digits than float32 holds, so an exact round trip proves float64 storage.
    assert not np.array_equal(m.vertices.astype(np.float32).astype(np.float64), m.vertices)
    data = ply.to_bytes(m)
    assert data == ply.to_bytes(TriMesh(m.vertices.copy(), m.faces.copy(), m.normals.copy(),
                                        None if m.uvs is None else m.uvs.copy()))   # deterministic bytes
    back = ply.from_bytes(data, "test")
    assert back.vertices.dtype == np.float64 and np.array_equal(back.vertices, m.vertices)
    assert back.faces.dtype == np.int64 and np.array_equal(back.faces, m.faces)
    assert np.array_equal(back.normals, m.normals.astype(np.float32).astype(np.float64))
    if with_uv:
        assert back.uvs is not None
        assert np.array_equal(back.uvs, m.uvs.astype(np.float32).astype(np.float64))
    else:
        assert back.uvs is None


@pytest.mark.parametrize("with_uv", [False, True])
def test_ply_loads_in_trimesh(tmp_path, with_uv):
    import trimesh

    m = _mesh(with_uv)
    path = tmp_path / "m.ply"
    ply.write(path, m)
    t = trimesh.load(str(path), force="mesh", process=False)
    assert len(t.vertices) == len(m.vertices)
    assert np.array_equal(np.asarray(t.faces), m.faces)
    assert np.array_equal(np.asarray(t.vertices, np.float64), m.vertices)


def test_ply_truncated_is_rejected():
    data = ply.to_bytes(_mesh(False))
    with pytest.raises(InputError, match="truncated"):
        ply.from_bytes(data[:-1], "cut.ply")


# ------------------------------------------------------------------------------------------ EXR

def test_exr_multipart_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    base = rng.random((16, 24), dtype=np.float32)
    strided = base[1::2, ::2]                               # (8, 12), a non-contiguous view
    assert strided.shape == (8, 12) and not strided.flags.c_contiguous
    normal_x = rng.random((8, 12))                          # float64: narrowed to float32
    transposed = np.asarray(rng.random((12, 8)), np.float32).T     # (8, 12), Fortran-ordered view
    small = rng.random((3, 5), dtype=np.float32)
    ids = rng.integers(0, 2**32 - 1, size=(3, 5), dtype=np.uint32)
    path = tmp_path / "t.exr"
    exr.write(path, {"geometry": {"depth.Z": strided, "normal.X": normal_x, "normal.Y": transposed},
                     "small": {"mask.A": small, "id.I": ids}})
    back = exr.read(path)
    assert set(back) == {"geometry", "small"}
    g, s = back["geometry"], back["small"]
    assert set(g) == {"depth.Z", "normal.X", "normal.Y"} and set(s) == {"mask.A", "id.I"}
    assert g["depth.Z"].shape == (8, 12) and s["mask.A"].shape == (3, 5)
    assert np.array_equal(g["depth.Z"], strided)
    assert g["normal.X"].dtype == np.float32
    assert np.array_equal(g["normal.X"], normal_x.astype(np.float32))
    assert np.array_equal(g["normal.Y"], transposed)
    assert np.array_equal(s["mask.A"], small)
    assert s["id.I"].dtype == np.uint32 and np.array_equal(s["id.I"], ids)


def test_exr_rejects_3d_array(tmp_path):
    path = tmp_path / "t.exr"
    with pytest.raises(ValueError, match="2-D"):
        exr.write(path, {"p": {"normal": np.zeros((4, 4, 3), np.float32)}})
    assert not path.exists()


def test_exr_rgba_channels_round_trip_separately(tmp_path):
    # vdmrender caches its reference frames as channels R, G, B, A and reads them back by name;
    # the binding merges those into one 'RGBA' array unless told to keep channels separate.
    rng = np.random.default_rng(5)
    chans = {c: rng.random((4, 6), dtype=np.float32) for c in "RGBA"}
    path = tmp_path / "ref.exr"
    exr.write(path, {"reference": chans})
    back = exr.read(path)["reference"]
    assert set(back) == set("RGBA")
    for c in "RGBA":
        assert np.array_equal(back[c], chans[c])
