"""The mesostructure techniques end to end through OpenGL (vdm, pom, bump, displaced): bake a scene,
render it, compare against the Embree-traced, truly displaced reference. A baseline torus, then the
stiff cases of VDM's per-pixel algorithm (sec. 3.2): views along the normal (the paper's c_V is
0/0 there) and at grazing angles, the light at the horizon, curvatures outside the table, vertical
cliffs, all-top and all-bottom height fields, zero depth, k above the SVD's rank; and the bake's
'leave out' rule (a plane gets one curvature sample, an object without vdm no VDM tables); no false
self-shadows under a low light; the refined VDM (refine knob) against the paper's and POM.

Every bound below is the figure measured on Mesa llvmpipe (2-core machine) with some headroom, the
measurement in a comment beside it."""
from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from vdmbake.bundle import parts
from vdmbake.kernels import vdm
from vdmbake.bundle.directory import Bundle

import meso_scenes
from meso_scenes import (BIG_PLANE, CYLINDER, GRAZING, HEAD_ON, OBLIQUE, ORBIT, PLANE, TOP, TORUS, centre_dluv,
                         manifest, mean, render)

ALL = 'mesh = {}, vdm = { k = ["all"] }, pom = { steps = [16] }, bump = {}'


def scene(camera, obj, techniques=ALL, **kw):
    return meso_scenes.scene(camera, obj, techniques, **kw)


# ----------------------------------------------------------------------------- baseline

@pytest.mark.slow
def test_torus_bricks_baseline(tmp_path):
    """Bricks on a torus, 64^2, two orbit frames: vdm and pom within their bounds of the displaced reference,
    more eigenfunctions no worse, every vdm below bump below the plain mesh, vdm's IoU at least bump's; the bake
    keeps the k asked (all: the rank) and its truncation error falls with k."""
    text = scene(ORBIT.format(count=2), TORUS, 'mesh = {}, vdm = { k = [2, 8, "all"] }, pom = { steps = [16] }, '
                 'bump = {}, displaced = { levels = [1] }', size=32, tiling=(8, 2), res=64, shadow_map=512)
    rows, _ = render(tmp_path, text)
    assert set(rows) == {"mesh", "vdm@2", "vdm@8", "vdm@all", "pom@16", "bump", "displaced@1"}
    vdms = [mean(rows, k) for k in ("vdm@2", "vdm@8", "vdm@all")]
    assert mean(rows, "vdm@all") <= mean(rows, "vdm@2") + 0.1         # 2.682 vs 3.384
    assert mean(rows, "vdm@8") <= mean(rows, "vdm@2") + 0.1           # 2.764 vs 3.384
    assert max(vdms) < mean(rows, "bump") < mean(rows, "mesh")        # 3.384 < 4.300 < 6.261
    assert mean(rows, "pom@16") < mean(rows, "bump")                  # 2.824 < 4.300
    assert mean(rows, "vdm@all") <= 3.0                               # 2.682
    assert mean(rows, "pom@16") <= 3.1                                # 2.824
    # silhouettes: VDM's MVM cuts the base mesh's outline where the mesostructure is not hit
    assert rows["vdm@all"]["iou"] >= rows["bump"]["iou"]              # 0.9921 vs 0.9883
    # the displaced mesh has the reference's silhouette
    assert rows["displaced@1"]["iou"] >= 0.998                        # 0.9995
    assert mean(rows, "vdm@all") <= mean(rows, "displaced@1") + 0.2   # 2.682 vs 2.775
    meso = manifest(tmp_path)["objects"]["p"]["techniques"]["vdm"]
    assert meso["k"] == meso["rank"] <= 8 * 4 + 4                     # "all": every eigenfunction, 31 of 36 columns
    assert len(meso["curvatures"]) == 4
    errors = meso["errors"]
    assert sorted(errors, key=int) == ["2", "8", str(meso["rank"])]
    by_k = [errors[k] for k in sorted(errors, key=int)]
    # measured rms_vdm 0.043744, 0.007066, 4e-6; rms_mvm 0.023214, 0.008852, 0; max 0.5126, 0.2816, 0.000179
    for a, b in zip(by_k, by_k[1:]):
        assert b["energy"] >= a["energy"]
        assert b["rms_vdm"] < a["rms_vdm"] and b["rms_mvm"] <= a["rms_mvm"] and b["max_abs_vdm"] < a["max_abs_vdm"]
    assert by_k[-1]["rms_vdm"] < 1e-4 and by_k[-1]["energy"] == 1.0


# ----------------------------------------------------------------------------- views

def test_view_along_the_normal_on_a_plane(tmp_path):
    """theta_V = 0 at the centre pixel (33^2, odd): V parallel to N, the paper's c_V a 0/0. vdm covers exactly
    the plane, stays within its bound, below bump below the plain mesh, and the centre pixel is right; the plane
    gets one curvature sample."""
    rows, out = render(tmp_path, scene(TOP, PLANE, res=33))
    assert rows["vdm@all"]["coverage"] == 1.0 and rows["vdm@all"]["iou"] == 1.0
    assert mean(rows, "vdm@all") <= 0.2                               # 0.119
    assert mean(rows, "vdm@all") < mean(rows, "bump") < mean(rows, "mesh")
    assert centre_dluv(out, "vdm@all") <= 0.5                          # 0.0
    # the 'leave out' rule: a plane's table has the one curvature 0
    assert manifest(tmp_path)["objects"]["p"]["techniques"]["vdm"]["curvatures"] == [0.0]


def test_view_along_the_normal_on_a_curved_surface(tmp_path):
    """The same at a cylinder's side (c = 0.49 around it in texture units): V = N with curvature; vdm within its
    bound, and at the centre pixel vdm and bump agree (the mesostructure's shading normal there, not the
    lookup)."""
    rows, out = render(tmp_path, scene(HEAD_ON, CYLINDER, tiling=(8, 2), res=33))
    assert mean(rows, "vdm@all") <= 0.8                                # 0.541
    assert mean(rows, "vdm@all") < mean(rows, "mesh")                  # 3.857
    assert abs(centre_dluv(out, "vdm@all") - centre_dluv(out, "bump")) <= 0.1   # 2.308 both
    assert centre_dluv(out, "vdm@all") <= 3.0


def test_grazing_view(tmp_path):
    """theta_V up to 88.5 degrees, beyond the table's last theta sample (84.4): vdm within its bound and below
    bump."""
    rows, _ = render(tmp_path, scene(GRAZING, BIG_PLANE, tiling=(8, 8)))
    assert mean(rows, "vdm@all") <= 1.0                               # 0.748
    assert mean(rows, "vdm@all") < mean(rows, "bump")                 # 2.726


# ----------------------------------------------------------------------------- light

@pytest.mark.parametrize("direction,bound", [
    ("[1, 0, 0]", 0.1),        # measured 0.025, exactly the mesh's (everything but the ambient is dark)
    ("[1, 0, -0.01]", 0.05),   # measured 0.000, the mesh's too
    ("[1, 0, 0.01]", 0.85),    # measured 0.693 (pom@16 0.216, bump 1.276, mesh 1.403); 1.129 with false shadows
])
def test_light_at_the_horizon(tmp_path, direction, bound):
    """The light in the tangent plane (L.z = 0: theta_L = 90 degrees), just below and just above it
    (the VDM shadow lookup then starts h / L.z = up to 6 tiles away)."""
    rows, _ = render(tmp_path, scene(OBLIQUE, PLANE, light=f"[light]\ndirection = {direction}\n"))
    assert mean(rows, "vdm@all") <= bound
    if direction != "[1, 0, 0.01]":
        # no direct light on the base surface: vdm and pom shade with the ambient only, like the mesh
        assert mean(rows, "vdm@all") == pytest.approx(mean(rows, "mesh"), abs=0.01)
        assert mean(rows, "pom@16") == pytest.approx(mean(rows, "mesh"), abs=0.01)
    else:
        assert mean(rows, "vdm@all") < mean(rows, "mesh")


# ----------------------------------------------------------------------------- curvature

def test_curvature_outside_the_table(tmp_path):
    """curvatures = 1: the table has the single sample lo = -0.535 (the torus's most concave texture curvature)
    and every other curvature clamps to it; vdm stays within its bound and below bump."""
    rows, _ = render(tmp_path, scene(ORBIT.format(count=2), TORUS, tiling=(8, 2), curvatures=1, res=64))
    meso = manifest(tmp_path)["objects"]["p"]["techniques"]["vdm"]
    assert meso["curvatures"] == [pytest.approx(-0.5351586, abs=1e-6)]
    assert mean(rows, "vdm@all") <= 2.1                               # 1.765
    assert mean(rows, "vdm@all") < mean(rows, "bump")                 # 2.152


# ----------------------------------------------------------------------------- height fields

def test_cliffs_on_a_torus(tmp_path):
    """Vertical walls (0 to 1 between neighbouring texels) and a one-texel slot, on a curved surface: vdm within
    its bound and below pom, in mean ΔLuv and in IoU."""
    rows, _ = render(tmp_path, scene(ORBIT.format(count=2), TORUS, ALL + ", displaced = { levels = [1] }",
                                     height="cliffs", tiling=(8, 2)))
    assert mean(rows, "vdm@all") <= 4.8                               # 4.307
    assert mean(rows, "vdm@all") < mean(rows, "pom@16")               # 6.759
    assert rows["vdm@all"]["iou"] >= 0.962                            # 0.9716
    assert rows["vdm@all"]["iou"] > rows["pom@16"]["iou"] + 0.03      # 0.9006


def test_cliffs_on_a_plane(tmp_path):
    """Cliffs 0.15 deep, seen obliquely: vdm within its bound and below bump."""
    rows, _ = render(tmp_path, scene(OBLIQUE, PLANE, height="cliffs", depth=0.15))
    assert mean(rows, "vdm@all") <= 1.1                               # 0.947
    assert mean(rows, "vdm@all") < mean(rows, "bump")                 # 2.487


@pytest.mark.parametrize("shape", ["plane", "torus"])
@pytest.mark.parametrize("what", ["flat", "depth 0"])
def test_no_relief_renders_the_base_surface(tmp_path, what, shape):
    """All-one heights, or depth 0: the mesostructure is the base surface itself, so vdm must match the plain
    mesh technique (on the plane exactly; on the torus within the bound left by the bake's outline, see
    test_no_relief_tables_on_a_convex_surface)."""
    obj, cam, tiling = (PLANE, OBLIQUE, (2, 2)) if shape == "plane" else (TORUS, ORBIT.format(count=2), (8, 2))
    kw = {"height": "flat"} if what == "flat" else {"depth": 0.0}
    rows, _ = render(tmp_path, scene(cam, obj, tiling=tiling, **kw))
    assert mean(rows, "pom@16") == pytest.approx(mean(rows, "mesh"), abs=0.05)
    assert mean(rows, "bump") == pytest.approx(mean(rows, "mesh"), abs=0.05)
    assert rows["vdm@all"]["iou"] >= rows["mesh"]["iou"] - 1e-3, "vdm drops pixels of the base surface"
    assert mean(rows, "vdm@all") <= mean(rows, "mesh") + 0.05


@pytest.mark.parametrize("what", ["flat", "depth 0"])
def test_no_relief_tables_on_a_convex_surface(what):
    """The cause of the torus's lost outline pixels, in the bake: with every hit at the entry point (d = 0), a
    ray at any theta up to 90 degrees hits, also on a convex surface; the MVM must be pi / 2 and no entry -1
    (vdm_curved_rows: has_hi is false when the last kept sample's angle equals theta_j exactly, as it does for d
    = 0, th' = th, and the SVD then stores the MVM angle there as d)."""
    heights, depth = (np.ones((8, 8)), 0.06) if what == "flat" else (np.full((8, 8), 0.5), 0.0)
    s = vdm.Sampling(8, 8, 8, (-0.5, 0.0, 1.0, 4.0))
    table, theta_mvm, _ = vdm.bake_tables(heights, depth, s)
    bad = table < 0
    assert not bad.any(), (f"-1 entries at curvatures {sorted({s.curvatures[i] for i in np.nonzero(bad)[-1]})}, "
                           f"theta samples {sorted(set(np.nonzero(bad)[3].tolist()))}")
    assert np.abs(table).max() < 1e-6
    assert np.allclose(theta_mvm, np.pi / 2), f"MVM from {np.degrees(theta_mvm.min()):.3f} degrees"


def test_all_zero_heights(tmp_path):
    """An 8-bit PNG all zero but one texel (heights are normalised by min / max, and a constant image has no
    relief): the surface lies at the floor, depth * s_n inside the torus, an offset surface, save one small bump
    per tile. vdm within its bound and under half of pom's error (pom has no silhouettes); displaced, which has
    the offset surface's outline, near exact. (VDM's outline comes early: the curved tables' horizon at c = 1
    lies below the angle up to which the floor is visible.)"""
    img = np.zeros((16, 16), np.uint8)
    img[8, 8] = 255
    Image.fromarray(img).save(tmp_path / "zeros.png")
    rows, _ = render(tmp_path, scene(ORBIT.format(count=2), TORUS, ALL + ", displaced = { levels = [1] }",
                                     height="zeros.png", tiling=(8, 2)))
    bundle = Bundle(tmp_path / "b.bundle")
    assert np.count_nonzero(bundle.read(bundle.manifest["objects"]["p"]["mesostructure"], parts.MESOSTRUCTURE).heights) == 1
    assert mean(rows, "vdm@all") <= 5.0                               # 4.503
    assert rows["vdm@all"]["iou"] >= 0.96                             # 0.9692
    assert mean(rows, "vdm@all") < 0.5 * mean(rows, "pom@16")         # 9.867: pom has no silhouettes
    assert mean(rows, "displaced@1") <= 0.25 and rows["displaced@1"]["iou"] >= 0.999


# ----------------------------------------------------------------------------- SVD and the bake's rules

def test_k_above_the_rank(tmp_path):
    """k = 256 asks for more eigenfunctions than A has columns (theta x c + c = 36): the bake keeps rank of them
    (nearly lossless), and the render uses those, within vdm@all's bound."""
    rows, _ = render(tmp_path, scene(ORBIT.format(count=2), TORUS, 'vdm = { k = [256] }, bump = {}', tiling=(8, 2)))
    meso = manifest(tmp_path)["objects"]["p"]["techniques"]["vdm"]
    assert meso["k"] == meso["rank"] <= 8 * 4 + 4
    assert list(meso["errors"]) == [str(meso["rank"])]
    assert meso["errors"][str(meso["rank"])]["rms_vdm"] < 1e-4
    assert set(rows) == {"vdm@256", "bump"}
    assert mean(rows, "vdm@256") <= 2.1                               # 1.848


def test_object_without_vdm_gets_no_tables(tmp_path):
    """The 'leave out' rule: a mesostructure drawn only by bump bakes the height field and nothing of VDM."""
    rows, _ = render(tmp_path, scene(OBLIQUE, PLANE, "bump = {}"))
    m = manifest(tmp_path)
    obj = m["objects"]["p"]
    assert obj["mesostructure"] == "objects/p/mesostructure.exr" and obj["techniques"] == {}
    assert "vdm" not in {p["kind"] for p in m["parts"].values()}
    assert not (tmp_path / "b.bundle" / "objects" / "p" / "vdm.exr").exists()
    assert list(rows) == ["bump"] and mean(rows, "bump") <= 2.0       # measured 1.339 (oblique bricks)


# ----------------------------------------------------------------------------- false self-shadows

def dark_fractions(tmp_path, out, label):
    """Over the pixels both cover, the fraction shaded with the ambient only (shadowed, or facing away
    from the light) in the frame but not in the reference (false dark), and the reverse (missed dark)."""
    from vdmrender.common.images import encode

    sc = json.loads((tmp_path / "b.bundle/manifest.json").read_text())["scene"]
    amb = np.array(sc["light"]["ambient"]) * np.array(sc["objects"][0]["material"]["albedo"])
    amb8 = encode(np.array([[[*amb, 1.0]]], np.float32), (0, 0, 0))[0, 0, :3].astype(int)
    bg8 = encode(np.zeros((1, 1, 4), np.float32), sc["render"]["background"])[0, 0, :3].astype(int)
    false_dark = missed = n = 0
    for ref_png in sorted((out / "reference/p").glob("[0-9][0-9][0-9].png")):
        ref = np.asarray(Image.open(ref_png))[..., :3].astype(int)
        img = np.asarray(Image.open(out / f"frames/p/{label}/{ref_png.name}"))[..., :3].astype(int)
        both = (np.abs(ref - bg8).max(-1) > 0) & (np.abs(img - bg8).max(-1) > 0)
        d_img, d_ref = (np.abs(img - amb8).max(-1) <= 1) & both, (np.abs(ref - amb8).max(-1) <= 1) & both
        false_dark += (d_img & ~d_ref).sum()
        missed += (d_ref & ~d_img).sum()
        n += both.sum()
    return false_dark / n, missed / n


@pytest.mark.parametrize("height", ["skimage:gravel", "bricks"])
def test_no_false_self_shadows_under_a_low_light(tmp_path, height):
    """The light 0.6 degrees above the horizon, beyond the tables' last polar angle (84.4 degrees): the lookup
    toward the light used to return the clamped, steeper ray's hit, short of P', so the test d_L < h /
    cos(theta_L) - eps shadowed most lit pixels. Now the light's angle is clamped to the sampled ones before the
    shadow ray is built: the share of falsely dark and of missed dark pixels stays within the bounds, as pom's
    does, on the gravel photo and on bricks."""
    text = scene(OBLIQUE, PLANE, 'vdm = { k = ["all"] }, pom = { steps = [16] }', height=height,
                 light="[light]\ndirection = [1, 0, 0.01]\n")
    rows, out = render(tmp_path, text)
    (false_vdm, missed_vdm), (false_pom, missed_pom) = (dark_fractions(tmp_path, out, v) for v in ("vdm@all", "pom@16"))
    print(f"false dark vdm {false_vdm:.4f} pom {false_pom:.4f}; missed dark vdm {missed_vdm:.4f} pom {missed_pom:.4f}")
    assert false_vdm <= 0.01
    assert missed_vdm <= missed_pom + 0.03


# ----------------------------------------------------------------------------- refined VDM

def test_refine_brings_vdm_below_pom(tmp_path):
    """refine = R finishes the lookup's hit on the height field (R + 1 samples and a secant step) and tests
    self-shadows with R samples toward the light. Torus, bricks, 64^2, k = 8: the error falls with R, and
    vdm@8r4 comes well below pom@16 and displaced@1 with no less coverage than vdm@8."""
    text = scene(ORBIT.format(count=2), TORUS, 'vdm = { k = [8], refine = [0, 1, 2, 4] }, pom = { steps = [16] }, '
                 'displaced = { levels = [1] }', size=32, tiling=(8, 2), res=64, shadow_map=512)
    rows, _ = render(tmp_path, text)
    assert set(rows) == {"vdm@8", "vdm@8r1", "vdm@8r2", "vdm@8r4", "pom@16", "displaced@1"}
    assert rows["vdm@8r4"]["value"] == "8r4" and rows["vdm@8r4"]["knob"] == "k"
    assert mean(rows, "vdm@8r4") < mean(rows, "vdm@8r2") < mean(rows, "vdm@8")
    assert mean(rows, "vdm@8r4") <= 2.1
    assert mean(rows, "vdm@8r4") < mean(rows, "pom@16") - 0.5
    assert mean(rows, "vdm@8r4") < mean(rows, "displaced@1") - 0.5
    assert rows["vdm@8r4"]["iou"] >= rows["vdm@8"]["iou"]


def test_costs_per_fragment(tmp_path):
    """The cost counters (vdmrender/measuring/counters.py) of vdm.frag at k = 8 (two RGBA groups), per what a fragment
    does past its V.z test: the view ray is a search, and so is the light ray where the light is above the
    surface. The paper's algorithm (refine 0) looks each up with 2 x 2 weight fetches (phi interpolated) and 2 x
    2 eigenfunction fetches; unless the MVM says miss, the height at T', the normal and the shadow map follow:
    fetches - 8 searches lies in [0, 3 view searches], and nothing steps. Refined (refine 4): the view lookup
    with the nearest phi (2 + 4 fetches), 5 height samples along the view ray, 4 toward the light where lit,
    each a step and a fetch, then the 3: view searches V = steps - 4 searches, light searches 5 searches -
    steps, and fetches - 6 V - steps in [0, 3 V]."""
    from bench.interleave import scene_of
    from vdmrender.measuring import counters
    from vdmrender.gpu import gl
    from vdmrender.common.source import Source
    from vdmrender.techniques.vdm import VDMPass

    text = scene(ORBIT.format(count=1), TORUS, 'vdm = { k = [8] }', size=16, tiling=(8, 2), res=32)
    (tmp_path / "s.toml").write_text(text)
    from vdmbake.bake import bake

    bake(tmp_path / "s.toml", tmp_path / "b.bundle")
    bundle, sc, obj, entry, cams = scene_of(tmp_path / "b.bundle")
    src = Source(obj, entry, entry["techniques"]["vdm"], bundle, sc, obj.techniques["vdm"])
    ctx = gl.create_context()
    try:
        with counters.counting(ctx):
            built = [VDMPass(ctx, src, 8, r) for r in (0, 4)]
        target = gl.Target(ctx, cams[0].width, cams[0].height)
        paper, refined = (counters.count_frames(ctx, p, cams, target)["passes"]["frame"] for p in built)
    finally:
        ctx.release()
    print(paper, refined)
    n = paper["fragments"]
    assert paper["steps"] == 0 and 0 < paper["searches"] <= 2 * n
    assert 0 <= paper["fetches"] - 8 * paper["searches"] <= 3 * n
    views, lit = refined["steps"] - 4 * refined["searches"], 5 * refined["searches"] - refined["steps"]
    assert 0 < lit <= views <= refined["fragments"]
    assert 0 <= refined["fetches"] - 6 * views - refined["steps"] <= 3 * views


def test_more_layers_than_the_device_has_is_refused(tmp_path, monkeypatch):
    """W's texture array holds ceil(k / 4) x phi layers; over the device's GL_MAX_ARRAY_TEXTURE_LAYERS the
    driver drew garbage and the run exited 0. Now it exits 2 naming the limit: shown by lowering the limit the
    device reports to below what a small table needs."""
    import moderngl

    from meso_scenes import bake_and_render

    real = moderngl.Context.info
    monkeypatch.setattr(moderngl.Context, "info", property(lambda ctx: {**real.fget(ctx),
                                                                        "GL_MAX_ARRAY_TEXTURE_LAYERS": 8}))
    r, _ = bake_and_render(tmp_path, scene(ORBIT.format(count=1), TORUS, 'vdm = { k = [8] }', tiling=(8, 2)))
    assert r.exit_code == 2 and "texture layers, over this GL device's limit of 8" in r.output, r.output
