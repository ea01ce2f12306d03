"""vdmbake.assets.heightfields: procedural tiles, PNG/EXR loading, periodic resampling, scikit-image photos."""
from __future__ import annotations

import sys

import numpy as np
import pytest
from PIL import Image

from vdmbake.formats import exr
from vdmbake.assets import heightfields as hf
from vdmbake.errors import InputError

N = 128


def seam_ok(h: np.ndarray) -> bool:
    """The wrap-around step (last column -> first, last row -> first) looks like an interior step:
    no larger (per texel, and averaged over the seam) than the largest interior neighbour step,
    and, texel by texel, not much larger than the steps just beside it (a smooth surface
    crossing the seam keeps its slope; a step hidden among steeper features elsewhere shows)."""
    for a in (h, h.T):
        inner = np.abs(np.diff(a, axis=1))  # (n, n-1) neighbour steps inside the tile
        seam = np.abs(a[:, 0] - a[:, -1])
        if seam.max() > inner.max() + 1e-12 or seam.mean() > inner.mean(axis=0).max() + 1e-12:
            return False
        beside = np.maximum(inner[:, 0], inner[:, -1])
        if np.any(seam > 2.0 * beside + 1e-3):
            return False
    return True


def test_seam_check_can_fail():
    ramp = np.tile(np.linspace(0.0, 1.0, 64), (64, 1))
    assert not seam_ok(ramp)
    assert not seam_ok(ramp.T)
    bricks = hf.pattern("bricks", 80)
    assert seam_ok(bricks)
    assert not seam_ok(bricks[:, :70])  # a crop that is not a whole period has a seam
    assert not seam_ok(bricks[:30, :])
    smooth = np.tile(np.sin(np.linspace(0, 2.6, 64)), (64, 1)) * 0.1  # gentle, but not periodic
    smooth[:, 20] += 0.5  # a steep feature elsewhere must not hide the seam step
    assert not seam_ok(smooth)


@pytest.mark.parametrize("name", hf.PATTERNS)
def test_pattern_shape_range_periodic(name):
    h = hf.pattern(name, N)
    assert h.shape == (N, N) and h.dtype == np.float64
    assert h.min() >= 0.0 and h.max() <= 1.0
    assert seam_ok(h)
    assert np.array_equal(h, hf.pattern(name, N))  # deterministic
    if name != "flat":
        assert h.min() == 0.0 and h.max() > 0.98
        assert seam_ok(hf.pattern(name, 97))  # odd sizes tile too


@pytest.mark.parametrize("name", hf.PATTERNS)
def test_pattern_other_sizes(name):
    for size in (2, 3, 64, 200):
        h = hf.pattern(name, size)
        assert h.shape == (size, size)
        assert 0.0 <= h.min() and h.max() <= 1.0
        if size >= 64:
            assert seam_ok(h)


def test_flat_is_ones():
    assert np.array_equal(hf.pattern("flat", 16), np.ones((16, 16)))


def test_bricks_mortar_tops_and_smooth_variation():
    h = hf.pattern("bricks", 256)
    mortar = np.mean(h < 0.02)
    tops = np.mean(h > 0.9)
    assert 0.05 < mortar < 0.3, mortar
    assert tops > 0.5, tops
    # running bond: a full-width bed joint (a mortar row) and head joints offset by half a tile
    row_mean = h.mean(axis=1)
    assert row_mean.min() < 0.02
    lower = h[64]  # middle of course 0: head joint on the seam
    upper = h[192]  # middle of course 1: head joint half a tile over
    assert lower[0] < 0.02 and lower[-1] < 0.02 and lower[128] > 0.9
    assert upper[128] < 0.02 and upper[127] < 0.02 and upper[0] > 0.9
    assert np.mean(lower < 0.02) < 0.1 and np.mean(upper < 0.02) < 0.1  # one joint per brick
    # tops vary a little, smoothly (sines, not noise)
    top = h[h > 0.9]
    assert 0.01 < top.max() - top.min() <= 0.1
    inner = h[40:90, 40:90]  # inside one brick
    assert inner.min() > 0.9
    assert np.abs(np.diff(inner, axis=0)).max() < 0.005
    assert np.abs(np.diff(inner, axis=1)).max() < 0.005
    # bevel: a linear ramp several texels wide between mortar and top
    ramp = np.mean((h > 0.05) & (h < 0.85))
    assert ramp > 0.05


def test_weave_gaps_strands_undulate():
    h = hf.pattern("weave", 256)
    assert np.mean(h < 1e-9) > 0.01  # gaps at 0
    assert h.max() > 0.98
    # smooth cosine profiles: no steps
    assert np.abs(np.diff(h, axis=0)).max() < 0.25
    assert np.abs(np.diff(h, axis=1)).max() < 0.25
    # strands both ways: a row through the middle of a lane and a column likewise are both mostly raised
    lane = 256 // 8
    assert np.mean(h[lane // 2, :] > 0.3) > 0.8
    assert np.mean(h[:, lane // 2] > 0.3) > 0.8
    # over/under: along one strand's axis the height goes up and down
    axis = h[lane // 2, :]
    assert axis.max() > 0.95 and axis.min() < 0.7
    assert not np.allclose(h, h.T)


def test_bumps_grid_of_hemispheres():
    h = hf.pattern("bumps", N)
    cell = N // 4
    for i in range(4):
        for j in range(4):
            c = h[i * cell:(i + 1) * cell, j * cell:(j + 1) * cell]
            assert c.max() > 0.99
            assert c[0, 0] == 0.0 and c[-1, -1] == 0.0  # the base between bumps
    # a hemisphere: h = sqrt(1 - (d / r)^2) along a line through a centre
    centre_row = h[cell // 2 - 1]  # texel centre at 15.5 / 128, half a texel off the bump centre
    x = (np.arange(N) + 0.5) / N
    dx = (x * 4) % 1.0 - 0.5  # to the nearest bump centre, in cells
    d2 = dx ** 2 + (0.5 / cell) ** 2
    expect = np.sqrt(np.clip(1 - d2 / 0.45 ** 2, 0, 1))
    assert np.allclose(centre_row, expect, atol=1e-9)
    assert 0.3 < np.mean(h > 0) < 0.8


def test_cliffs_vertical_walls_and_slot():
    for size in (16, 64, 101):
        h = hf.pattern("cliffs", size)
        assert set(np.unique(h)) == {0.0, 1.0}
        assert np.abs(np.diff(h, axis=1)).max() == 1.0  # a wall between two adjacent texels
        assert np.abs(np.diff(h, axis=0)).max() == 1.0
        # the walls are not on the seam
        assert np.array_equal(h[:, 0], h[:, -1]) and np.array_equal(h[0, :], h[-1, :])
        # a one-texel slot: 1, 0, 1 across a row, and never two zeros side by side inside the plateau
        slot = (h[:, 1:-1] == 0) & (h[:, :-2] == 1) & (h[:, 2:] == 1)
        rows, cols = np.nonzero(slot)
        assert len(rows) >= 2
        assert len(set(cols)) == 1  # one column
        c = cols[0] + 1
        assert np.all(h[rows, c - 1] == 1) and np.all(h[rows, c + 1] == 1)
        # plateau: a sizeable raised square
        assert 0.15 < h.mean() < 0.4


# ------------------------------------------------------------------ image files


def test_png_8bit_normalised_by_range_and_flipped(tmp_path):
    """One rule for every format (heightfields docstring): min / max to [0, 1]; rows flipped so row 0
    is v = 0, the picture's bottom."""
    a = np.arange(64, dtype=np.uint8).reshape(8, 8) * 3 + 11  # 11 .. 200
    assert a.max() == 200
    p = tmp_path / "h8.png"
    Image.fromarray(a, mode="L").save(p)
    h = hf.load_image(p, None)
    assert h.shape == (8, 8) and h.dtype == np.float64
    assert np.allclose(h, (a[::-1] - 11.0) / 189.0, atol=1e-12)
    assert h.max() == 1.0 and h.min() == 0.0


def test_png_16bit_precision_kept(tmp_path):
    a = np.zeros((4, 4), np.uint16)
    a[0, 0], a[0, 1], a[1, 1] = 65535, 32768, 1000
    p = tmp_path / "h16.png"
    im = Image.new("I;16", (4, 4))
    im.frombytes(a.astype("<u2").tobytes())
    im.save(p)
    h = hf.load_image(p, None)[::-1]          # back to picture rows
    assert h[0, 0] == 1.0
    assert abs(h[0, 1] - 0.5) < 1e-4
    assert abs(h[1, 1] - 1000 / 65535) < 1e-12  # 16-bit precision kept (8-bit would give 0 or 1/255)
    assert h[3, 3] == 0.0


def test_png_rgb_and_rgba_rec709_luminance(tmp_path):
    rgb = np.zeros((2, 2, 3), np.uint8)
    rgb[0, 0] = (255, 0, 0)
    rgb[0, 1] = (0, 255, 0)
    rgb[1, 0] = (0, 0, 255)
    rgb[1, 1] = (10, 100, 200)
    p = tmp_path / "rgb.png"
    Image.fromarray(rgb, mode="RGB").save(p)
    h = hf.load_image(p, None)
    y = np.array([[0.2126, 0.7152], [0.0722, (0.2126 * 10 + 0.7152 * 100 + 0.0722 * 200) / 255]])
    expect = ((y - y.min()) / (y.max() - y.min()))[::-1]
    assert np.allclose(h, expect, atol=1e-12)
    rgba = np.dstack([rgb, np.full((2, 2), 7, np.uint8)])  # alpha is ignored
    q = tmp_path / "rgba.png"
    Image.fromarray(rgba, mode="RGBA").save(q)
    assert np.allclose(hf.load_image(q, None), expect, atol=1e-12)


def test_exr_float_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    z = rng.uniform(-3.0, 5.0, (16, 16)).astype(np.float32)
    p = tmp_path / "h.exr"
    exr.write(p, {"height": {"Y": z}})
    h = hf.load_image(p, None)
    expect = (z.astype(np.float64) - z.min()) / (float(z.max()) - z.min())
    assert np.allclose(h, expect[::-1], atol=1e-12)
    assert h.min() == 0.0 and h.max() == 1.0


def test_exr_channel_choice_and_constant(tmp_path):
    ramp = np.tile(np.linspace(0, 1, 8, dtype=np.float32), (8, 1))
    p = tmp_path / "rgb.exr"
    exr.write(p, {"rgba": {"B": ramp[::-1].copy(), "G": ramp.T.copy(), "R": ramp}})
    assert np.allclose(hf.load_image(p, None), ramp)  # R, not G or B (its rows are all alike)
    q = tmp_path / "single.exr"
    exr.write(q, {"depth": {"depth.Z": 2 * ramp.T}})
    assert np.allclose(hf.load_image(q, None), ramp.T[::-1])  # the only channel, picture rows flipped
    c = tmp_path / "const.exr"
    exr.write(c, {"h": {"Y": np.full((4, 4), 0.25, np.float32)}})
    assert np.array_equal(hf.load_image(c, None), np.ones((4, 4)))


def test_resample_periodic_keeps_mean_and_is_seamless(tmp_path):
    h = hf.pattern("bumps", 128)
    for size in (64, 96, 200, 256):
        r = hf.resample(h, size)
        assert r.shape == (size, size)
        assert abs(r.mean() - h.mean()) < 0.002 * h.mean(), (size, r.mean(), h.mean())
        assert seam_ok(r)
    # the loader uses it: 8-bit PNG of a periodic field
    p = tmp_path / "b.png"
    Image.fromarray(np.round(h * 255).astype(np.uint8), mode="L").save(p)
    r = hf.load_image(p, 80)
    assert r.shape == (80, 80) and seam_ok(r)


def test_resample_wraps_around_not_clamps():
    n, m = 64, 96
    x_in = (np.arange(n) + 0.5) / n
    x_out = (np.arange(m) + 0.5) / m
    f = np.tile(np.sin(2 * np.pi * x_in), (n, 1))
    r = hf.resample(f, m)
    expect = np.sin(2 * np.pi * x_out)
    # a clamped filter would get the first and last texels wrong by ~ the slope there
    assert np.abs(r - expect[None, :]).max() < 2e-3
    assert np.allclose(r[:, 0], r[0, 0])
    # shrinking averages (tent of the reduction width): a one-texel-period stripe becomes grey
    stripes = np.tile(np.array([1.0, 0.0, 0.0, 0.0] * 16), (64, 1))
    assert np.allclose(hf.resample(stripes, 16), 0.25)  # point-sampling bilinear would give 0
    # same size is the identity
    assert np.array_equal(hf.resample(f, n), f)


# ------------------------------------------------------------------ errors


def _raises_naming(fn, *words):
    with pytest.raises(InputError) as e:
        fn()
    for w in words:
        assert str(w) in str(e.value), (w, str(e.value))
    return str(e.value)


def test_errors_name_the_file(tmp_path):
    missing = tmp_path / "nowhere.png"
    _raises_naming(lambda: hf.load_image(missing, None), "nowhere.png", "PNG")
    _raises_naming(lambda: hf.load_image(tmp_path, None), str(tmp_path))
    text = tmp_path / "notes.png"
    text.write_text("not an image")
    _raises_naming(lambda: hf.load_image(text, None), "notes.png", "PNG", "EXR")
    truncated = tmp_path / "cut.png"
    Image.fromarray(np.zeros((64, 64), np.uint8), mode="L").save(truncated)
    truncated.write_bytes(truncated.read_bytes()[:40])
    _raises_naming(lambda: hf.load_image(truncated, None), "cut.png")
    badexr = tmp_path / "junk.exr"
    badexr.write_bytes(b"\x76\x2f\x31\x01" + b"\x00" * 20)
    _raises_naming(lambda: hf.load_image(badexr, None), "junk.exr")
    z = np.zeros((4, 4), np.float32)
    z[1, 2] = np.nan
    nan = tmp_path / "nan.exr"
    exr.write(nan, {"h": {"Y": z}})
    _raises_naming(lambda: hf.load_image(nan, None), "nan.exr", "NaN")
    z[1, 2] = np.inf
    inf = tmp_path / "inf.exr"
    exr.write(inf, {"h": {"Y": z}})
    _raises_naming(lambda: hf.load_image(inf, None), "inf.exr", "infinite")
    two = tmp_path / "two.exr"
    exr.write(two, {"h": {"a": z, "b": z}})
    _raises_naming(lambda: hf.load_image(two, None), "two.exr", "Y")


def test_size_errors(tmp_path):
    p = tmp_path / "ok.png"
    Image.fromarray(np.zeros((8, 8), np.uint8), mode="L").save(p)
    for bad in (1, 0, -4, 4097, 2.5, True):
        _raises_naming(lambda bad=bad: hf.load_image(p, bad), "ok.png", "4096")
        _raises_naming(lambda bad=bad: hf.pattern("bumps", bad), "bumps", "4096")
    assert hf.load_image(p, 2).shape == (2, 2) and hf.load_image(p, 4096).shape == (4096, 4096)
    tiny = tmp_path / "tiny.png"
    Image.fromarray(np.zeros((1, 1), np.uint8), mode="L").save(tiny)
    _raises_naming(lambda: hf.load_image(tiny, None), "tiny.png", "2")
    assert hf.load_image(tiny, 4).shape == (4, 4)
    wide = tmp_path / "wide.png"
    Image.fromarray(np.zeros((8, 12), np.uint8), mode="L").save(wide)
    _raises_naming(lambda: hf.load_image(wide, None), "wide.png", "square")
    assert hf.load_image(wide, 16).shape == (16, 16)


def test_unknown_pattern():
    msg = _raises_naming(lambda: hf.pattern("marble", 16), "marble")
    for name in hf.PATTERNS:
        assert name in msg


# ------------------------------------------------------------------ scikit-image photos


def test_skimage_photo_unknown_name_lists_allowed():
    msg = _raises_naming(lambda: hf.skimage_photo("astronaut", 32), "astronaut")
    for name in ("brick", "gravel", "grass"):
        assert name in msg


def test_skimage_missing_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "skimage", None)  # import skimage now fails, find_spec is None
    _raises_naming(lambda: hf.skimage_photo("brick", 32), "scikit-image", hf.SKIMAGE_EXTRA, "pip install")


def test_skimage_brick_photo():
    pytest.importorskip("skimage")
    h = hf.skimage_photo("brick", None)
    assert h.shape == (512, 512) and h.dtype == np.float64
    assert h.min() == 0.0 and h.max() == 1.0
    assert h.std() > 0.05  # a photograph, not a constant
    small = hf.skimage_photo("brick", 64)
    assert small.shape == (64, 64)
    assert 0.0 <= small.min() and small.max() <= 1.0
    assert abs(small.mean() - h.mean()) < 0.01
    for name in ("gravel", "grass"):
        assert hf.skimage_photo(name, 32).shape == (32, 32)
