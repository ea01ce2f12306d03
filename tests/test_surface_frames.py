"""Per-vertex texture tangents and principal curvatures of the primitives (VDM needs c_V, sec. 3.2)."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.assets import primitives
from vdmbake.common.mesh import transformed
from vdmbake.scene import Transform


def test_sphere_is_umbilic_everywhere_poles_included():
    m = primitives.sphere(2.0, 32, 16)
    assert np.allclose(m.frame.k1, 0.5) and np.allclose(m.frame.k2, 0.5)


def test_torus_curvatures():
    a, b = 1.0, 0.35
    m = primitives.torus(a, b, 64, 32)
    cos_theta = (np.hypot(m.vertices[:, 0], m.vertices[:, 1]) - a) / b
    assert np.allclose(m.frame.k2, 1 / b)                                   # around the tube
    assert np.allclose(m.frame.k1, cos_theta / (a + b * cos_theta))         # around the axis: < 0 inside
    assert (m.frame.k1 < 0).any() and (m.frame.k1 > 0).any()


def test_cylinder_and_flat_parts():
    m = primitives.cylinder(0.5, 2.0, 32, 4, 1)
    side = np.abs(m.normals[:, 2]) < 0.5
    assert np.allclose(m.frame.k1[side], 2.0) and np.allclose(m.frame.k2[side], 0.0)
    assert np.allclose(m.frame.k1[~side], 0.0) and np.allclose(m.frame.k2[~side], 0.0)
    p = primitives.plane(2.0, 4)
    assert not p.frame.k1.any() and np.allclose(p.frame.dpdu, [2.0, 0, 0])


@pytest.mark.parametrize("name", ["vase", "torus", "sphere"])
def test_curvatures_match_the_normals_rate_of_turn(name):
    """Shape operator check: along a principal direction, dN/ds = k * direction (finite differences
    of the analytic normals between neighbouring vertices of the grid)."""
    seg, rings = 400, 400
    m = primitives.PRIMITIVES[name][0](**{"vase": dict(radius=0.5, height=2.0),
                                     "torus": dict(major=1.0, minor=0.35),
                                     "sphere": dict(radius=1.0)}[name], segments=seg, rings=rings)
    grid = lambda a: a.reshape(rings + 1, seg + 1, *a.shape[1:])  # noqa: E731
    v, n, f = grid(m.vertices), grid(m.normals), m.frame
    k1, k2 = grid(f.k1), grid(f.k2)
    inner = (slice(5, -5), slice(0, -1))
    # along the parallel (next vertex in phi) and along the meridian (next ring)
    for dv, dn, k in ((v[:, 1:] - v[:, :-1], n[:, 1:] - n[:, :-1], k1[:, :-1]),
                      (v[1:, :-1] - v[:-1, :-1], n[1:, :-1] - n[:-1, :-1], k2[:-1, :-1])):
        ds = np.linalg.norm(dv, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):      # the sphere's pole rows have ds = 0 (excluded)
            rate = np.einsum("...i,...i->...", dn, dv) / ds ** 2  # (dN . dP) / |dP|^2 = k
        assert np.abs(rate - k)[inner].max() < 0.02 * np.abs(k).max() + 1e-9


def test_frames_follow_transforms():
    m = primitives.torus(1.0, 0.35, 16, 8)
    t = transformed(m, Transform(scale=(2.0, 2.0, 2.0), rotate_deg=(30.0, 0.0, 45.0)))
    assert np.allclose(t.frame.k2, 1 / 0.7) and np.allclose(np.linalg.norm(t.frame.d1, axis=1), 1)
    assert np.allclose(np.einsum("ij,ij->i", t.frame.d1, t.normals), 0, atol=1e-12)  # still tangent
    assert np.allclose(np.linalg.norm(t.frame.dpdv, axis=1), 2 * np.linalg.norm(m.frame.dpdv, axis=1))
    assert transformed(m, Transform(scale=(1.0, 2.0, 1.0))).frame is None   # non-uniform: curvature unknown
