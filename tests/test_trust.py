"""Measurements a CI job can trust (issue 11): stale bundles and references are redone after a code
change, a frame with no covered pixel is no data, strict GL, and regression gating against an
earlier run's report (--baseline)."""
from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from click.testing import CliRunner

import vdmbake
import vdmbake.bake as bake_mod
from vdmbake.cli import main as bake_main
from vdmrender.deciding import baseline
from vdmrender.reporting import report
from vdmrender.gpu import gl
from vdmrender.common import progress
from vdmrender.tracing import refcache
from vdmrender.cli import main as render_main

from scenes import TINY_HEAD, bake_and_render, rows_by_label

BALL = TINY_HEAD + """
[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 16, rings = 8 }
techniques = { mesh = {}, coarse = { ratios = [0.1] } }
"""


# ------------------------------------------------------------------------------------- freshness

def _package(tmp_path, monkeypatch):
    """A throwaway package `fp` on sys.path: a imports b relatively, c is imported by nobody."""
    root = tmp_path / "fp"
    root.mkdir()
    (root / "__init__.py").write_text("")
    (root / "a.py").write_text("from . import b\n")
    (root / "b.py").write_text("X = 1\n")
    (root / "c.py").write_text("Y = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(vdmbake, "PACKAGES", ("fp",))
    return root


def test_code_fingerprint_follows_imports_and_edits(tmp_path, monkeypatch):
    root = _package(tmp_path, monkeypatch)
    assert vdmbake.package_modules("fp") == ["fp", "fp.a", "fp.b", "fp.c"]
    closure = vdmbake.imported_closure(["fp.a"])
    assert closure == ["fp", "fp.a", "fp.b"]          # c is not imported by a
    before = vdmbake.code_fingerprint(closure)
    (root / "c.py").write_text("Y = 2\n")
    assert vdmbake.code_fingerprint(closure) == before
    (root / "b.py").write_text("X = 2\n")             # an edit to an imported module counts
    assert vdmbake.code_fingerprint(closure) != before


def test_reference_code_covers_what_the_reference_runs():
    mods = vdmbake.imported_closure(refcache.REFERENCE_ROOTS)
    assert {"vdmrender.tracing.reference", "vdmrender.tracing.quadric_math", "vdmrender.tracing.shading", "vdmrender.common.camera",
            "vdmbake.common.embree", "vdmbake.common.geometry", "vdmbake.common.instances"} <= set(mods)
    assert "vdmrender.gpu.gl" not in mods                 # GL code does not invalidate the cached reference
    meso = vdmbake.imported_closure(["vdmrender.common.mesostructure"])
    assert "vdmbake.common.geometry" in meso and "vdmrender.gpu.gl" not in meso   # the displaced mesh, no GL
    assert refcache.reference_code(True) != refcache.reference_code(False)


def test_other_bake_code_rebakes_with_the_reason_logged(tmp_path, monkeypatch):
    scene, out = tmp_path / "s.toml", tmp_path / "s.bundle"
    scene.write_text(BALL)
    r = CliRunner().invoke(bake_main, [str(scene), "-o", str(out)])
    assert r.exit_code == 0 and "baking (no bundle yet)" in r.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["code_fingerprint"] == bake_mod.bake_code()
    r = CliRunner().invoke(bake_main, [str(scene), "-o", str(out)])
    assert "up to date" in r.stderr
    # As after an edit to, say, vdmbake/kernels/vdm.py: another fingerprint of the package's sources.
    monkeypatch.setattr(bake_mod, "bake_code", lambda: "f" * 64)
    r = CliRunner().invoke(bake_main, [str(scene), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert f"baked by other code: bake code {manifest['code_fingerprint'][:12]}, now ffffffffffff)" in r.stderr
    assert "baked" in r.stdout
    assert json.loads((out / "manifest.json").read_text())["code_fingerprint"] == "f" * 64


def test_other_reference_code_retraces(tmp_path, monkeypatch):
    r1, out = bake_and_render(tmp_path, BALL)
    r2 = CliRunner().invoke(render_main, [str(tmp_path / "b.bundle"), "-o", str(out), "--json", "--no-flip"])
    assert rows_by_label(r2)["mesh"]["reference_cached"] is True
    monkeypatch.setattr(refcache, "reference_code", lambda mesostructure: "e" * 64)
    r3 = CliRunner().invoke(render_main, [str(tmp_path / "b.bundle"), "-o", str(out), "--json", "--no-flip"])
    assert rows_by_label(r3)["mesh"]["reference_cached"] is False


# ---------------------------------------------------------------------------------- empty frames

AWAY = TINY_HEAD.replace("orbit = { count = 1 }", "") + """
[[camera.poses]]
eye = [0.0, -5.0, 0.0]
target = [0.0, -10.0, 0.0]
[[camera.poses]]
eye = [0.0, -5.0, 0.0]
target = [0.0, 0.0, 0.0]
[[objects]]
name = "ball"
primitive = "sphere"
techniques = { mesh = {}, coarse = { ratios = [0.02] } }
"""


def test_an_empty_frame_is_flagged_and_left_out_of_the_averages(tmp_path):
    """Frame 0 looks away from the sphere, frame 1 at it: the row counts one empty frame, its error
    and IoU come from frame 1 alone (an empty frame once scored 0.0 and IoU 1.0 and was averaged in)."""
    r, out = bake_and_render(tmp_path, AWAY, empty_reference_ok=True)
    assert r.exit_code == 0, r.output
    row = rows_by_label(r)["coarse@0.02"]
    f0, f1 = row["per_frame"]
    assert f0["empty"] is True and f0["mean_dluv"] is None and f0["iou"] is None and f0["flip"] is None
    assert f1["empty"] is False and f1["mean_dluv"] > 0 and f1["iou"] < 1
    assert row["empty_frames"] == 1
    assert row["iou"] == f1["iou"] and row["mean_dluv"] == f1["mean_dluv"]
    assert row["flip_mean"] == f1["flip"] > 0
    csv = (out / "report.csv").read_text().splitlines()
    assert "empty_frames" in csv[0] and "flip_mean" in csv[0]


def test_a_variant_with_no_covered_pixel_is_exit_2_unless_expected(tmp_path):
    text = AWAY.replace('[[camera.poses]]\neye = [0.0, -5.0, 0.0]\ntarget = [0.0, 0.0, 0.0]\n', "")
    r, out = bake_and_render(tmp_path, text, empty_reference_ok=True)
    assert r.exit_code == 2, r.output
    assert "ball: mesh: no frame has a pixel to score" in r.stderr and "expect_empty" in r.stderr
    rows = json.loads((out / "report.json").read_text())["rows"]   # the report is written all the same
    assert [(x["empty_frames"], x["frames"], x["mean_dluv"], x["iou"]) for x in rows] == [(1, 1, None, None)] * 2
    r, _ = bake_and_render(tmp_path, text.replace('primitive = "sphere"', 'primitive = "sphere"\nexpect_empty = true'),
                           empty_reference_ok=True)
    assert r.exit_code == 0, r.output


def test_the_test_helpers_refuse_an_empty_reference(tmp_path):
    with pytest.raises(AssertionError, match="the reference covers no pixel in frames \\[0\\]"):
        bake_and_render(tmp_path, AWAY)


# -------------------------------------------------------------------------------------- strict GL

def test_strict_gl_refuses_unknown_uniforms_and_layout_mismatches(monkeypatch):
    ctx = gl.create_context()
    try:
        prog = gl.program(ctx, "mesh.vert", "depth.frag")
        gl.set_uniforms(prog, u_mvp=np.eye(4))
        with pytest.raises(gl.GLError, match="no active uniform 'u_mvp_typo'"):
            gl.set_uniforms(prog, u_mvp_typo=np.eye(4))
        buf = ctx.buffer(np.zeros((3, 3), "f4").tobytes())
        with pytest.raises(gl.GLError, match="no active vertex attribute 'in_normal'"):
            gl.vertex_array(ctx, prog, [(buf, "3f 3f", "in_pos", "in_normal")])
        with pytest.raises(gl.GLError, match="has 3 components, the layout '2f' gives 2"):
            gl.vertex_array(ctx, prog, [(buf, "2f", "in_pos")])
        with pytest.raises(gl.GLError, match=r"\['in_pos'\] are read but not given"):
            gl.vertex_array(ctx, prog, [])
        gl.release(gl.vertex_array(ctx, prog, [(buf, "3f", "in_pos")]))
        # Declared: a pass variant that compiles a uniform or attribute away (here: depth.frag reads no normal).
        lax = gl.program(ctx, "mesh.vert", "depth.frag", ("DECLARED",), may_lack=("in_normal", "u_albedo"))
        gl.set_uniforms(lax, u_albedo=(1.0, 1.0, 1.0))
        gl.release(gl.vertex_array(ctx, lax, [(buf, "3f 3f", "in_pos", "in_normal")]), buf)
        monkeypatch.setenv("VDM_GL_STRICT", "0")   # not strict: skipped, as before
        gl.set_uniforms(prog, u_mvp_typo=np.eye(4))
    finally:
        ctx.release()


def test_textures_are_bound_by_sampler_name():
    """Each sampler reads the texture given by its name, on a unit of its own that no caller numbers;
    a misspelt sampler is refused like a misspelt uniform."""
    ctx = gl.create_context()
    try:
        prog = gl.program(ctx, "billboard.vert", "billboard.frag", ("IMPROVED",))
        names = gl.samplers(prog)
        assert names == sorted(names) and {"u_maps", "u_alpha", "u_shadow_map"} <= set(names)
        assert "u_board_texels" not in names    # a float, and ints such as pom's u_steps, are no samplers
        assert "u_steps" not in gl.samplers(gl.program(ctx, "mesostructure.vert", "pom.frag"))
        textures = {n: ctx.texture((1, 1), 1, dtype="f4") for n in names}
        gl.bind_textures(prog, **textures)
        assert sorted(prog[n].value for n in names) == list(range(len(names)))   # one unit each
        assert all(prog[n].value == names.index(n) for n in names)
        with pytest.raises(gl.GLError, match="no active sampler 'u_map'"):
            gl.bind_textures(prog, u_map=textures["u_maps"])
        gl.release(*textures.values())
    finally:
        ctx.release()


def test_no_dead_shadow_bias():
    from vdmrender.gpu.gl import source

    assert "u_shadow_bias" not in source("mesh.frag") and "u_shadow_bias" not in source("sphere.frag")


# ------------------------------------------------------------------------------------------ baseline

def _report(**rows):
    return {"device": "d", "resolution": [8, 8], "time": "gpu", "rows": [
        {"object": "o", "label": k, "mean_dluv": v[0], "p95_dluv": v[1], "median_ms": v[2], "flip_mean": 0.1}
        for k, v in rows.items()]}


def test_baseline_changes_and_thresholds():
    old = _report(mesh=(0.02, 0.1, 10.0), **{"coarse@0.1": (0.8, 3.0, 5.0), "gone": (1.0, 1.0, 1.0)})
    new = _report(mesh=(0.02, 0.1, 10.5), **{"coarse@0.1": (0.95, 3.5, 7.0), "added": (1.0, 1.0, 1.0)})
    b = baseline.compare(old, new, max_error_increase=0.1, max_slowdown=1.25)
    by = {c["label"]: c for c in b["rows"]}
    assert by["mesh"]["d_mean_dluv"] == 0.0 and by["mesh"]["time_ratio"] == 1.05 and by["mesh"]["exceeds"] == []
    assert by["coarse@0.1"]["d_mean_dluv"] == 0.15 and by["coarse@0.1"]["d_p95_dluv"] == 0.5
    assert by["coarse@0.1"]["time_ratio"] == 1.4 and by["coarse@0.1"]["exceeds"] == ["error", "time"]
    assert by["added"]["status"] == "new" and by["gone"]["status"] == "missing"
    assert b["failed"] == ["o: coarse@0.1"]
    assert baseline.compare(old, new, 0.2, 1.5)["failed"] == []         # within both thresholds
    assert baseline.compare(old, new, None, None)["failed"] == []       # no threshold, no failure
    table = report.baseline_table(b)
    assert "| o | coarse@0.1 | 0.800 → 0.950 | +0.150 |" in table and "error, time" in table
    assert report.baseline_csv(b).splitlines()[0].startswith("object,label,status,old_mean_dluv")


def test_baseline_refuses_what_is_not_a_report(tmp_path):
    from vdmbake.errors import InputError

    bad = tmp_path / "r.json"
    bad.write_text('{"rows": [{"object": "o"}]}')
    with pytest.raises(InputError, match="not a vdmrender report.json"):
        baseline.load(bad)
    with pytest.raises(InputError, match="file not found"):
        baseline.load(tmp_path / "missing.json")


def test_baseline_through_the_cli(tmp_path):
    """Against itself: exit 0 and a zero change; against a doctored better baseline: exit 1, the table
    on stderr, baseline.md/.csv and report.json's block; thresholds without --baseline: exit 2."""
    r, out = bake_and_render(tmp_path, BALL, "--no-flip", "--repeats", "4")     # --max-slowdown's least
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "report.json").read_text())
    for row in doc["rows"]:
        row["median_ms"] = 1e9                         # a baseline no run is slower than, whatever the load
    old = tmp_path / "old.json"
    old.write_text(json.dumps(doc))
    args = [str(tmp_path / "b.bundle"), "-o", str(tmp_path / "new"), "--no-flip", "--baseline", str(old),
            "--max-error-increase", "0.05", "--max-slowdown", "1000", "--repeats", "4"]
    r = CliRunner().invoke(render_main, args)
    assert r.exit_code == 0, r.output
    block = json.loads((tmp_path / "new" / "report.json").read_text())["baseline"]
    assert all(c["d_mean_dluv"] == 0.0 and c["exceeds"] == [] for c in block["rows"])
    better = json.loads(old.read_text())
    for row in better["rows"]:
        row["mean_dluv"] = round(row["mean_dluv"] - 0.1, 4)     # last week's run was 0.1 better
    (tmp_path / "better.json").write_text(json.dumps(better))
    args[args.index(str(old))] = str(tmp_path / "better.json")
    r = CliRunner().invoke(render_main, args)
    assert r.exit_code == 1, r.output
    assert "| ball | coarse@0.1 |" in r.stderr and "+0.100 |" in r.stderr and "exceeds the baseline" in r.stderr
    assert (tmp_path / "new" / "baseline.md").read_text().count("error") >= 2
    assert "error" in (tmp_path / "new" / "baseline.csv").read_text()
    r = CliRunner().invoke(render_main, [str(tmp_path / "b.bundle"), "-o", str(tmp_path / "x"), "--max-slowdown", "2"])
    assert r.exit_code == 2 and "--baseline" in r.stderr


# ------------------------------------------------------------------------------------------ progress

def test_progress_bar_only_on_a_terminal(monkeypatch):
    items = [1, 2, 3]
    assert progress.bar(items, "x") is items                    # CliRunner, CI logs: no bar
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    b = progress.bar(items, "x")
    assert type(b).__name__ == "tqdm" and list(b) == items
