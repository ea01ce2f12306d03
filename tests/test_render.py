"""End to end through OpenGL (EGL; Mesa llvmpipe on machines without a GPU): bake, render,
compare against the Embree reference, and the report's contract."""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from vdmbake.cli import main as bake_main
from vdmrender.gpu import gl
from vdmrender.cli import main as render_main

import scenes
from scenes import rows_by_label

ROOT = Path(__file__).resolve().parents[1]

SMALL = """
[render]
resolution = [{w}, {h}]
repeats = 2
warmup = 0
shadow_map = 2048
[camera]
orbit = {{ count = 2, elevation_deg = 25, distance = 2.8, fov_deg = 40 }}
{extra}
[[objects]]
{obj}
"""


def bake_and_render(tmp_path, obj, w=96, h=80, extra="", args=()):
    """No FLIP score: no test here looks at it."""
    return scenes.bake_and_render(tmp_path, SMALL.format(w=w, h=h, extra=extra, obj=obj), "--no-flip", *args)


@pytest.mark.slow
@pytest.mark.plots
def test_bunny_mesh_matches_traced_reference(tmp_path):
    """The real scanned bunny: rasterised full mesh against Embree, same shading, same pixel centres."""
    obj = ('name = "bunny"\nmesh = "pkg:pymeshfix/examples/StanfordBunny.ply"\n'
           'techniques = { mesh = {}, coarse = { ratios = [0.3, 0.03, 0.005] } }')
    r, out = bake_and_render(tmp_path, obj, w=160, h=160)
    assert r.exit_code == 0, r.output
    rows = rows_by_label(r)
    mesh = rows["mesh"]
    assert mesh["faces"] == 99785
    assert mesh["mean_dluv"] < 1.0 and mesh["iou"] > 0.999 and mesh["nonfinite"] == 0
    # Coarser meshes are worse: the error grows as the face ratio falls.
    errs = [rows[f"coarse@{r}"]["mean_dluv"] for r in ("0.3", "0.03", "0.005")]
    assert mesh["mean_dluv"] < errs[0] < errs[1] < errs[2]
    assert errs[2] > 2.0  # 500 faces of a bunny cannot look right: the metric sees it
    assert all(row["ratio_to_baseline"] > 0 and row["baseline"] == "mesh" for row in rows.values())
    for name in ("report.json", "report.csv", "error_vs_time.png", "overview/bunny.png",
                 "reference/bunny/000.png", "reference/bunny/000.exr", "frames/bunny/mesh/001.png",
                 "heatmaps/bunny/coarse@0.005/000.png"):
        assert (out / name).is_file(), name
    csv_lines = (out / "report.csv").read_text().splitlines()
    assert csv_lines[0].startswith("object,technique,knob,value,label") and len(csv_lines) == 5


@pytest.mark.parametrize("primitive", ["sphere", "torus", "vase", "cylinder", "plane"])
def test_primitives_match_reference(tmp_path, primitive):
    r, _ = bake_and_render(tmp_path, f'name = "p"\nprimitive = "{primitive}"\ntechniques = {{ mesh = {{}} }}')
    row = rows_by_label(r)["mesh"]
    assert row["mean_dluv"] < 1.0 and row["iou"] > 0.995 and row["nonfinite"] == 0


def test_far_from_origin_wide_fov_and_camera_inside(tmp_path):
    """1e5 units from the origin, a 150-degree field of view and a camera inside the torus's tube."""
    extra = ('[[camera.poses]]\neye = [100001.0, 100000.0, 100000.0]\n'
             'target = [100001.0, 100001.0, 100000.0]\nfov_deg = 150\n')
    obj = ('name = "far"\nprimitive = "torus"\ntransform = { translate = [100000.0, 100000.0, 100000.0] }\n'
           'techniques = { mesh = {} }')
    r, out = bake_and_render(tmp_path, obj, extra=extra)
    row = rows_by_label(r)["mesh"]
    assert row["frames"] == 3 and row["nonfinite"] == 0
    assert row["mean_dluv"] < 1.0 and row["iou"] > 0.99
    # Inside the closed tube every ray hits the wall and no light gets in: the traced reference has
    # full coverage and ambient only. (The shadow map leaks a little light along the light-space
    # silhouette, where both walls' depths meet; that is the frame's measured error above.)
    from vdmbake.formats import exr
    from vdmbake.scene import Light, Material
    from vdmbake.common.colour import to_srgb8

    ref = exr.read(out / "reference/far/002.exr")["reference"]
    assert (ref["A"] == 1).all()
    ambient_only = to_srgb8(np.asarray(Light().ambient) * np.asarray(Material().albedo))
    ref8 = np.asarray(Image.open(out / "reference/far/002.png"))
    assert (np.abs(ref8.astype(int) - ambient_only).max(-1) <= 1).all()
    frame = np.asarray(Image.open(out / "frames/far/mesh/002.png"))
    assert (np.abs(frame.astype(int) - ambient_only).max(-1) <= 1).mean() > 0.95


def test_rerender_reuses_reference_and_is_deterministic(tmp_path):
    r1, out = bake_and_render(tmp_path, 'name = "s"\nprimitive = "sphere"\ntechniques = { mesh = {} }')
    first = {p.relative_to(out): p.read_bytes() for p in out.rglob("*.png") if "frames" in p.parts or "reference" in p.parts}
    r2 = CliRunner().invoke(render_main, [str(tmp_path / "b.bundle"), "-o", str(out), "--json"])
    assert r2.exit_code == 0, r2.output
    assert rows_by_label(r1)["mesh"]["reference_cached"] is False
    assert rows_by_label(r2)["mesh"]["reference_cached"] is True
    second = {p.relative_to(out): p.read_bytes() for p in out.rglob("*.png") if "frames" in p.parts or "reference" in p.parts}
    assert first == second and len(first) == 4
    assert not list(tmp_path.glob(".out.*"))  # no staging folder left behind


def test_max_error_exit_code_and_technique_filter(tmp_path):
    obj = 'name = "s"\nprimitive = "sphere"\ntechniques = { mesh = {}, coarse = { ratios = [0.02] } }'
    r, out = bake_and_render(tmp_path, obj, args=("--max-error", "0.5", "-t", "coarse"))
    assert r.exit_code == 1, r.output  # 2% of a sphere's faces is visibly faceted
    rows = rows_by_label(r)
    assert list(rows) == ["coarse@0.02"] and rows["coarse@0.02"]["mean_dluv"] > 0.5
    assert (out / "report.json").is_file()  # exit 1 still writes the full report
    r = CliRunner().invoke(render_main, [str(tmp_path / "b.bundle"), "-o", str(out), "--max-error", "50"])
    assert r.exit_code == 0, r.output


def test_shader_includes_expand():
    src = gl.source("mesh.frag")
    assert "#include" not in src and "vec3 shade(" in src and "float shadow_lit(" in src
    assert src.lstrip().startswith("#version 430")


def test_unused_programs_are_not_compiled(tmp_path):
    """A scene with only `mesh` compiles the mesh and depth programs and nothing else."""
    from vdmbake.bundle.directory import Bundle
    from vdmbake.scene import parse_scene_dict
    from vdmrender.techniques import variants

    scene = tmp_path / "scene.toml"
    scene.write_text(SMALL.format(w=8, h=8, extra="", obj='name = "s"\nprimitive = "sphere"\ntechniques = { mesh = {} }'))
    assert CliRunner().invoke(bake_main, [str(scene), "-o", str(tmp_path / "b")]).exit_code == 0
    b = Bundle(tmp_path / "b")
    sc = parse_scene_dict(b.manifest["scene"], "manifest")
    ctx = gl.create_context()
    try:
        (v,) = variants(sc.objects[0], b.manifest["objects"]["s"], b, sc)
        v.build(ctx).release()
        assert sorted(ctx.extra) == [("mesh.vert", "depth.frag"), ("mesh.vert", "mesh.frag")]
    finally:
        ctx.release()


def test_wheel_ships_the_shaders(tmp_path):
    """The shaders are found from a built wheel too (vdmrender/shaders is a link to shaders/), and the wheel
    holds exactly the modules and data files of both packages (the technique subpackages were missing from
    `packages`: setuptools shipped them only by a deprecated fallback, with a warning; the benchmarks are not
    shipped)."""
    # built from a copy of the sources: setuptools keeps build/lib in the tree it builds, and a stale one
    # from an earlier build would ship modules deleted since
    src = tmp_path / "src"
    shutil.copytree(ROOT, src, symlinks=True, ignore=shutil.ignore_patterns(
        ".git", ".venv", ".device", "out", "build", "*.egg-info", "__pycache__", ".pytest_cache"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
                    "-w", str(tmp_path), str(src)], check=True, capture_output=True)
    (wheel,) = tmp_path.glob("*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for f in (ROOT / "shaders").rglob("*"):
        if f.is_file():
            assert f"vdmrender/shaders/{f.relative_to(ROOT / 'shaders').as_posix()}" in names
    tree = {f.relative_to(ROOT).as_posix() for package in ("vdmbake", "vdmrender") for f in (ROOT / package).rglob("*")
            if f.suffix in (".py", ".txt") and "shaders" not in f.parts and "__pycache__" not in f.parts}
    # exactly the tree's modules: not the benchmarks (bench/)
    assert {n for n in names if n.endswith((".py", ".txt")) and ".dist-info" not in n} == tree
