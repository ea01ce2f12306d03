"""vdmrender.comparing.metrics and vdmrender.tracing.shading, checked against colour-science (an independent
implementation of the sRGB transfer functions, the sRGB -> XYZ matrix and CIE 1976 L*u*v*)
and against hand-computed shading values."""
from __future__ import annotations

import itertools
import types
import warnings

import numpy as np
import pytest

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # colour warns once that SciPy is absent; nothing used here needs it
    import colour

from vdmbake.common.colour import srgb_encode, to_srgb8
from vdmbake.scene import Light, Material
from vdmrender.comparing import metrics
from vdmrender.tracing import shading

D65_XY = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]  # (0.3127, 0.3290)


def _colours() -> np.ndarray:
    fixed = [(0, 0, 0), (255, 255, 255), (255, 0, 0), (0, 255, 0), (0, 0, 255), (128, 128, 128),
             (3, 2, 1),            # every channel below the sRGB linear-segment knee (10/255 = 0.0392)
             (10, 11, 12),         # straddling the knee (0.04045 * 255 = 10.31)
             (255, 255, 0), (0, 255, 255), (255, 0, 255)]
    rnd = np.random.default_rng(1234).integers(0, 256, size=(12, 3))
    return np.concatenate([np.array(fixed), rnd])


COLOURS = _colours()


# ---------------------------------------------------------------------------------------------
# Colour conversion vs colour-science
# ---------------------------------------------------------------------------------------------

def test_srgb8_to_linear_matches_colour():
    ours = metrics.srgb8_to_linear(COLOURS)
    ref = colour.cctf_decoding(COLOURS / 255.0, function="sRGB")
    # Same closed-form IEC 61966-2-1 formula on the same float64 inputs: agreement to rounding.
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-12)
    assert ours[0].tolist() == [0.0, 0.0, 0.0] and ours[1].tolist() == [1.0, 1.0, 1.0]
    # (3, 2, 1) lies on the linear segment: c / 12.92.
    np.testing.assert_allclose(ours[6], np.array([3, 2, 1]) / 255.0 / 12.92, rtol=1e-14)


def test_srgb8_to_luv_matches_colour_pipeline():
    """The whole chain against colour.sRGB_to_XYZ + colour.XYZ_to_Luv with D65 (0.3127, 0.3290).

    Tolerance 0.05 L*u*v* units, and why it cannot be ~1e-3: colour-science 0.4.7 uses the
    4-decimal matrix printed in IEC 61966-2-1 (0.4124, 0.3576, 0.1805 / ... / 0.9505), whose
    white (row sums) is not exactly the D65 xy it normalises against, while vdmrender uses the
    7-decimal matrix derived from the sRGB primaries and the D65 white XYZ (0.95047, 1, 1.08883)
    (checked to 3e-7 in the next test). Measured over this set (and over a 52^3 grid of 8-bit
    colours) the largest per-component difference is 0.0448, in u* of pure red; white comes
    out at u* = 0.0137 in colour's chain and exactly 0 in ours. Once the matrix and white are
    matched (test_xyz_to_luv_matches_colour) the two agree to 1e-9. 0.05 is 1 - 2 orders of
    magnitude below anything visible (a JND is ~1 unit) and still fails for any real formula error.
    """
    ours = metrics.srgb8_to_luv(COLOURS)
    ref = colour.XYZ_to_Luv(colour.sRGB_to_XYZ(COLOURS / 255.0), illuminant=D65_XY)
    assert ref[:, 0].max() <= 100.0 + 1e-9  # colour's L* is on the 0-100 scale, like ours
    np.testing.assert_allclose(ours, ref, rtol=0, atol=0.05)
    # L* alone depends only on the Y row, where the two matrices differ by <= 1e-4: much tighter.
    np.testing.assert_allclose(ours[:, 0], ref[:, 0], rtol=0, atol=0.01)


def test_srgb_matrix_is_the_primaries_matrix_for_its_white():
    """SRGB_TO_XYZ is the normalised primary matrix of the sRGB primaries for its own white,
    and that white is D65 (xy within 1e-4 of 0.3127, 0.3290)."""
    white_xy = colour.XYZ_to_xy(metrics.WHITE_D65)
    np.testing.assert_allclose(white_xy, D65_XY, atol=1e-4)
    primaries = colour.RGB_COLOURSPACES["sRGB"].primaries
    npm = colour.normalised_primary_matrix(primaries, white_xy)
    # The constants are printed to 7 decimals; measured difference 1.4e-7.
    np.testing.assert_allclose(metrics.SRGB_TO_XYZ, npm, rtol=0, atol=3e-7)
    np.testing.assert_allclose(metrics.WHITE_D65, [0.95047, 1.0, 1.08883], atol=2e-7)


def test_xyz_to_luv_matches_colour():
    """The L*u*v* formula alone (both branches of L*), with matrix and white matched exactly."""
    xyz = metrics.srgb8_to_linear(COLOURS) @ metrics.SRGB_TO_XYZ.T
    white = metrics.WHITE_D65
    ours = metrics.xyz_to_luv(xyz)
    # colour takes the white as xy with Y_n = 1; ours has Y_n = white[1] = 1.0000001.
    ref = colour.XYZ_to_Luv(xyz / white[1], illuminant=colour.XYZ_to_xy(white))
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-9)  # measured 4e-13
    # (3, 2, 1) has Y/Yn below (6/29)^3 and exercises the linear L* branch.
    assert xyz[6, 1] / white[1] < (6 / 29) ** 3


def test_luv_reference_points():
    luv = metrics.srgb8_to_luv(np.array([[0, 0, 0], [255, 255, 255], [128, 128, 128]]))
    np.testing.assert_allclose(luv[0], [0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(luv[1], [100, 0, 0], atol=1e-9)   # white: L* 100, neutral
    np.testing.assert_allclose(luv[2, 1:], [0, 0], atol=1e-9)    # greys are neutral
    np.testing.assert_allclose(luv[2, 0], 53.585, atol=1e-3)      # mid grey 128: L* = 53.585


def test_delta_luv_red_vs_blue():
    """The thesis says the metric ranges over 0-580 ('red vs blue'). CIE 1976 L*u*v* with the D65
    white and sRGB primaries gives 250.41 for sRGB red (255, 0, 0) vs blue (0, 0, 255)
    (colour-science's chain: 250.45); the largest distance between any two 8-bit sRGB colours
    is green vs magenta, 274.56. So 580 is not reachable with this metric on sRGB input."""
    d = metrics.delta_luv(np.array([255, 0, 0]), np.array([0, 0, 255]))
    assert d == pytest.approx(250.413, abs=1e-3)
    luv = colour.XYZ_to_Luv(colour.sRGB_to_XYZ(np.array([[1.0, 0, 0], [0, 0, 1.0]])), illuminant=D65_XY)
    assert d == pytest.approx(np.linalg.norm(luv[0] - luv[1]), abs=0.1)
    corners = np.array(list(itertools.product([0, 255], repeat=3)))
    dmax = metrics.delta_luv(corners[:, None], corners[None]).max()
    assert dmax == pytest.approx(274.557, abs=1e-3)
    assert dmax < 580


def test_delta_luv_basic_properties():
    a, b = COLOURS, COLOURS[::-1]
    np.testing.assert_array_equal(metrics.delta_luv(a, a), 0.0)
    np.testing.assert_allclose(metrics.delta_luv(a, b), metrics.delta_luv(b, a))
    # Black vs white is exactly the L* span, 100.
    assert metrics.delta_luv(np.array([0, 0, 0]), np.array([255, 255, 255])) == pytest.approx(100.0, abs=1e-9)


# ---------------------------------------------------------------------------------------------
# compare()
# ---------------------------------------------------------------------------------------------

def _image(h=4, w=6):
    return np.zeros((h, w, 4), np.uint8)


def test_compare_identical():
    rng = np.random.default_rng(7)
    img = rng.integers(0, 256, size=(8, 10, 4)).astype(np.uint8)
    img[..., 3] = np.where(rng.random((8, 10)) < 0.5, 255, 0)
    r = metrics.compare(img, img.copy())
    assert r["mean"] == 0.0
    assert r["iou"] == 1.0
    assert r["values"].size == int((img[..., 3] > 0).sum())


def test_compare_half_missing_counts_missing_pixels():
    """Reference: 4 white object pixels. Frame: 2 of them white, the other 2 missing (alpha 0,
    black background). Union 4, intersection 2 -> IoU 0.5; per-pixel distances 0, 0, 100, 100
    (black vs white = 100 L* units) -> mean 50. Pixels outside both masks differ wildly in
    colour but must not count."""
    ref, frame = _image(), _image()
    obj = [(1, 1), (1, 2), (2, 1), (2, 2)]
    for y, x in obj:
        ref[y, x] = (255, 255, 255, 255)
    for y, x in obj[:2]:
        frame[y, x] = (255, 255, 255, 255)
    # background outside the union: different colours in the two images, alpha 0 in both
    ref[0, 5] = (255, 0, 0, 0)
    frame[0, 5] = (0, 0, 255, 0)
    ref[3, 0] = (0, 255, 0, 0)
    r = metrics.compare(frame, ref)
    assert r["iou"] == pytest.approx(0.5)
    assert r["union"].sum() == 4
    assert r["mean"] == pytest.approx(50.0, abs=1e-9)
    assert sorted(r["values"].round(9).tolist()) == [0.0, 0.0, 100.0, 100.0]
    assert r["dist"][0, 5] == 0.0 and r["dist"][3, 0] == 0.0
    # An extra pixel in the frame (covered there, not in the reference) counts too.
    frame[3, 5] = (255, 255, 255, 255)
    r = metrics.compare(frame, ref)
    assert r["iou"] == pytest.approx(2 / 5)
    assert r["mean"] == pytest.approx(300.0 / 5, abs=1e-9)


def test_compare_empty_coverage_is_no_data_not_a_perfect_score():
    a, b = _image(), _image()
    a[..., :3] = 255  # colours differ, but nothing is covered in either
    r = metrics.compare(a, b)
    assert r["empty"] is True
    assert r["mean"] is None and r["iou"] is None
    assert r["values"].size == 0
    assert not r["union"].any()
    assert metrics.flip_values(a, b, r["union"]).size == 0
    b[1, 1] = (255, 255, 255, 255)   # one covered pixel: data again
    r = metrics.compare(a, b)
    assert r["empty"] is False and r["iou"] == 0.0 and r["mean"] == pytest.approx(0.0)


def test_flip_over_the_union():
    """FLIP is 0 for identical frames, grows with a visible difference, and is read only where either
    image covers a pixel (so a change outside both masks does not count)."""
    rng = np.random.default_rng(5)
    ref = np.zeros((48, 64, 4), np.uint8)
    ref[8:40, 8:56] = (180, 120, 90, 255)
    ref[8:40, 8:56, :3] += rng.integers(0, 20, size=(32, 48, 3)).astype(np.uint8)
    union = metrics.compare(ref, ref)["union"]
    assert np.all(metrics.flip_values(ref, ref, union) == 0.0)
    darker = ref.copy()
    darker[..., :3] = (darker[..., :3] * 0.8).astype(np.uint8)
    f = metrics.flip_values(darker, ref, union)
    assert f.shape == (32 * 48,) and 0.3 < f.mean() < 0.6, f.mean()    # measured 0.472
    outside = ref.copy()
    outside[0:4, 0:4, :3] = 255   # alpha 0, 4 pixels from the object: not part of the frame's object
    assert np.all(metrics.flip_values(outside, ref, union) == 0.0)



def test_flip_of_a_small_object_is_the_whole_frame_s():
    """FLIP is computed over the scored pixels' box and its filters' reach only: at the scored pixels, the values
    equal the whole frame's, on a textured background that the filters see (a narrower margin would not)."""
    import flip_evaluator

    rng = np.random.default_rng(7)
    ref = rng.integers(0, 256, size=(160, 200, 4)).astype(np.uint8)
    ref[..., 3] = 0
    ref[70:82, 90:104] = (200, 150, 90, 255)
    test = ref.copy()
    test[70:82, 90:104, :3] = rng.integers(0, 256, size=(12, 14, 3)).astype(np.uint8)
    union = metrics.compare(test, ref)["union"]
    whole = flip_evaluator.evaluate(*(np.ascontiguousarray(x[..., :3], np.float32) / 255 for x in (ref, test)),
                                    "LDR", applyMagma=False, computeMeanError=False)[0][..., 0]
    assert np.array_equal(metrics.flip_values(test, ref, union), np.asarray(whole, np.float64)[union])
    narrow = flip_evaluator.evaluate(*(np.ascontiguousarray(x[68:84, 88:106, :3], np.float32) / 255 for x in (ref, test)),
                                     "LDR", applyMagma=False, computeMeanError=False)[0][..., 0]
    assert not np.array_equal(np.asarray(narrow, np.float64)[union[68:84, 88:106]], np.asarray(whole, np.float64)[union])

# ---------------------------------------------------------------------------------------------
# sRGB encoding
# ---------------------------------------------------------------------------------------------

def test_srgb_encode_matches_colour():
    lin = np.concatenate([np.linspace(0, 1, 1001), np.geomspace(1e-7, 1e-2, 200),
                          [0.0031308 * (1 - 1e-9), 0.0031308 * (1 + 1e-9)]])
    np.testing.assert_allclose(srgb_encode(lin), colour.cctf_encoding(lin, function="sRGB"),
                               rtol=0, atol=1e-12)
    # Exactly at the knee the two branches of the standard do not meet (0.0031308 is a rounded
    # constant): 12.92 * 0.0031308 = 0.04044994 vs 1.055 * 0.0031308^(1/2.4) - 0.055 = 0.04044991.
    # colour takes the linear branch there (<=), vdmrender the power branch (<): 2.9e-8 apart,
    # 7e-6 of an 8-bit code, so immaterial; accept either branch but nothing else.
    knee = srgb_encode(np.array([0.0031308]))[0]
    assert knee == pytest.approx(colour.cctf_encoding(0.0031308, function="sRGB"), abs=3e-8)
    # out of range is clamped (colour does not clamp: compare with clipped input)
    out = np.array([-0.5, -1e-9, 1.0 + 1e-9, 3.0])
    np.testing.assert_allclose(srgb_encode(out),
                               colour.cctf_encoding(np.clip(out, 0, 1), function="sRGB"), atol=1e-12)
    np.testing.assert_allclose(srgb_encode(out), [0.0, 0.0, 1.0, 1.0], rtol=0, atol=1e-15)


def test_to_srgb8_round_trip_and_rounding():
    codes = np.arange(256)
    lin = colour.cctf_decoding(codes / 255.0, function="sRGB")
    out = to_srgb8(lin)
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out, codes)
    # round to nearest, not truncate: encodings of 127.4/255 and 127.6/255
    lo, hi = colour.cctf_decoding(np.array([127.4, 127.6]) / 255.0, function="sRGB")
    assert to_srgb8(np.array([lo, hi])).tolist() == [127, 128]
    assert to_srgb8(np.array([-1.0, 0.0, 2.0, np.inf])).tolist() == [0, 0, 255, 255]
    # and the decode used by the metric inverts it
    np.testing.assert_allclose(metrics.srgb8_to_linear(out), lin, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# shade(): hand-computed cases
# ---------------------------------------------------------------------------------------------

AMB = np.array([0.1, 0.12, 0.14])
ALB = np.array([0.8, 0.5, 0.2])
KD, KS, SHIN = 0.7, 0.3, 16.0


def _light(direction=(0.0, 0.0, 1.0), color=(1.0, 1.0, 1.0)):
    return Light(direction=tuple(direction), color=tuple(color), ambient=tuple(AMB))


MAT = Material(albedo=tuple(ALB), diffuse=KD, specular=KS, shininess=SHIN)


def _shade(n, v, lit, light=None, material=MAT, albedo=ALB):
    n, v = np.atleast_2d(np.asarray(n, float)), np.atleast_2d(np.asarray(v, float))
    return shading.shade(albedo, n, v, np.atleast_1d(np.asarray(lit, bool)), light or _light(), material)


def test_shade_straight_on():
    c = _shade([0, 0, 1], [0, 0, 1], True)
    np.testing.assert_allclose(c[0], AMB * ALB + KD * ALB + KS, rtol=1e-12)


def test_shade_light_colour_multiplies_direct_only():
    col = np.array([0.5, 1.0, 2.0])
    c = _shade([0, 0, 1], [0, 0, 1], True, light=_light(color=col))
    np.testing.assert_allclose(c[0], AMB * ALB + col * (KD * ALB + KS), rtol=1e-12)


def test_shade_oblique_cases():
    s, h = np.sqrt(3) / 2, 0.5
    L = (s, 0.0, h)  # 60 degrees from N = +Z
    # mirror view: the half vector is N, so the specular term is 1; N.L = cos 60 = 0.5
    c = _shade([0, 0, 1], [-s, 0, h], True, light=_light(L))
    np.testing.assert_allclose(c[0], AMB * ALB + KD * 0.5 * ALB + KS, rtol=1e-12)
    # view along N: the half vector is 30 degrees from N, specular = cos(30 deg)^shininess
    c = _shade([0, 0, 1], [0, 0, 1], True, light=_light(L))
    np.testing.assert_allclose(c[0], AMB * ALB + KD * 0.5 * ALB + KS * np.cos(np.radians(30)) ** SHIN,
                               rtol=1e-12)


def test_shade_shadowed_gets_ambient_only():
    c = _shade([0, 0, 1], [0, 0, 1], False)
    np.testing.assert_allclose(c[0], AMB * ALB, rtol=1e-12)


def test_shade_facing_away_from_light_gets_ambient_only():
    # N.L < 0, although lit and the half vector would give a specular highlight if unguarded
    c = _shade([0, 0, -1], [0, 0, -1], True, light=_light((0.0, 0.6, 0.8)))
    np.testing.assert_allclose(c[0], AMB * ALB, rtol=1e-12)
    # grazing N.L = 0 exactly: no direct light either
    c = _shade([1, 0, 0], [1, 0, 0], True)
    np.testing.assert_allclose(c[0], AMB * ALB, rtol=1e-12)


def test_shade_light_opposite_view_is_finite():
    # L = -V: the half vector is zero; must not produce NaN. N.L = 0.8, specular 0.
    L = np.array([0.0, 0.6, 0.8])
    c = _shade([0, 0, 1], -L, True, light=_light(L))
    assert np.isfinite(c).all()
    np.testing.assert_allclose(c[0], AMB * ALB + KD * 0.8 * ALB, rtol=1e-12)


def test_shade_zero_normal_is_finite():
    c = _shade([0, 0, 0], [0, 0, 1], True)
    assert np.isfinite(c).all()
    np.testing.assert_allclose(c[0], AMB * ALB, rtol=1e-12)


def test_shade_batch_and_namespace_objects():
    """A batch with per-point albedo, plain namespaces for light/material: rows are independent."""
    light = types.SimpleNamespace(direction=np.array([0.0, 0.0, 1.0]), color=np.ones(3), ambient=AMB)
    mat = types.SimpleNamespace(diffuse=KD, specular=KS, shininess=SHIN)
    n = np.array([[0, 0, 1], [0, 0, 1], [0, 0, -1]], float)
    v = np.array([[0, 0, 1], [0, 0, 1], [0, 0, -1]], float)
    alb = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    c = shading.shade(alb, n, v, np.array([True, False, True]), light, mat)
    np.testing.assert_allclose(c[0], AMB * alb[0] + KD * alb[0] + KS, rtol=1e-12)
    np.testing.assert_allclose(c[1], AMB * alb[1], rtol=1e-12)
    np.testing.assert_allclose(c[2], AMB * alb[2], rtol=1e-12)
