"""The filtered reference's sampling (issue 40): correlated multi-jittered points per pixel, adaptive (a first pass,
the rest where the samples disagree), traced on every core with the same bytes whatever the thread count."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from vdmbake.assets import primitives
from vdmbake.formats import exr
from vdmbake.scene import Light, Material
from vdmrender.tracing import reference
from vdmrender.common.camera import Camera, clip_planes

LIGHT = Light(direction=(0.36, 0.48, 0.8), color=(1.0, 1.0, 1.0), ambient=(0.1, 0.1, 0.1))
MATERIAL = Material(albedo=(0.8, 0.6, 0.4), diffuse=0.8, specular=0.3)


def torus_reference() -> reference.MeshReference:
    """A torus lit from the side: silhouettes, a shadow it casts on itself and a highlight."""
    return reference.MeshReference(primitives.torus(1.0, 0.4, 48, 24), LIGHT, MATERIAL)


def camera(size: int = 24) -> Camera:
    eye, centre = np.array([0.3, -3.0, 1.6]), np.zeros(3)
    return Camera(eye, centre, np.array([0.0, 0.0, 1.0]), 45.0, size, size, *clip_planes(eye, centre, centre, 1.4))


def exr_bytes(frame, halves) -> bytes:
    """What refcache.save_reference writes of a frame and its Halves."""
    return exr.to_bytes({"reference": {c: frame[..., i] for i, c in enumerate("RGBA")},
                         "half": {c: halves.first[..., i] for i, c in enumerate("RGBA")},
                         "samples": {"N": halves.traced.astype(np.float32), "A": halves.in_first.astype(np.float32)}})


@pytest.mark.parametrize("spp", [4, 16, 64])
def test_the_same_bytes_on_one_and_two_threads(spp):
    """The samples traced on one thread and on two (and more than there are samples in a pass): the same EXR bytes,
    and the same rays counted: a primary ray per sample traced (adaptive: fewer than spp per pixel, but more than
    the first pass) and the shadow rays of those that hit."""
    ref, cam = torus_reference(), camera()
    out, rays = [], []
    for threads in (1, 2, 5):
        before = ref.scene.rays_cast
        frame, halves = reference.filtered(ref.render, cam, spp, threads)
        out.append(exr_bytes(frame, halves))
        rays.append(ref.scene.rays_cast - before)
    assert out[0] == out[1] == out[2]
    assert rays[0] == rays[1] == rays[2] > halves.traced.sum()
    first = len(reference.first_samples(spp))
    assert first * halves.traced.size <= halves.traced.sum() <= spp * halves.traced.size


def test_every_core_by_default():
    assert reference.workers() >= 1
    ref, cam = torus_reference(), camera(12)
    np.testing.assert_array_equal(reference.filtered(ref.render, cam, 4)[0],
                                  reference.filtered(ref.render, cam, 4, 1)[0])


def points(spp: int, height: int = 3, width: int = 5) -> np.ndarray:
    """(spp, H, W, 2): every pixel's sample offsets, sample k first."""
    pattern = reference.Pattern(SimpleNamespace(height=height, width=width), spp)
    return np.stack([pattern.at(k) for k in range(spp)])


@pytest.mark.parametrize("spp", [4, 16, 64])
def test_samples_are_correlated_multi_jittered(spp):
    """Kensler 2013: sample k in stratum (k mod N, k div N) of the pixel, and the N^2 samples in N^2 different
    columns and N^2 different rows of width 1/N^2 (jittered sampling puts N samples of a column of strata anywhere in
    it); every pixel its own pattern; the same points on every call."""
    n, p = math.isqrt(spp), points(spp)
    assert (p >= 0).all() and (p < 1).all()
    k = np.arange(spp)[:, None, None]
    np.testing.assert_array_equal(np.floor(p[..., 0] * n), np.broadcast_to(k % n, p.shape[:3]))
    np.testing.assert_array_equal(np.floor(p[..., 1] * n), np.broadcast_to(k // n, p.shape[:3]))
    for axis in (0, 1):
        fine = np.sort(np.floor(p[..., axis] * spp), 0)
        np.testing.assert_array_equal(fine, np.broadcast_to(k, fine.shape))
    flat = p.reshape(spp, -1, 2)
    assert len({flat[:, i].tobytes() for i in range(flat.shape[1])}) == flat.shape[1]
    np.testing.assert_array_equal(p, points(spp))


def test_an_edge_along_an_axis_is_covered_within_one_sample():
    """A vertical or horizontal edge anywhere across a pixel: the fraction of its 16 samples on one side is the
    covered fraction within 1/16 (one sample per fine column); jittered strata are off by up to 1/4 (a column of
    strata's 4 samples on either side)."""
    p = points(16, 8, 8)
    for x0 in np.linspace(0.01, 0.99, 37):
        for axis in (0, 1):
            assert np.abs((p[..., axis] < x0).mean(0) - x0).max() <= 1 / 16 + 1e-12


def test_a_pixels_samples_are_the_same_alone_or_in_the_frame():
    """Pattern.at for chosen pixels is those pixels' points of the whole frame's, and a render of chosen pixels
    (the adaptive pass) their pixels of the whole frame's render."""
    ref, cam = torus_reference(), camera(16)
    pattern, pixels = reference.Pattern(cam, 16), np.array([0, 17, 17, 100, 255])
    for k in (0, 5, 15):
        whole = pattern.at(k)
        np.testing.assert_array_equal(pattern.at(k, pixels), whole.reshape(-1, 2)[pixels])
        np.testing.assert_array_equal(ref.render(cam, offset=pattern.at(k, pixels), pixels=pixels),
                                      ref.render(cam, offset=whole).reshape(-1, 4)[pixels])


@pytest.mark.parametrize("n", range(3, 17))
def test_the_first_pass_is_one_sample_per_row_and_column_in_both_halves(n):
    """first_pass: N samples of N x N, one in each column and each row of strata, both halves of the strata among
    them (a pixel that stops there still has its noise estimated); at N = 4 one in each quadrant."""
    first = reference.first_pass(n)
    assert sorted(k % n for k in first) == sorted(k // n for k in first) == list(range(n))
    halves = [reference.in_first_half(k, n) for k in first]
    assert abs(2 * sum(halves) - n) <= 2 and 0 < sum(halves) < n
    if n == 4:
        assert sorted((k % n // 2, k // n // 2) for k in first) == [(0, 0), (0, 1), (1, 0), (1, 1)]


def test_interior_pixels_stop_after_the_first_pass():
    """On a flat-shaded sphere (one colour, only coverage varies), pixels wholly inside or outside its silhouette
    whose four neighbours are so too get only the first pass's N samples; every pixel the silhouette crosses by
    more than one sample's share gets the whole budget."""
    from tests.test_filtered import coverage, camera as sphere_camera, sphere_reference

    exact = coverage()
    p = np.pad(exact, 1, mode="edge")
    calm = ((exact == 0) | (exact == 1)) & (p[:-2, 1:-1] == exact) & (p[2:, 1:-1] == exact) \
        & (p[1:-1, :-2] == exact) & (p[1:-1, 2:] == exact)
    for spp in (16, 64):
        _, halves = reference.filtered(sphere_reference().render, sphere_camera(), spp)
        assert (halves.traced[calm] == math.isqrt(spp)).all()
        assert (halves.traced[(exact > 1 / spp) & (exact < 1 - 1 / spp)] == spp).all()
        assert calm.mean() > 0.8


@pytest.mark.parametrize("spp", [16, 64])
def test_adaptive_samples_reach_the_uniform_error_with_fewer_samples(spp):
    """The torus lit from the side (silhouettes, a shadow edge, a highlight) against its 256-spp frame: at the same
    budget the adaptive frame is as close as the uniform one (within 2%, over every pixel and over the pixels the
    silhouette crosses), for at most two thirds of the samples (a third of the frame is background)."""
    from vdmrender.common import images
    from vdmrender.comparing import metrics

    ref, cam, bg = torus_reference(), camera(64), np.array([0.1, 0.2, 0.3])
    truth = reference.filtered(ref.render, cam, 256, adaptive=False)[0]
    edge = (truth[..., 3] > 0) & (truth[..., 3] < 1)
    err, traced = {}, {}
    for adaptive in (False, True):
        frame, halves = reference.filtered(ref.render, cam, spp, adaptive=adaptive)
        c = metrics.compare(images.encode(frame, bg), images.encode(truth, bg))
        err[adaptive], traced[adaptive] = (c["mean"], c["dist"][edge].mean()), halves.traced.mean()
    assert err[True][0] <= 1.02 * err[False][0] and err[True][1] <= 1.02 * err[False][1], err
    assert traced[False] == spp and traced[True] < 2 / 3 * spp, traced


def far_camera(size: int, distance: float) -> Camera:
    """The torus small in a large frame (a sweep's small sizes), off the frame's centre."""
    eye, centre = np.array([0.3, -distance, 1.6]), np.zeros(3)
    target = np.array([2.0, 0.0, 1.0]) * distance / 12
    return Camera(eye, target, np.array([0.0, 0.0, 1.0]), 45.0, size, size, *clip_planes(eye, target, centre, 1.4))


@pytest.mark.parametrize("distance", [12.0, 2.2])
def test_confined_to_the_sphere_s_box_the_same_frame(distance):
    """Rays are traced only within the screen box of the object's bounding sphere (and a pixel around it): the frame,
    filtered and point-sampled, and the composite's depth are the same to the bit as every pixel traced, and far
    away most rays are not cast; near (the sphere past the frame) every pixel is traced."""
    full = torus_reference()
    whole = lambda camera, others=(), depth=False, offset=None, pixels=None: full._render(  # noqa: E731
        camera, others, depth, offset, pixels)
    cam = far_camera(96, distance)
    np.testing.assert_array_equal(full.render(cam), whole(cam))
    f, d = full.render(cam, depth=True)
    g, e = whole(cam, depth=True)
    np.testing.assert_array_equal(f, g)
    np.testing.assert_array_equal(d, e)
    assert f[..., 3].any()
    np.testing.assert_array_equal(reference.filtered(full.render, cam, 16, 1)[0],
                                  reference.filtered(whole, cam, 16, 1)[0])
    keep = reference.may_meet(cam, *full.sphere, np.arange(96 * 96))
    if distance > 10:
        assert keep.sum() < 0.2 * keep.size   # measured 1260 of 9216
    else:
        assert keep is None or keep.all()


def test_confined_quadrics_the_same_frame():
    """The same for ray-cast spheres and cylinders (QuadricReference), a molecule small in the frame."""
    from vdmbake.kernels.quadrics import QuadricSet

    q = QuadricSet(np.array([[0.0, 0.0, 0.0, 0.5], [1.0, 0.2, 0.1, 0.4]]), np.full((2, 3), 0.7, np.float32),
                 np.array([[0.0, 0.0, 0.0, 1.0, 0.2, 0.1, 0.15]]), np.full((1, 3), 0.5, np.float32))
    ref = reference.QuadricReference(q, LIGHT, MATERIAL)
    cam = far_camera(96, 14.0)
    frame = ref.render(cam)
    assert frame[..., 3].any()
    np.testing.assert_array_equal(frame, ref._render(cam))
