"""Technique `relief` end to end through OpenGL: the exact hierarchical tracer (heightfield_trace.glsl)
per pixel over the base mesh, against the Embree-traced displaced reference, beside pom, displaced and the
plain mesh. The stiff cases of test_vdm_render.py: views along the normal and at grazing angles, the light
at the horizon, vertical cliffs, all-top and all-bottom height fields, zero depth; the iteration cap; and
the bake's 'leave out' rule (the pyramid only for scenes that render relief).

Every bound below is the figure measured on Mesa llvmpipe (2-core machine) with some headroom, the
measurement in a comment beside it."""
from __future__ import annotations


import numpy as np
import pytest
from PIL import Image

from vdmbake.bundle import parts
from vdmbake.bundle.directory import Bundle

import meso_scenes
from meso_scenes import BIG_PLANE, GRAZING, OBLIQUE, ORBIT, PLANE, TOP, TORUS, centre_dluv, manifest, mean, render

ALL = 'mesh = {}, relief = { iterations = [32] }, pom = { steps = [16] }, displaced = { levels = [1] }'


def scene(camera, obj, techniques=ALL, **kw):
    return meso_scenes.scene(camera, obj, techniques, **kw)


def stage_errors(tmp_path, out, *defines_list, iterations=32):
    """(mean dLuv, IoU) of relief.frag compiled with each tuple of defines (e.g. ("FLAT",)) on the scene's
    cameras, against the reference the CLI run traced."""
    from vdmbake.formats import exr
    from vdmbake.scene import parse_scene_dict
    from vdmrender.gpu import gl
    from vdmrender.common import images
    from vdmrender.common.camera import cameras_for
    from vdmrender.comparing.metrics import compare
    from vdmrender.common.source import Source
    from vdmrender.techniques.relief import ReliefPass
    b = Bundle(tmp_path / "b.bundle")
    sc = parse_scene_dict(b.manifest["scene"], "manifest")
    obj, entry = sc.objects[0], b.manifest["objects"]["p"]
    w, h = sc.render.resolution
    cams = cameras_for(sc.camera, entry["centre"], entry["radius"], w, h)
    bg = sc.render.background
    refs = [images.encode(np.stack([exr.read(out / f"reference/p/{k:03d}.exr")["reference"][c] for c in "RGBA"], -1),
                          bg) for k in range(len(cams))]
    ctx = gl.create_context()
    target = gl.Target(ctx, w, h)
    result = []
    try:
        for defines in defines_list:
            src = Source(obj, entry, entry["techniques"]["relief"], b, sc, obj.techniques["relief"])
            r = ReliefPass(ctx, src, iterations, defines=defines)
            ms = []
            for cam, ref in zip(cams, refs):
                r.render(cam, target)
                frame = target.read()
                assert np.isfinite(frame).all()
                ms.append(compare(images.encode(frame, bg), ref))
            r.release()
            values = np.concatenate([m["values"] for m in ms])
            result.append((float(values.mean()), float(np.mean([m["iou"] for m in ms]))))
    finally:
        target.release()
        ctx.release()
    return result


# ----------------------------------------------------------------------------- baseline and knob

def test_torus_bricks_baseline(tmp_path):
    """Bricks on a torus, 64^2, two orbit frames; the iteration cap from starved to enough: relief@32 within its
    bound, below pom@16 below the plain mesh and under half of displaced@1's error, 12 visits nearly enough and
    4 not, a better outline than pom's (bent rays); the pyramid part wraps, holds the depths and their min/max
    at every level."""
    text = scene(ORBIT.format(count=2), TORUS, 'mesh = {}, relief = { iterations = [4, 12, 32] }, '
                 'pom = { steps = [16] }, displaced = { levels = [1] }', size=32, tiling=(8, 2), res=64,
                 shadow_map=512)
    rows, _ = render(tmp_path, text)
    assert set(rows) == {"mesh", "relief@4", "relief@12", "relief@32", "pom@16", "displaced@1"}
    assert mean(rows, "relief@32") <= 1.15                                    # 0.966
    assert mean(rows, "relief@32") < mean(rows, "pom@16") < mean(rows, "mesh")
    assert mean(rows, "relief@32") < 0.5 * mean(rows, "displaced@1")         # 2.775
    assert mean(rows, "relief@32") <= mean(rows, "relief@12") + 0.02         # 1.007: 12 visits nearly enough
    assert mean(rows, "relief@12") < 0.6 * mean(rows, "relief@4")            # 2.440: 4 are not
    assert rows["relief@32"]["iou"] >= rows["pom@16"]["iou"] + 0.005          # 0.9985 vs 0.9912: bent rays
    m = manifest(tmp_path)
    obj = m["objects"]["p"]
    rel = obj["techniques"]["relief"]["pyramid"]
    assert m["parts"][rel]["mode"] == "wrap" and m["parts"][rel]["levels"] == 6    # 32 cells: 32, 16, ..., 1
    b = Bundle(tmp_path / "b.bundle")
    p = b.read(rel, parts.PYRAMID)
    h = b.read(obj["mesostructure"], parts.MESOSTRUCTURE).heights
    assert np.allclose(p.samples, 0.06 * (1.0 - h), atol=1e-7)
    assert p.levels[-1][0, 0, 0] == p.samples.min() and p.levels[-1][0, 0, 1] == p.samples.max()


def test_no_pyramid_without_relief(tmp_path):
    """The 'leave out' rule: a mesostructure not drawn by relief bakes no pyramid."""
    render(tmp_path, scene(OBLIQUE, PLANE, "pom = { steps = [8] }"))
    m = manifest(tmp_path)
    assert "relief" not in m["objects"]["p"]["techniques"]
    assert "pyramid" not in {p["kind"] for p in m["parts"].values()}


# ----------------------------------------------------------------------------- views

def test_view_along_the_normal_on_a_plane(tmp_path):
    """theta_V = 0 at the centre pixel (33^2, odd): the ray straight down, no x, y motion; relief covers exactly
    the plane, within its bound, and the centre pixel is right."""
    rows, out = render(tmp_path, scene(TOP, PLANE, res=33))
    assert rows["relief@32"]["iou"] == 1.0
    assert mean(rows, "relief@32") <= 0.12                                    # 0.089
    assert centre_dluv(out, "relief@32") <= 0.5                                # 0.0


def test_grazing_view(tmp_path):
    """theta_V up to 88.5 degrees on an 8 x 8 plane: long rays across many tiles; relief stays within its bound,
    a tenth of pom's error."""
    rows, _ = render(tmp_path, scene(GRAZING, BIG_PLANE, tiling=(8, 8)))
    assert mean(rows, "relief@32") <= 0.08                                    # 0.049
    assert mean(rows, "relief@32") < 0.1 * mean(rows, "pom@16")              # 1.277


# ----------------------------------------------------------------------------- light

@pytest.mark.parametrize("direction,bound", [
    ("[1, 0, 0]", 0.05),       # measured 0.025, the mesh's (everything but the ambient is dark)
    ("[1, 0, -0.01]", 0.05),   # measured 0.000
    ("[1, 0, 0.01]", 0.1),     # measured 0.052 (pom@16 0.216, displaced@1 1.353)
])
def test_light_at_the_horizon(tmp_path, direction, bound):
    """The light in the tangent plane, just below and just above it (shadow rays up to 100 tiles long)."""
    rows, _ = render(tmp_path, scene(OBLIQUE, PLANE, light=f"[light]\ndirection = {direction}\n"))
    assert mean(rows, "relief@32") <= bound
    if direction != "[1, 0, 0.01]":
        assert mean(rows, "relief@32") == pytest.approx(mean(rows, "mesh"), abs=0.01)


# ----------------------------------------------------------------------------- height fields

def test_cliffs_on_a_torus(tmp_path):
    """Vertical walls and a one-texel slot on a curved surface: relief within its bound, far below pom in mean
    ΔLuv and IoU; the same stage with straight rays (FLAT) is clearly worse than with bent ones."""
    rows, out = render(tmp_path, scene(ORBIT.format(count=2), TORUS, height="cliffs", tiling=(8, 2)))
    assert mean(rows, "relief@32") <= 2.5                                     # 2.161
    assert mean(rows, "relief@32") < 0.4 * mean(rows, "pom@16")              # 7.186
    assert rows["relief@32"]["iou"] >= rows["pom@16"]["iou"] + 0.05          # 0.9748 vs 0.9006
    (bent, bent_iou), (flat, flat_iou) = stage_errors(tmp_path, out, (), ("FLAT",))
    assert bent == pytest.approx(mean(rows, "relief@32"), abs=1e-3)          # the same stage as the CLI's
    assert bent < 0.6 * flat and bent_iou > flat_iou + 0.03


def test_cliffs_on_a_plane(tmp_path):
    """Cliffs 0.15 deep, seen obliquely: relief within its bound (what remains is the reference's half-texel
    triangles against the bilinear patches at the walls)."""
    rows, _ = render(tmp_path, scene(OBLIQUE, PLANE, height="cliffs", depth=0.15))
    assert mean(rows, "relief@32") <= 0.3                                     # 0.224


@pytest.mark.parametrize("shape", ["plane", "torus"])
@pytest.mark.parametrize("what", ["flat", "depth 0"])
def test_no_relief_renders_the_base_surface(tmp_path, what, shape):
    """All-one heights, or depth 0: the mesostructure is the base surface itself, and relief@32 equals the plain
    mesh (error and coverage)."""
    obj, cam, tiling = (PLANE, OBLIQUE, (2, 2)) if shape == "plane" else (TORUS, ORBIT.format(count=2), (8, 2))
    kw = {"height": "flat"} if what == "flat" else {"depth": 0.0}
    rows, _ = render(tmp_path, scene(cam, obj, 'mesh = {}, relief = { iterations = [32] }', tiling=tiling, **kw))
    assert mean(rows, "relief@32") == pytest.approx(mean(rows, "mesh"), abs=0.05)
    assert rows["relief@32"]["iou"] >= rows["mesh"]["iou"] - 1e-3


def test_all_zero_heights(tmp_path):
    """An 8-bit PNG all zero but one texel (heights are normalised by min / max, so a constant image would have
    no relief): the surface lies at the floor, an offset surface inside the torus. Its outline comes from the
    bent view rays (a flat-frame tracer, like POM, has none): relief within its bound and far below pom, and
    bent rays far better than straight ones."""
    img = np.zeros((16, 16), np.uint8)
    img[8, 8] = 255
    Image.fromarray(img).save(tmp_path / "zeros.png")
    rows, out = render(tmp_path, scene(ORBIT.format(count=2), TORUS, height="zeros.png", tiling=(8, 2)))
    assert mean(rows, "relief@32") <= 3.0                                     # 2.530
    assert rows["relief@32"]["iou"] >= 0.95                                   # 0.9572
    assert mean(rows, "relief@32") < 0.3 * mean(rows, "pom@16")              # 9.867
    (bent, bent_iou), (flat, flat_iou) = stage_errors(tmp_path, out, (), ("FLAT",))
    assert bent < 0.4 * flat and bent_iou > flat_iou + 0.1


def test_back_faces_follow_the_winding():
    """relief's frame pass culls the faces its stage would discard: back faces of a consistently wound mesh,
    front faces of one wound the other way, nothing for a mixed one."""
    from vdmbake.assets import primitives
    from vdmbake.common.mesh import TriMesh
    from vdmrender.passes.mesostructure import back_faces
    m = primitives.build("torus", {"major": 1.0, "minor": 0.35, "segments": 16, "rings": 8})
    assert back_faces(m) == "back"
    flipped = TriMesh(m.vertices, m.faces[:, ::-1].copy(), m.normals, m.uvs)
    assert back_faces(flipped) == "front"
    mixed = TriMesh(m.vertices, np.concatenate([m.faces[:10], flipped.faces[10:]]), m.normals, m.uvs)
    assert back_faces(mixed) is None


@pytest.mark.parametrize("size", [16, 20])
def test_non_power_of_two_fields(tmp_path, size):
    """A 20^2 field (its pyramid 20, 10, 5, 3, 2, 1 cells per side, the GL mip chain padded to 32) renders as
    exactly as a 16^2 one: as close to the reference as a dense POM (64 steps, near exact on a plane)."""
    rows, _ = render(tmp_path, scene(OBLIQUE, PLANE, 'relief = { iterations = [32] }, pom = { steps = [64] }',
                                     size=size))
    assert mean(rows, "relief@32") <= 0.15                                    # 0.067, 0.119
    assert mean(rows, "relief@32") <= mean(rows, "pom@64") + 0.02
    m = manifest(tmp_path)
    assert m["parts"][m["objects"]["p"]["techniques"]["relief"]["pyramid"]]["levels"] == (5 if size == 16 else 6)
