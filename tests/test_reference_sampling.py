"""The filtered reference's sampling (issue 40): correlated multi-jittered points per pixel, traced on every core with
the same bytes whatever the thread count."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from vdmbake.assets import primitives
from vdmbake.formats import exr
from vdmbake.scene import Light, Material
from vdmrender import reference
from vdmrender.camera import Camera, clip_planes

LIGHT = Light(direction=(0.36, 0.48, 0.8), color=(1.0, 1.0, 1.0), ambient=(0.1, 0.1, 0.1))
MATERIAL = Material(albedo=(0.8, 0.6, 0.4), diffuse=0.8, specular=0.3)


def torus_reference() -> reference.MeshReference:
    """A torus lit from the side: silhouettes, a shadow it casts on itself and a highlight."""
    return reference.MeshReference(primitives.torus(1.0, 0.4, 48, 24), LIGHT, MATERIAL)


def camera(size: int = 24) -> Camera:
    eye, centre = np.array([0.3, -3.0, 1.6]), np.zeros(3)
    return Camera(eye, centre, np.array([0.0, 0.0, 1.0]), 45.0, size, size, *clip_planes(eye, centre, centre, 1.4))


def exr_bytes(frame, half) -> bytes:
    """What refcache.save_reference writes of a frame and its first half."""
    return exr.to_bytes({"reference": {c: frame[..., i] for i, c in enumerate("RGBA")},
                         "half": {c: half[..., i] for i, c in enumerate("RGBA")}})


@pytest.mark.parametrize("spp", [4, 16])
def test_the_same_bytes_on_one_and_two_threads(spp):
    """The strata traced on one thread and on two (and more than there are strata): the same EXR bytes, and the same
    rays counted."""
    ref, cam = torus_reference(), camera()
    out, rays = [], []
    for threads in (1, 2, 5):
        before = ref.scene.rays_cast
        out.append(exr_bytes(*reference.filtered(ref.render, cam, spp, threads)))
        rays.append(ref.scene.rays_cast - before)
    assert out[0] == out[1] == out[2]
    assert rays[0] == rays[1] == rays[2] > spp * cam.width * cam.height


def test_every_core_by_default():
    assert reference.workers() >= 1
    ref, cam = torus_reference(), camera(12)
    np.testing.assert_array_equal(reference.filtered(ref.render, cam, 4)[0],
                                  reference.filtered(ref.render, cam, 4, 1)[0])


def points(spp: int, height: int = 3, width: int = 5) -> np.ndarray:
    """(spp, H, W, 2): every pixel's sample offsets, sample k first."""
    return np.stack(list(reference.strata(SimpleNamespace(height=height, width=width), spp)))


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
