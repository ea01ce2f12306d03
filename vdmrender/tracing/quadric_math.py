"""Ray/quadric kernels and projected bounds (pure numpy, float64): the reference's exact
intersections, and the numpy twin of the impostor shaders' bounding box (shaders/include/quadric.glsl).

Parameter space (Sigg2006; dePoel2009 §3): a sphere is the unit
sphere x^T D x = 0 with D = diag(1, 1, 1, -1); the variance matrix T maps it to the scene.
"""
from __future__ import annotations

import numpy as np

from vdmbake.common.geometry import onb

D = np.diag([1.0, 1.0, 1.0, -1.0])
UNBOUNDED = 1e-12   # R_w D R_w^T >= -this |R_w|^2: the quadric reaches the eye plane (quadric.glsl's test)


def _sign(x):
    return np.where(x >= 0, 1.0, -1.0)


def _first_root(c, b, disc, tmin):
    """Smallest root >= tmin of t^2 - 2 b t + c = 0 written with half-b (t = b +- sqrt(disc)),
    by the cancellation-free pair q = b + sign(b) sqrt(disc), t = {c / q, q}."""
    q = b + _sign(b) * np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = np.where(q != 0, c / q, 0.0)
    lo, hi = np.minimum(t0, q), np.maximum(t0, q)
    t = np.where(lo >= tmin, lo, np.where(hi >= tmin, hi, np.inf))
    return np.where(disc >= 0, t, np.inf)


def ray_spheres(o, d, centre, radius, tmin):
    """Distance along unit directions d (N, 3) from o to each ray's sphere, first hit >= tmin, inf if none.

    Ray Tracing Gems ch. 7 form: with f = o - c, b = -f.d and l = f + b d (the offset of the
    closest approach), disc = r^2 - |l|^2 keeps its digits for small spheres far away, where
    b^2 - (|f|^2 - r^2) would cancel."""
    f = o - centre
    b = -np.einsum("ij,ij->i", f, d)
    l = f + b[:, None] * d
    disc = radius * radius - np.einsum("ij,ij->i", l, l)
    c = np.einsum("ij,ij->i", f, f) - radius * radius
    return _first_root(c, b, disc, tmin)


def ray_capped_cylinders(o, d, p0, p1, radius, tmin):
    """First hit >= tmin of unit rays with capped cylinders (axis p0 -> p1): (t, normal), t inf if none."""
    axis = p1 - p0
    half = 0.5 * np.linalg.norm(axis, axis=1)
    w = axis / (2 * half)[:, None]
    u, v = onb(w)
    f = o - 0.5 * (p0 + p1)
    op = np.stack([np.einsum("ij,ij->i", f, e) for e in (u, v, w)], 1)
    dp = np.stack([np.einsum("ij,ij->i", d, e) for e in (u, v, w)], 1)
    # Side x^2 + y^2 = r^2: the same stable form in the plane across the axis.
    s = np.hypot(dp[:, 0], dp[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        n2 = dp[:, :2] / s[:, None]
        b = -np.einsum("ij,ij->i", op[:, :2], n2)
        l = op[:, :2] + b[:, None] * n2
        disc = radius * radius - np.einsum("ij,ij->i", l, l)
        c = np.einsum("ij,ij->i", op[:, :2], op[:, :2]) - radius * radius
        q = b + _sign(b) * np.sqrt(np.maximum(disc, 0.0))
        roots = np.stack([np.where(q != 0, c / q, 0.0), q], 1) / s[:, None]
    side = np.full(len(o), np.inf)
    for k in range(2):
        t = roots[:, k]
        z = op[:, 2] + t * dp[:, 2]
        ok = (s > 0) & (disc >= 0) & (t >= tmin) & (np.abs(z) <= half)
        side = np.where(ok & (t < side), t, side)
    # Caps z = +-half, inside the radius.
    cap, cap_sign = np.full(len(o), np.inf), np.zeros(len(o))
    for sgn in (-1.0, 1.0):
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (sgn * half - op[:, 2]) / dp[:, 2]
            xy = op[:, :2] + t[:, None] * dp[:, :2]
        ok = (dp[:, 2] != 0) & (t >= tmin) & (np.einsum("ij,ij->i", xy, xy) <= radius * radius)
        better = ok & (t < cap)
        cap, cap_sign = np.where(better, t, cap), np.where(better, sgn, cap_sign)
    t = np.minimum(side, cap)
    hit_p = op + np.where(np.isfinite(t), t, 0.0)[:, None] * dp
    n_side = u * hit_p[:, :1] + v * hit_p[:, 1:2]
    n = np.where((cap < side)[:, None], w * cap_sign[:, None], n_side / radius[:, None])
    return t, n


def sphere_variance(centre, radius) -> np.ndarray:
    """T: parameter space (unit sphere) -> scene, for one sphere."""
    t = np.eye(4) * radius
    t[3, 3] = 1.0
    t[:3, 3] = centre
    return t


def disk_variance(centre, u, v, radius) -> np.ndarray:
    """T of a flat disk (a cylinder's cap): the unit sphere squashed onto the plane spanned by u, v."""
    t = np.zeros((4, 4))
    t[:3, 0], t[:3, 1], t[:3, 3], t[3, 3] = u * radius, v * radius, centre, 1.0
    return t


def projected_bounds(view_proj: np.ndarray, variance: np.ndarray):
    """NDC bounding box (xmin, ymin, xmax, ymax) of the projected quadric, or None where the
    quadric reaches the eye plane and its projection is unbounded.

    Sigg et al.: R = P M T; a clip-space plane x - X w = 0 is tangent to the quadric iff its
    parameter-space covector h = R_x - X R_w satisfies h D h^T = 0, a quadratic in X."""
    r = view_proj @ variance
    rw = r[3]
    a = rw @ D @ rw
    if a >= -UNBOUNDED * (rw @ rw):
        return None
    out = []
    for k in (0, 1):
        b = r[k] @ D @ rw
        c = r[k] @ D @ r[k]
        root = np.sqrt(max(b * b - a * c, 0.0))
        out.append(((b + root) / a, (b - root) / a))
    (x0, x1), (y0, y1) = out
    return min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1)
