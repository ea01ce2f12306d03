"""Rays over a curved reference surface (tests/curved_ray.py and its GLSL twin
shaders/include/curved_ray.glsl): the plane limit, the inverses, the distance from the bake's exact
bend (second order in c t). The GLSL functions against numpy: tests/test_twins.py."""
from __future__ import annotations

import numpy as np

from vdmbake.kernels import vdm
import curved_ray as cr

RNG = np.random.default_rng(7)
N = 4000
THETA = RNG.uniform(0.0, np.radians(85.0), N)
ST, CT = np.sin(THETA), np.cos(THETA)
C = RNG.uniform(-2.0, 3.0, N)


def test_plane_limit():
    t, h = RNG.uniform(0, 0.5, N), RNG.uniform(0, 0.06, N)
    sigma, depth = cr.curved_ray(t, 0.0, ST, -CT, 0.0)
    assert np.array_equal(sigma, t) and np.allclose(depth, t * CT, rtol=0, atol=1e-15)
    assert np.allclose(cr.ray_distance(t, CT, 0.0), t, rtol=1e-15)
    assert np.allclose(cr.depth_distance(h, ST, CT, 0.0), h / CT, rtol=1e-14)
    assert np.allclose(cr.exit_distance(h, ST, CT, 0.0), h / CT, rtol=1e-14)
    assert cr.ray_distance(0.0, 1.0, 2.0) == 0.0 and cr.exit_distance(0.0, 0.0, 1.0, 2.0) == 0.0


def test_inverses():
    """ray_distance inverts sigma, depth_distance the view ray's depth (before its deepest point),
    and the light ray reaches depth 0 after exit_distance."""
    d = RNG.uniform(0, 0.5, N)
    t = cr.ray_distance(d, CT, C)
    reach = 1 + 4 * C * CT * d >= 0                             # else d is past a concave ray's largest sigma
    assert reach.mean() > 0.85                                  # measured 0.899
    assert np.allclose(cr.curved_ray(t, 0.0, ST, -CT, C)[0][reach], d[reach], rtol=1e-12, atol=1e-15)
    depth = cr.curved_ray(t, 0.0, ST, -CT, C)[1]
    descending = CT - C * ST * ST * t > 0                       # d depth / dt > 0
    assert np.allclose(cr.depth_distance(depth, ST, CT, C)[descending], t[descending], rtol=1e-9, atol=1e-12)
    h = RNG.uniform(0, 0.06, N)
    u = cr.exit_distance(h, ST, CT, C)
    rises = CT * CT + 2 * C * ST * ST * h >= 0                  # else a concave surface rises over the ray
    assert rises.mean() > 0.9
    assert np.allclose(cr.curved_ray(u, h, ST, CT, C)[1][rises], 0.0, atol=1e-12)


def test_second_order_in_c_t_against_the_exact_bend():
    """A point s along the surface and h below it, bent to curvature c exactly (vdmbake/kernels/vdm.py bend),
    seen from the entry point at distance t and angle theta: the model puts the ray's point at that distance
    over arc sigma sin(theta) and at a depth within 0.5 (c t)^2 t and 0.3 (c t)^2 t over |c t| <= 0.2, theta <=
    85 degrees."""
    s, h, c = RNG.uniform(0, 0.3, 5 * N), RNG.uniform(0, 0.06, 5 * N), RNG.uniform(-2, 3, 5 * N)
    x, y = vdm.bend(s, h, c)
    t, th = np.hypot(x, y), np.arctan2(x, -y)
    ok = (np.abs(c * t) <= 0.2) & (th < np.radians(85))
    sigma, depth = cr.curved_ray(t, 0.0, np.sin(th), -np.cos(th), c)
    bound = (c * t) ** 2 * t
    assert ok.sum() > 5000
    assert np.all(np.abs(sigma * np.sin(th) - s)[ok] <= 0.5 * bound[ok] + 1e-12)
    assert np.all(np.abs(depth - h)[ok] <= 0.3 * bound[ok] + 1e-12)


# The GLSL functions against these numpy ones on the GL device: tests/test_twins.py.
