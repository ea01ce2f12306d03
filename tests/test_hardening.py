"""Hardening (issue 14): a reproduction per finding, small and fast. Bad manifests, damaged parts and
scenes vdmrender could not draw end in exit 2 with one line naming the key or file; parts are read once
(regular files of the listed size) and parsed from the bytes hashed; signals clean up and exit 128+N."""
from __future__ import annotations

import json
import os
import shutil
import signal
import struct
from pathlib import Path

import numpy as np
import pytest

from vdmbake.formats import exr, ply
from vdmbake.bundle import parts, staging
from vdmbake.bundle.directory import Bundle
from vdmbake.errors import InputError

from helpers import assert_input_error, bake, render, write_scene
from scenes import GOOD_SCENE, TINY_HEAD

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
    """A re-bake swapping the part between its checksum and its parse cannot mix bundles: the part is read once
    and the very bytes hashed are parsed (the issue's mixed frame)."""
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
    from vdmbake.assets import primitives
    from vdmbake.assets.primitives import PRIMITIVES

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


# ------------------------------------------------------------------------- what vdmbake must refuse

def _obj_file(path: Path, v, f, uv=None) -> str:
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in v]
    if uv is None:
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    else:
        lines += [f"vt {s:.17g} {t:.17g}" for s, t in uv]
        lines += ["f " + " ".join(f"{i + 1}/{i + 1}" for i in tri) for tri in f]
    path.write_text("\n".join(lines) + "\n")
    return path.name


def _mesh_scene(name: str, techniques: str, extra: str = "") -> str:
    return TINY_HEAD + f'[[objects]]\nname = "thing"\nmesh = "{name}"\n{extra}techniques = {{ {techniques} }}\n'


@pytest.mark.parametrize("shape", ["collinear", "point"])
@pytest.mark.parametrize("technique", ["mesh = {}", "billboards = {}", "coarse = { ratios = [0.5] }"])
def test_mesh_without_area_refused_at_bake(tmp_path, shape, technique):
    v = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]] if shape == "collinear" else [[1, 1, 1]] * 4
    name = _obj_file(tmp_path / "m.obj", v, [[0, 1, 2], [1, 3, 2]])
    out = tmp_path / "x.bundle"
    assert_input_error(bake(write_scene(tmp_path, _mesh_scene(name, technique)), "-o", out), "no area", out)


def test_nan_uvs_refused_with_a_mesostructure(tmp_path):
    name = _obj_file(tmp_path / "m.obj", [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.1]], [[0, 1, 2], [1, 3, 2]],
                     uv=[[0, 0], [float("nan"), 0], [0, 1], [1, 1]])
    out = tmp_path / "x.bundle"
    meso = 'mesostructure = { height = "bricks", size = 8 }\n'
    assert_input_error(bake(write_scene(tmp_path, _mesh_scene(name, "bump = {}", meso)), "-o", out),
                       "texture coordinates", out)
    # without a mesostructure nothing reads them: the mesh bakes (without UVs)
    assert bake(write_scene(tmp_path, _mesh_scene(name, "mesh = {}")), "-o", out).exit_code == 0


def test_coarse_ratio_leaving_no_face_refused(tmp_path, monkeypatch):
    """fast-simplification can collapse a small mesh to nothing; the bake says so instead of writing a
    part vdmrender cannot draw."""
    from vdmbake.kernels import coarse
    from vdmbake.common.mesh import TriMesh

    monkeypatch.setattr(coarse, "simplify", lambda mesh, ratio: TriMesh(mesh.vertices[:0], mesh.faces[:0], mesh.normals[:0]))
    out = tmp_path / "x.bundle"
    scene = GOOD_SCENE.replace("techniques = { mesh = {} }", "techniques = { coarse = { ratios = [0.001] } }")
    assert_input_error(bake(write_scene(tmp_path, scene), "-o", out), ["ratios", "0.001", "no face"], out)


def test_bake_reads_each_part_back_through_the_renderers_checks(tmp_path, monkeypatch):
    """Whatever a bake step writes goes through the reader's checks before the bundle is committed."""
    from vdmbake.kernels import coarse
    from vdmbake.common.mesh import TriMesh

    real = coarse.simplify

    def nan_normals(mesh, ratio):
        c = real(mesh, ratio)
        c.normals[0] = np.nan
        return TriMesh(c.vertices, c.faces, c.normals)

    monkeypatch.setattr(coarse, "simplify", nan_normals)
    out = tmp_path / "x.bundle"
    scene = GOOD_SCENE.replace("techniques = { mesh = {} }", "techniques = { coarse = { ratios = [0.5] } }")
    assert_input_error(bake(write_scene(tmp_path, scene), "-o", out), ["as baked", "normals"], out)


# ------------------------------------------------------------------------------------------- scale

def _sphere_file(tmp_path: Path, scale: float, offset: float) -> str:
    import trimesh

    s = trimesh.creation.icosphere(2)
    return _obj_file(tmp_path / "s.obj", s.vertices * scale + offset, s.faces)


@pytest.mark.parametrize("scale,offset", [(1e-8, 0.0), (1e-9, 0.0), (1.0, 1e11), (1e-9, 1e3)])
def test_any_scale_and_offset(tmp_path, scale, offset):
    """A unit sphere (162 vertices) at 1e-9 or 1e11 from the origin keeps its vertices (an absolute weld lost
    most of them) and renders like at unit scale, within the bound (before: the wrong mesh, a ZeroDivisionError,
    and with the vertices kept, the reference's own shadow acne)."""
    from scenes import bake_and_render, rows_by_label

    name = _sphere_file(tmp_path, scale, offset)
    result, _ = bake_and_render(tmp_path, _mesh_scene(name, "mesh = {}"), "--no-flip")
    assert result.exit_code == 0, result.output
    assert json.loads((tmp_path / "b.bundle/manifest.json").read_text())["parts"]["objects/thing/mesh.ply"]["vertices"] == 162
    assert rows_by_label(result)["mesh"]["mean_dluv"] < 0.3


# ---------------------------------------------------------------------------- signals and output commits

import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

# about 9 s of bake on an idle 2-core machine, so a signal sent 0.2 s after the staging folder appears lands
# during the bake (at 256 texels the whole bake took 0.5 s there and the signal came after the exit)
SLOW_SCENE = GOOD_SCENE.replace("techniques = { mesh = {} }", "techniques = { billboards = { resolution = 1024 } }")
BIN = Path(sys.executable).parent


def _dead_pid() -> int:
    p = subprocess.Popen(["true"])
    p.wait()
    return p.pid


def _siblings(out: Path) -> list[str]:
    return sorted(p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}."))


def _default_signals() -> None:
    """In the child: the default dispositions a terminal gives. A test run started in the background or
    under nohup has SIGINT or SIGHUP ignored, which the tools rightly keep ignored (vdmbake/signals.py)."""
    for s in (signal.SIGINT, signal.SIGHUP, signal.SIGTERM):
        signal.signal(s, signal.SIG_DFL)


def _signal_when_staging(cmd, out: Path, sig: int) -> subprocess.CompletedProcess:
    """Start cmd, send `sig` once its staging folder exists (plus a moment), return its result."""
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_default_signals)
    tmp = staging.sibling(out, "tmp", p.pid)
    t0 = time.monotonic()
    while not tmp.exists() and p.poll() is None and time.monotonic() - t0 < 60:
        time.sleep(0.01)
    time.sleep(0.2)
    p.send_signal(sig)
    stdout, stderr = p.communicate(timeout=60)
    return subprocess.CompletedProcess(cmd, p.returncode, stdout, stderr)


@pytest.mark.parametrize("sig,code", [(signal.SIGTERM, 143), (signal.SIGHUP, 129), (signal.SIGINT, 130)])
def test_bake_signal_cleans_up_and_exits_128_plus_n(tmp_path, sig, code):
    out = tmp_path / "x.bundle"
    r = _signal_when_staging([str(BIN / "vdmbake"), str(write_scene(tmp_path, SLOW_SCENE)), "-o", str(out)], out, sig)
    assert r.returncode == code, (r.returncode, r.stderr[-2000:])
    assert "Traceback" not in r.stderr and "interrupted" in r.stderr
    assert not out.exists() and _siblings(out) == []


def test_render_sigterm_cleans_up_and_keeps_the_previous_output(baked, tmp_path):
    """SIGTERM mid-render: exit 143, the previous output as it was, nothing beside it. The render asked for would
    sample for minutes (--sample-s), so the signal lands mid-render however late a loaded machine delivers it."""
    out = tmp_path / "out"
    cmd = [str(BIN / "vdmrender"), str(baked), "-o", str(out), "--no-flip"]
    assert subprocess.run(cmd, capture_output=True).returncode == 0
    before = (out / "report.json").read_bytes()
    r = _signal_when_staging(cmd + ["--sample-s", "600"], out, signal.SIGTERM)
    assert r.returncode == 143, r.stderr[-2000:]
    assert (out / "report.json").read_bytes() == before and _siblings(out) == []


EXITING = """
import sys, time
class Slow:                      # destroyed with the module's globals, in the interpreter's own teardown
    def __del__(self):
        print("teardown", file=sys.stderr, flush=True)
        time.sleep(1.0)
slow = Slow()
from vdmbake.errors import guarded
guarded(lambda: print("done", flush=True), False)
"""


def test_a_signal_while_the_interpreter_exits_is_ignored(tmp_path):
    """A command that returned (its output committed, its exit code chosen), then SIGTERM during the interpreter's
    teardown: exit 0. Python's finalisation puts back a signal's default action before that teardown (0.2 s after a
    render's last line with llvmpipe loaded), where SIGTERM would kill a finished run (-15: as a shell reads it, a run
    stopped before writing); vdmbake.signals ignores the signals once the interpreter exits. The teardown here is an
    object's slow destructor, so the signal lands in it every time."""
    (tmp_path / "exiting.py").write_text(EXITING)
    p = subprocess.Popen([sys.executable, str(tmp_path / "exiting.py")], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, preexec_fn=_default_signals)
    for line in p.stderr:
        if line.startswith("teardown"):
            p.send_signal(signal.SIGTERM)
            break
    stdout, stderr = p.communicate(timeout=60)
    assert (p.returncode, stdout) == (0, "done\n"), (p.returncode, stderr[-2000:])


def test_swallowed_interrupt_still_stops_the_commit(tmp_path, monkeypatch):
    """trimesh's optional imports catch BaseException, so a Ctrl-C during them is lost; the signal is
    recorded and the commit refuses to run: exit 130, nothing written (it was exit 0 with a bundle)."""
    from vdmbake import bake as bake_module, signals

    real = bake_module.object_mesh

    def swallow(*args):
        try:
            signals._handler(signal.SIGINT, None)
        except BaseException:   # what trimesh does
            pass
        return real(*args)

    monkeypatch.setattr(bake_module, "object_mesh", swallow)
    out = tmp_path / "x.bundle"
    r = bake(write_scene(tmp_path, GOOD_SCENE), "-o", out)
    assert r.exit_code == 130, (r.exit_code, r.output)
    assert not out.exists() and _siblings(out) == []


def test_stale_staging_of_dead_processes_removed(tmp_path):
    out = tmp_path / "x.bundle"
    pid = _dead_pid()
    for kind in ("tmp", "old"):
        (tmp_path / f".x.bundle.{kind}-{pid}" / "objects").mkdir(parents=True)
    assert bake(write_scene(tmp_path, GOOD_SCENE), "-o", out).exit_code == 0
    assert (out / "manifest.json").is_file() and _siblings(out) == [], _siblings(out)


def test_bundle_lost_between_the_two_renames_is_restored(tmp_path, baked):
    """A kill between the fallback swap's two renames left only `.NAME.old-PID`: the next run puts it back."""
    from vdmbake.bundle.staging import StagedDir

    out = tmp_path / "x.bundle"
    shutil.copytree(baked, tmp_path / f".x.bundle.old-{_dead_pid()}")
    StagedDir(out, "manifest.json", "bundle").abort()
    assert Bundle(out).manifest and _siblings(out) == []


def test_live_processes_staging_is_left_alone(tmp_path):
    out = tmp_path / "x.bundle"
    mine = tmp_path / f".x.bundle.tmp-{os.getppid()}"      # a live process (our parent)
    mine.mkdir()
    assert bake(write_scene(tmp_path, GOOD_SCENE), "-o", out).exit_code == 0
    assert mine.is_dir()


def test_swap_keeps_a_bundle_at_every_instant(tmp_path, baked, monkeypatch):
    """The commit exchanges the folders in one step: the path never lacks a bundle."""
    from vdmbake.bundle import staging

    out = tmp_path / "x.bundle"
    shutil.copytree(baked, out)
    seen = []
    real = staging.exchange

    def watch(a, b):
        ok = real(a, b)
        seen.append(ok and (b / "manifest.json").is_file())
        return ok

    monkeypatch.setattr(staging, "exchange", watch)
    assert bake(write_scene(tmp_path, GOOD_SCENE.replace("count = 1", "count = 2")), "-o", out).exit_code == 0
    assert seen == [True] and _siblings(out) == []


@pytest.mark.parametrize("target", [".", "dangling", "link", "link-force"])
def test_odd_output_targets(tmp_path, baked, monkeypatch, target):
    monkeypatch.chdir(tmp_path)
    scene = write_scene(tmp_path, GOOD_SCENE)
    if target == ".":
        r = bake(scene, "-o", ".")
        assert_input_error(r, "folder name")
        return
    link = tmp_path / "l.bundle"
    link.symlink_to(tmp_path / "nowhere" if target == "dangling" else baked)
    r = bake(scene, "-o", link, *(["--force"] if target == "link-force" else []))
    assert_input_error(r, "symbolic link")
    assert link.is_symlink() and _siblings(link) == []


def test_render_output_dot_refused(baked, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert_input_error(render(baked, "-o", ".", "--no-flip"), "folder name")


def test_debug_keeps_exit_code_2(tmp_path):
    r = bake(tmp_path / "missing.toml", "-o", tmp_path / "x", "--debug")
    assert r.exit_code == 2 and "Traceback" in r.stderr and "error:" in r.stderr


def test_full_disk_is_exit_2(tmp_path, monkeypatch):
    import errno

    from vdmbake.bundle import directory as bundle_module

    def full(self, rel, kind, value):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "x"))

    monkeypatch.setattr(bundle_module.BundleWriter, "add_read", full)   # every part is written there
    out = tmp_path / "x.bundle"
    assert_input_error(bake(write_scene(tmp_path, GOOD_SCENE), "-o", out), "No space left", out)


def test_shader_compile_error_is_exit_2_with_the_log(monkeypatch):
    from vdmrender.gpu import gl

    try:
        ctx = gl.create_context(None)
    except InputError as e:
        pytest.skip(f"no OpenGL here: {e}")
    real = gl.source
    monkeypatch.setattr(gl, "source", lambda name: real(name).replace("void main", "void main_broken", 1)
                        if name.endswith(".frag") else real(name))
    with pytest.raises(InputError, match="do not compile.*Compiler log"):
        gl.program(ctx, "mesh.vert", "mesh.frag")
    ctx.release()


@pytest.mark.slow
def test_concurrent_bakes_to_one_output(tmp_path):
    """Two vdmbake --force on one -o: each exits 0 (the swap is an exchange) or 2 with a message, never a
    traceback, and one valid bundle is left with no debris. Each bakes 512² billboards (about 1 s, 11 MB):
    started together, the two bakes overlap from start to swap."""
    out = tmp_path / "x.bundle"
    scene = write_scene(tmp_path, SLOW_SCENE.replace("resolution = 1024", "resolution = 512"))
    ps = [subprocess.Popen([str(BIN / "vdmbake"), str(scene), "-o", str(out), "--force"], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(p.wait(timeout=120), p.stderr.read()) for p in ps]
    for rc, err in results:
        assert rc in (0, 2) and "Traceback" not in err, err[-2000:]
    assert Bundle(out).manifest and _siblings(out) == []


# ------------------------------------------------------------------------------------------ memory

def test_memory_guard_counts_geometry(baked):
    """The guard counts the largest object's faces and quadrics beside the pixels (the issue: a 1e6-atom render
    at a tiny resolution ran out of memory while only the resolution was checked)."""
    from vdmbake.bundle import budget
    from vdmrender.render import held_geometry

    b = Bundle(baked)
    faces = b.manifest["parts"][MESH]["faces"] + b.manifest["parts"]["objects/ball/coarse-0.5.ply"]["faces"]
    assert held_geometry(b) == (budget.Geometry("ball", faces), budget.Geometry("atoms", quadrics=2))
    r = budget.Render(48, 48, 1, objects=held_geometry(b))
    need = budget.render_bytes(r)   # the largest object's: the ball's faces
    assert need - budget.render_bytes(budget.Render(48, 48, 1)) == faces * budget.BYTES_PER_FACE
    with pytest.raises(InputError, match="geometry .* GiB: object 'ball'"):
        budget.check_render(r, free=need - 1)
    assert budget.check_render(r, free=need) is None


def test_vdm_bake_memory_guard():
    from vdmbake.scene import Mesostructure
    from vdmbake.techniques import vdm

    big = Mesostructure(height="bricks", size=1024)     # defaults: 32 phi, 8 theta, 16 curvatures: 16 GiB table
    with pytest.raises(InputError, match="mesostructure.size"):
        vdm.check_memory(big, "object 'x'", free=24 << 30)
    vdm.check_memory(Mesostructure(height="bricks", size=64), "object 'x'", free=24 << 30)


# ------------------------------------------------------------------------------- scene values and files

@pytest.mark.parametrize("light,needle", [("[1" + "0" * 400 + ", 0, 1]", "light.direction"), ("[1e-200, 0, 0]", None)])
def test_scene_numbers_finite_after_parsing_and_normalising(tmp_path, light, needle):
    """An integer literal past float's range is refused by key (it was OverflowError); a direction whose
    norm underflows is normalised by its largest component (it was ZeroDivisionError)."""
    from vdmbake.scene import load_scene

    p = write_scene(tmp_path, f"[light]\ndirection = {light}\n" + GOOD_SCENE)
    if needle:
        with pytest.raises(InputError, match=needle):
            load_scene(p)
    else:
        assert load_scene(p).light.direction == (1.0, 0.0, 0.0)


def test_duplicate_knob_values_and_newlines_refused_in_one_line(tmp_path):
    out = tmp_path / "x.bundle"
    dup = GOOD_SCENE.replace("techniques = { mesh = {} }", "techniques = { coarse = { ratios = [1, 1.0] } }")
    assert_input_error(bake(write_scene(tmp_path, dup), "-o", out), ["ratios", "distinct"], out)
    nl = GOOD_SCENE.replace('name = "ball"', 'name = "b\\nx"')
    assert_input_error(bake(write_scene(tmp_path, nl), "-o", out), ["objects[0].name", "'b\\nx'"], out)


@pytest.mark.parametrize("fmt", ["png", "exr"])
def test_height_map_size_limit_is_the_same_for_png_and_exr(tmp_path, fmt, monkeypatch):
    """A 16k PNG was refused as a "decompression bomb" while a 16k EXR was accepted: one limit, from the
    header, for both (made small here so the test stays small)."""
    from PIL import Image

    from vdmbake.assets import heightfields

    monkeypatch.setattr(heightfields, "MAX_PIXELS", 64 * 64)
    a = np.linspace(0, 1, 65 * 64, dtype=np.float32).reshape(64, 65)
    p = tmp_path / f"h.{fmt}"
    if fmt == "png":
        Image.fromarray((a * 255).astype(np.uint8)).save(p)
    else:
        exr.write(p, {"h": {"Y": a}})
    with pytest.raises(InputError, match="65 x 64 pixels"):
        heightfields.from_spec(p.name, 8, tmp_path)


def test_missing_optional_reader_reported_as_unsupported_format(tmp_path, monkeypatch):
    import trimesh

    def load(*a, **k):
        raise ModuleNotFoundError("No module named 'charset_normalizer'", name="charset_normalizer")

    monkeypatch.setattr(trimesh, "load_scene", load)   # how assets/meshes.py reads every file
    name = _obj_file(tmp_path / "m.obj", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    out = tmp_path / "x.bundle"
    assert_input_error(bake(write_scene(tmp_path, _mesh_scene(name, "mesh = {}")), "-o", out),
                       ["format not supported", "install the Python package charset_normalizer"], out)


def test_vdm_entry_k_larger_than_stored(tmp_path):
    scene = GOOD_SCENE.replace("techniques = { mesh = {} }", 'mesostructure = { height = "bricks", size = 8, phi = 4, '
                               'theta = 2, curvatures = 2 }\ntechniques = { vdm = { k = [2] } }')
    out = tmp_path / "v.bundle"
    assert bake(write_scene(tmp_path, scene), "-o", out).exit_code == 0
    rewrite(out, lambda m: m["objects"]["ball"]["techniques"]["vdm"].update(k=16))
    refused(out, ["'objects.ball.techniques.vdm.k'", "records"])


def test_unknown_key_with_a_newline_in_one_line():
    """Found by the fuzzer (tests/fuzz_inputs.py): an unknown key holding a newline broke the message."""
    from vdmbake.scene import parse_scene_dict

    ball = {"name": "a", "primitive": "sphere", "techniques": {"mesh": {}}}
    for data in ({"\n": 1, "objects": [ball]}, {"objects": [dict(ball, techniques={"x\ny": {}})]}):
        with pytest.raises(InputError) as e:
            parse_scene_dict(data, "s.toml")
        assert "\n" not in str(e.value) and "\\n" in str(e.value)


def test_a_signal_turned_into_another_exception_still_exits_as_the_signal(capsys):
    """SIGTERM arriving inside an extension module's import surfaces as ImportError ("initialization failed"; CI saw
    it in OpenEXR's lazy import during a render): the tool still exits 143, not 1 with a traceback."""
    from vdmbake.errors import guarded

    def work():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
        except BaseException:
            raise ImportError("initialization failed") from None

    with pytest.raises(SystemExit) as e:
        guarded(work, debug=False)
    assert e.value.code == 143 and "interrupted" in capsys.readouterr().err
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
