"""Enhanced billboards, the render side (Vichitvejpaisal 2005, sec. 3.3, 3.4, 4.1): billboards baked by
vdmbake.kernels.billboards, ray-marched through OpenGL (Mesa llvmpipe without a GPU), against the Embree
reference of the full mesh. Bounds sit a little above the values measured on llvmpipe (in comments)."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.errors import InputError
from vdmrender.common import images
from vdmrender.comparing import metrics
from vdmrender.common.camera import Camera, clip_planes
from vdmbake.bundle import parts
from vdmbake.bundle.parts import Billboard
from vdmrender.techniques.billboards import Billboards

from frames import BG, LIGHT, MATERIAL, SHADOW, bordered, model, orbit_camera, render, score


# (mean dLuv bound, IoU bound) per (mesh, method, hit range, coarse): R 128, 96x96, azimuth 30, elevation 25.
BOUNDS = {
    # measured 11.11, 0.872 (holes: sec. 3.4); 9.56 before issue 9, where a hit met from below after the ray
    # entered behind the surface (a false hit beyond a hole, or an open surface's back) was shaded lit
    ("sphere", "thesis", 0.01, False): (12.0, 0.86),
    ("sphere", "thesis", 0.01, True): (1.0, 0.99),      # 0.880, 0.9931
    ("sphere", "thesis", 0.02, False): (4.0, 0.97),     # 3.58, 0.9736
    ("sphere", "thesis", 0.02, True): (1.1, 0.984),     # 0.954, 0.9863
    ("sphere", "improved", 0.01, False): (0.08, 0.999),   # 0.053, 0.9994
    ("sphere", "improved", 0.01, True): (0.17, 0.997),    # 0.053, 0.9994 (0.136, 0.9977 before the seam-safe coarse mesh)
    ("torus", "thesis", 0.01, False): (11.5, 0.90),     # 10.21, 0.9092 (10.47 before issue 9)
    ("torus", "thesis", 0.01, True): (2.3, 0.975),      # 2.07, 0.978
    ("torus", "thesis", 0.02, False): (6.0, 0.94),      # 5.44, 0.9439
    ("torus", "thesis", 0.02, True): (2.9, 0.95),       # 2.64, 0.9549
    ("torus", "improved", 0.01, False): (0.25, 0.998),    # 0.189, 0.9989
    # 0.543, 0.9920; 0.454 before the coarse mesh was welded at the UV seam, where its vertices stayed on the
    # surface (welded, 10% of the faces put vertices up to 0.0147 outside the torus of R = 1, 0.0139 before)
    ("torus", "improved", 0.01, True): (0.60, 0.99),
}


@pytest.mark.parametrize("name", ["sphere", "torus"])
@pytest.mark.slow
def test_methods_against_reference(ctx, name):
    """Both marches, both thesis hit ranges, with and without the coarse mesh (sec. 3.4)."""
    mesh, baked, co = model(name)
    cam = orbit_camera(mesh, 30, 25)
    got = {}
    for method, e in (("thesis", 0.01), ("thesis", 0.02), ("improved", 0.01)):
        for with_coarse in (False, True):
            frame = render(ctx, baked.billboards, cam, method, e, co if with_coarse else None)
            got[method, e, with_coarse] = score(frame, mesh, cam)
    for key, (err, iou) in got.items():
        bound_err, bound_iou = BOUNDS[(name, *key)]
        assert err < bound_err and iou > bound_iou, (key, err, iou)
    # The improved march beats the thesis's at its hit range 0.01, alone and with the coarse mesh.
    assert got["improved", 0.01, False][0] <= got["thesis", 0.01, False][0]
    assert got["improved", 0.01, True][0] <= got["thesis", 0.01, True][0]
    # Sec. 3.4: the coarse mesh fills the thesis march's holes, and doubling e fills some of them too.
    for e in (0.01, 0.02):
        assert got["thesis", e, True][1] >= got["thesis", e, False][1]
        assert got["thesis", e, True][0] <= got["thesis", e, False][0]
    assert got["thesis", 0.02, False][1] > got["thesis", 0.01, False][1]
    # The improved march leaves almost no holes, so there the coarse mesh (whose 10% simplification puts
    # vertices outside the surface) only widens the silhouette: a measured IoU loss of 0.0000 (sphere) and
    # 0.0069 (torus), bounded above; it is no fix for that method.
    assert got["improved", 0.01, False][1] - got["improved", 0.01, True][1] < 0.01


@pytest.mark.slow
def test_camera_inside_boxes(ctx):
    """From the torus's centre, inside the boxes of the billboards that look down on it (and outside the
    mesh), looking at the inner wall of the tube: the ray starts on the near plane, inside the box."""
    mesh, baked, co = model("torus")
    eye = np.zeros(3)
    inside = [np.all((0 <= (eye - b.origin) @ b.axes.T) & ((eye - b.origin) @ b.axes.T <= b.size))
              for b in baked.billboards]
    assert sum(inside) >= 2
    cam = Camera(eye, np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), 70.0, 64, 64,
                 *clip_planes(eye, np.array([1.0, 0.0, 0.0]), np.zeros(3), mesh.bounding_sphere()[1]))
    for method in ("thesis", "improved"):
        err, iou = score(render(ctx, baked.billboards, cam, method), mesh, cam)
        if method == "improved":
            assert err < 0.3 and iou > 0.992, (err, iou)      # measured 0.224, 0.9940
        else:
            assert err < 9.5 and iou > 0.81, (err, iou)       # measured 8.39, 0.8299
    # Inside the closed tube every surface is seen from behind; nothing is hit but the output stays finite.
    inner = Camera(np.array([1.0, 0.0, 0.0]), np.array([1.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), 120.0,
                   64, 64, *clip_planes(np.array([1.0, 0.0, 0.0]), np.array([1.0, 1.0, 0.0]), np.zeros(3), 1.35))
    for method in ("thesis", "improved"):
        assert np.isfinite(render(ctx, baked.billboards, inner, method, coarse_mesh=co)).all()


def test_grazing_view(ctx):
    """Nearly edge-on to the torus (elevation 3 degrees): long, flat rays through the billboards."""
    mesh, baked, co = model("torus")
    cam = orbit_camera(mesh, 20, 3)
    thesis = score(render(ctx, baked.billboards, cam, "thesis"), mesh, cam)
    improved = score(render(ctx, baked.billboards, cam, "improved"), mesh, cam)
    assert improved[0] < 0.25 and improved[1] > 0.998, improved  # measured 0.190, 0.9993
    assert thesis[0] < 8.0 and thesis[1] > 0.92, thesis          # measured 7.00, 0.9348
    assert improved[0] < thesis[0]


def test_far_from_origin(ctx):
    """The sphere 1e5 from the origin: anchor-relative coordinates keep it as good as at the origin."""
    offset = (1e5, -1e5, 1e5)
    near_mesh, near_baked, _ = model("sphere", 64)
    far_mesh, far_baked, _ = model("sphere", 64, offset)
    cam0 = orbit_camera(near_mesh, 30, 25, size=64)
    cam1 = orbit_camera(far_mesh, 30, 25, size=64)
    at_origin = render(ctx, near_baked.billboards, cam0)
    far = render(ctx, far_baked.billboards, cam1)
    err0, iou0 = score(at_origin, near_mesh, cam0)
    err1, iou1 = score(far, far_mesh, cam1)
    assert err0 < 0.09 and iou0 > 0.999, (err0, iou0)   # measured 0.0716, 1.0
    assert err1 < 0.09 and iou1 > 0.999, (err1, iou1)   # measured 0.0716, 1.0 (the same image)
    same = metrics.compare(images.encode(far, BG), images.encode(at_origin, BG))
    assert same["iou"] == 1.0 and same["mean"] < 0.05, same["mean"]   # measured 0.0


def test_bundle_round_trip_and_bounds(ctx):
    """Billboards read back from their bundle part render as the bake's own, and given bounds."""
    mesh, baked, co = model("sphere", 64)
    cam = orbit_camera(mesh, 60, 10, size=64)
    boards = parts.stored(parts.BILLBOARDS, baked.billboards)
    a = render(ctx, baked.billboards, cam, coarse_mesh=co)
    b = render(ctx, boards, cam, coarse_mesh=co)
    assert np.array_equal(a, b)
    c = render(ctx, boards, cam, bounds=mesh.bounding_sphere())
    err, iou = score(c, mesh, cam)
    assert err < 0.11 and iou > 0.999, (err, iou)   # measured 0.086, 0.9997
    r = Billboards(ctx, boards, bordered(boards), LIGHT, MATERIAL, SHADOW, coarse=co)
    assert r.faces == len(co.faces) > 0
    r.release()
    with pytest.raises(InputError):
        Billboards(ctx, boards, bordered(boards), LIGHT, MATERIAL, SHADOW, method="linear")
    with pytest.raises(InputError):
        b1 = boards[1]
        mixed = boards[:1] + [Billboard(b1.origin, b1.axes, b1.size, np.zeros((8, 8)), np.ones((8, 8)),
                                        np.zeros((8, 8, 3)))]
        Billboards(ctx, mixed, bordered(mixed), LIGHT, MATERIAL, SHADOW)


def test_billboards_through_the_command_line(tmp_path):
    """Scene -> bundle -> frames: only the projections and the coarse mesh the variants name are baked,
    and the improved method with hole filling stays close to the reference."""
    import json

    from scenes import TINY_HEAD, bake_and_render, rows_by_label

    scene = TINY_HEAD + """
[[objects]]
name = "torus"
primitive = "torus"
params = { segments = 48, rings = 24 }
techniques = { billboards = { variants = ["greedy-hit0.02", "greedy-improved+coarse"], resolution = 48 } }
"""
    r, out = bake_and_render(tmp_path, scene, "--no-flip", "--no-counters")   # neither looked at here
    assert r.exit_code == 0, r.output
    rows = rows_by_label(r)
    assert set(rows) == {"billboards@greedy-hit0.02", "billboards@greedy-improved+coarse"}
    assert all(row["nonfinite"] == 0 for row in rows.values())
    m = json.loads((tmp_path / "b.bundle" / "manifest.json").read_text())
    entry = m["objects"]["torus"]["techniques"]["billboards"]
    assert set(entry) == {"greedy", "coarse"}                     # no axis projection was asked for
    assert entry["greedy"]["leftover"]["hidden"] == 0 and len(m["parts"][entry["greedy"]["maps"]]["boards"]) >= 2
    # measured at 32x32: improved+coarse 0.89 (IoU 0.9935), the thesis's march at hit range 0.02 5.22 (0.9457)
    assert rows["billboards@greedy-improved+coarse"]["mean_dluv"] < 1.0
    assert rows["billboards@greedy-improved+coarse"]["mean_dluv"] < rows["billboards@greedy-hit0.02"]["mean_dluv"]


@pytest.mark.slow
def test_bench_quick_smoke(tmp_path, no_warm_up):
    """make bench's billboard script runs end to end (a sphere at 200x150, 64-texel maps) and writes its report."""
    import json

    from click.testing import CliRunner

    from bench.billboards import PROFILE, main as bench_main

    r = CliRunner().invoke(bench_main, ["-o", str(tmp_path), "--quick"])
    assert r.exit_code == 0, r.output
    report = json.loads((tmp_path / "billboards.json").read_text())
    labels = {row["label"] for row in report["rows"]}
    assert {"mesh", "coarse@0.1", "billboards@greedy-hit0.01", "billboards@greedy-improved+coarse",
            "billboards@greedy-hier+coarse"} <= labels
    assert all(row["nonfinite"] == 0 for row in report["rows"])
    assert {p["label"] for p in report["profile"]} == set(PROFILE) and set(report["march_cost"]) == {"improved", "hier"}
    assert report["bakes"]["sphere"]["pyramid_mb"] > 0
    assert report["bakes"]["sphere"]["greedy"] >= 1 and report["bakes"]["sphere"]["axis"] >= 1
    assert "| sphere |" in (tmp_path / "billboards.md").read_text()


@pytest.mark.parametrize("source", ['primitive = "plane"', 'mesh = "tri.obj"'], ids=["flat-plane", "single-triangle"])
def test_degenerate_models_render_finite(tmp_path, source):
    """A flat (coplanar) mesh and a single triangle: one billboard each, finite frames, close to the
    reference with the improved march."""
    from scenes import TINY_HEAD, bake_and_render, rows_by_label

    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0.2\nv 0 1 0.1\nf 1 2 3\n")
    scene = TINY_HEAD + f"""
[[objects]]
name = "m"
{source}
techniques = {{ billboards = {{ variants = ["greedy-hit0.01", "greedy-improved"], resolution = 32 }} }}
"""
    r, out = bake_and_render(tmp_path, scene, "--no-flip", "--no-counters")   # neither looked at here
    assert r.exit_code == 0, r.output
    rows = rows_by_label(r)
    assert all(row["nonfinite"] == 0 for row in rows.values())
    # measured (32x32): improved 0.000 / IoU 1.0 on both; hit0.01 0.35 (plane) and 3.27 (triangle, IoU 0.95)
    assert rows["billboards@greedy-improved"]["mean_dluv"] < 0.05 and rows["billboards@greedy-improved"]["iou"] > 0.999
    assert rows["billboards@greedy-hit0.01"]["mean_dluv"] < 4.0
