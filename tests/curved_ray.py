"""Straight rays through the mesostructure of a curved reference surface, in texture space: the numpy
twin of shaders/include/curved_ray.glsl (refined VDM, beyond Wang et al. 2003).

The reference surface is bent to curvature c (texture units; > 0 convex) along the ray's azimuth,
as the VDM bake bends its tables (vdmbake/kernels/vdm.py bend), to second order in c times the distance:
|c t| stays below about 0.2 for the depths the tables are baked for, and tests/test_curved_ray.py
bounds the difference from the exact bend. A ray starts h0 below the surface at arc position 0 and
runs at polar angle theta from the surface normal (st = sin theta), down into the surface
(cz = -cos theta: a view ray) or up out of it (cz = cos theta: a light ray).
"""
from __future__ import annotations

import numpy as np


def curved_ray(t, h0, st, cz, c) -> tuple[np.ndarray, np.ndarray]:
    """The ray's point at distance t: (sigma, depth). sigma is the arc length under the point over
    sin theta, the extended displacement of Wang2003 Appendix (the point lies over T -+ sigma V_xy); depth is
    below the surface."""
    x, y = t * st, t * cz - h0
    return t * (1.0 - c * y), -y - 0.5 * c * x * x


def ray_distance(d, ct, c) -> np.ndarray:
    """The distance along a view ray (h0 = 0) whose sigma is d: c cos(theta) t^2 + t - d = 0, stable form
    (past a concave ray's largest sigma, 1 / (-4 c cos(theta)), that of the largest)."""
    return 2.0 * d / (1.0 + np.sqrt(np.maximum(1.0 + 4.0 * c * ct * d, 0.0)))


def depth_distance(h, st, ct, c) -> np.ndarray:
    """The distance along a view ray to depth h (the smaller root of (c st^2 / 2) t^2 - ct t + h = 0);
    that of the ray's deepest point where a convex surface's ray never gets that deep."""
    disc = ct * ct - 2.0 * c * st * st * h
    with np.errstate(divide="ignore", invalid="ignore"):
        deepest = ct / (c * st * st)
    return np.where(disc >= 0, 2.0 * h / np.maximum(ct + np.sqrt(np.maximum(disc, 0.0)), 1e-12), deepest)


def exit_distance(h, st, ct, c) -> np.ndarray:
    """The distance from depth h along a light ray to where it leaves the surface: the root of
    (c st^2 / 2) u^2 + ct u - h = 0; the discriminant clamped where a concave surface rises over it."""
    return 2.0 * h / np.maximum(ct + np.sqrt(np.maximum(ct * ct + 2.0 * c * st * st * h, 0.0)), 1e-12)
