"""Open boundaries (VDM sec. 5, issue 10): the shell's side wall along a base mesh's borders
(vdmbake.common.geometry.skirt), the pixel classes the reference and the metric agree on (vdmrender/tracing/borders.py),
and a plane with a real elevation model scored on its surface, its border and inside apart.

Bounds are the figures measured on Mesa llvmpipe with some headroom, the measurement beside them."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.common import geometry
from vdmbake.assets import primitives
from vdmbake.common.embree import RayScene
from vdmbake.assets.meshes import load_mesh_file
from vdmrender.tracing import borders as pixel_classes
from vdmrender.common.camera import Camera
from vdmrender.comparing.metrics import compare

from scenes import bake_and_render, rows_by_label
from meso_scenes import dem, torus_obj, write_png16


def test_skirt_of_a_plane():
    p = primitives.plane(2.0, 4)
    v, f = geometry.skirt(p, 0.05, (2, 2))
    assert len(f) == 2 * 16                                   # 16 border edges, a quad each
    top, bottom = v[: len(v) // 2], v[len(v) // 2:]
    assert np.allclose(top[:, 2], 0.0) and np.allclose(bottom[:, 2], -0.05)   # s_n = 1: a tile is 1 x 1
    assert np.allclose(np.abs(top[:, :2]).max(1), 1.0)        # only the plane's rim


def test_closed_surfaces_and_uv_seams_have_no_border(tmp_path):
    t = primitives.torus(1.0, 0.3, 16, 8)                     # seam columns duplicated, equal up to rounding
    assert len(geometry.skirt(t, 0.05, (4, 1))[1]) == 0
    m = load_mesh_file(torus_obj(tmp_path))                 # split at its UV seams by the loader
    ids = np.arange(len(m.vertices))
    assert len(geometry.boundary_edges(m.faces, ids)) > 0     # keyed by vertex, the seams look open
    from vdmbake.kernels.curvature import estimate_frame
    m.frame = estimate_frame(m.vertices, m.faces, m.normals, m.uvs)
    assert len(geometry.skirt(m, 0.05, (4, 1))[1]) == 0       # welded by position they are not


def test_classify_confined_to_a_closed_sheet_s_box():
    """A closed sheet (no skirt) far in the frame: classes traced only within its bounding sphere's screen box are
    those of every pixel traced (the torus seen through its hole, from behind at the far side: INSIDE pixels)."""
    t = primitives.torus(1.0, 0.3, 24, 12)
    sheet = RayScene(t.vertices, t.faces[:, ::-1])            # wound inwards: what the eye sees is its back
    cam = Camera(np.array([0.5, -9.0, 2.0]), np.array([1.5, 0.0, 0.5]), np.array([0.0, 0.0, 1.0]), 40.0, 64, 64,
                 0.5, 20.0)
    confined = pixel_classes.classify(cam, sheet, None, t.bounding_sphere())
    assert (confined == pixel_classes.INSIDE).sum() > 0
    np.testing.assert_array_equal(confined, pixel_classes.classify(cam, sheet, None))

def test_classify_plane_above_and_below():
    p = primitives.plane(2.0, 4)
    sheet = RayScene(p.vertices - [0, 0, 0.02], p.faces)      # a stand-in for the displaced sheet
    v, f = geometry.skirt(p, 0.05, (2, 2))
    skirt = RayScene(v, f)
    up = np.array([0.0, 0.0, 1.0])
    above = Camera(np.array([0.0, -3.0, 2.1]), np.zeros(3), up, 40.0, 48, 48, 0.5, 10.0)
    c = pixel_classes.classify(above, sheet, skirt)
    assert (c == pixel_classes.INSIDE).sum() == 0
    border = c == pixel_classes.BORDER
    assert 0 < border.sum() < 0.2 * c.size
    assert not border[20:28, 20:28].any()                     # the middle of the plane is its surface
    below = Camera(np.array([0.0, -3.0, -2.1]), np.zeros(3), up, 40.0, 48, 48, 0.5, 10.0)
    c = pixel_classes.classify(below, sheet, skirt)
    assert (c == pixel_classes.INSIDE).sum() > 0.2 * c.size   # the sheet from behind
    assert (c[20:28, 20:28] == pixel_classes.INSIDE).all()


def test_compare_scores_apart():
    ref = np.zeros((2, 3, 4), np.uint8)
    ref[..., 3] = 255
    ref[..., :3] = 100
    frame = ref.copy()
    frame[0, 0] = 0                                           # a missing pixel...
    frame[1, 2, :3] = 200                                     # ...and a wrong one
    classes = np.zeros((2, 3), np.uint8)
    classes[0, 0] = pixel_classes.BORDER
    c = compare(frame, ref, classes)
    assert c["iou"] == 1.0 and c["iou_all"] == 5 / 6
    assert c["apart"] == {1: 1, 2: 0} and c["values"].size == 5 and c["apart_values"].size == 1
    assert c["mean"] < c["mean_all"]
    plain = compare(frame, ref)
    assert plain["mean"] == c["mean_all"] and plain["iou"] == c["iou_all"] and plain["apart"] == {}


SCENE = """\
[render]
resolution = [48, 48]
repeats = 1
warmup = 0
shadow_map = 256
[camera]
orbit = {{ count = 1, elevation_deg = {elev}, azimuth_deg = 30, distance = 2.4, fov_deg = 40 }}
[[objects]]
name = "p"
primitive = "plane"
params = {{ size = 2.0, segments = 4 }}
expect_empty = {expect_empty}
techniques = {{ mesh = {{}}, bump = {{}}, pom = {{ steps = [16] }}, vdm = {{ k = [4] }}, displaced = {{ levels = [3] }} }}
[objects.mesostructure]
height = "dem.png"
size = 32
depth = 0.05
tiling = [1, 1]
phi = 8
theta = 8
curvatures = 4
"""


@pytest.mark.parametrize("elev", [35, -35])
def test_plane_with_an_elevation_model_scores_its_surface(tmp_path, elev):
    """The DEM on a plane at 35 degrees above and below (48^2). Above: every variant's surface pixels covered
    (IoU near 1) and scored below every pixel's error, with border pixels counted apart. Below: no surface
    pixel, the frame empty of surface and its pixels inside, counted apart. Over every pixel together the
    sheet's side wall and back still cost coverage (docs/mesostructure.md has the figures)."""
    write_png16(tmp_path / "dem.png", dem())
    # from below there is no surface pixel to score: expected, not an error
    r, out = bake_and_render(tmp_path, SCENE.format(elev=elev, expect_empty="true" if elev < 0 else "false"),
                             "--no-flip")   # FLIP not looked at here
    assert r.exit_code == 0, r.output
    rows = rows_by_label(r)
    for label, row in rows.items():
        print(label, {k: row[k] for k in ("mean_dluv", "iou", "mean_dluv_all", "iou_all", "surface_px", "border_px",
                                          "inside_px", "mean_dluv_apart")})
    assert (out / "reference/p/000-classes.png").is_file()
    for label in ("vdm@4", "pom@16", "bump", "displaced@3"):
        row = rows[label]
        assert row["border_px"] > 0
        if elev > 0:
            assert row["inside_px"] == 0 and row["surface_px"] > 0.3 * 48 * 48                 # 912
            assert row["iou"] >= 0.995, label                                                   # 0.9989-1.0
            assert row["mean_dluv"] < row["mean_dluv_all"], label
        else:
            assert row["surface_px"] == 0 and row["inside_px"] > 0.3 * 48 * 48, label          # 943
            assert row["empty_frames"] == 1 and row["mean_dluv"] is None and row["mean_dluv_all"] > 0
    if elev > 0:
        for label in ("vdm@4", "pom@16", "bump"):        # the per-pixel methods lose the border only
            assert rows[label]["iou_all"] <= 0.95 and rows[label]["mean_dluv"] <= 1.5, label   # 0.8976; 0.57-1.21
