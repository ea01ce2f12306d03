"""The quadric reference's tracer (grouped boxes, vdmrender.tracing.quadric_groups) against brute force over
every quadric: rounded coordinates whose box faces line up, a real molecule in two styles, and the
pieces it is built from."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vdmbake.assets.meshes import resolve_path
from vdmbake.assets.molecules import load_molecule
from vdmbake.kernels.quadrics import QuadricSet
from vdmrender.tracing import quadric_groups
from vdmrender.tracing import quadric_math as qm
from vdmrender.tracing.reference import QuadricTracer


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def brute_force(q: QuadricSet, o, d, tmin, tmax):
    """Nearest hit t of every ray with every quadric (inf where none in [tmin, tmax])."""
    n = len(o)
    best = np.full(n, np.inf)
    for x in q.spheres:
        best = np.minimum(best, qm.ray_spheres(o, d, np.broadcast_to(x[:3], o.shape), np.full(n, x[3]), tmin))
    for x in q.cylinders:
        t, _ = qm.ray_capped_cylinders(o, d, np.broadcast_to(x[:3], o.shape), np.broadcast_to(x[3:6], o.shape),
                                       np.full(n, x[6]), tmin)
        best = np.minimum(best, t)
    return np.where(best <= tmax, best, np.inf)


def quadric_set(spheres, cylinders=np.zeros((0, 7))):
    return QuadricSet(np.asarray(spheres, float), np.ones((len(spheres), 3), np.float32),
                      np.asarray(cylinders, float), np.ones((len(cylinders), 3), np.float32))


def assert_traced_exactly(q, o, d, tmin, tmax):
    """First hits equal brute force bit for bit, and short shadow rays agree on whether anything is hit."""
    tracer = QuadricTracer(q)
    expected = brute_force(q, o, d, tmin, tmax)
    t, _, idx = tracer.first_hit(o, d, tmin, tmax)
    np.testing.assert_array_equal(t, expected)
    assert np.array_equal(idx >= 0, np.isfinite(expected))
    short = np.full(len(o), 0.3)
    ts, _, _ = tracer.first_hit(o, d, tmin, short, stop_at_any=True)
    assert np.array_equal(np.isfinite(ts), brute_force(q, o, d, tmin, short) <= short)


@pytest.mark.parametrize("aligned", [False, True])
def test_rounded_coordinates_whose_box_faces_line_up(aligned, monkeypatch):
    """Equal spheres and axis-aligned cylinders on rounded coordinates (as PDB files round to 0.001 A):
    axis-aligned boxes share face planes, and a walk that steps past one face skips the others in the step (the
    one-box-a-quadric walk of bench/quadric_reference.py got some of these rays wrong). With every group box
    axis-aligned (aligned), the faces line up again, and the float64 check of the faces stepped over alone keeps
    the tracer exact."""
    if aligned:
        monkeypatch.setattr(quadric_groups, "random_rotations", lambda n, seed=0: np.tile(np.eye(3), (n, 1, 1)))
    rng = np.random.default_rng(5)
    c = np.round(rng.uniform(-3, 3, (400, 3)), 1)
    spheres = np.c_[c, np.full(400, 0.5)]
    a = np.round(rng.uniform(-3, 3, (60, 3)), 1)
    b = a.copy()
    b[np.arange(60), rng.integers(0, 3, 60)] += 1.0                     # along x, y or z
    q = quadric_set(spheres, np.c_[a, b, np.full(60, 0.2)])
    n = 6000
    o = np.repeat(np.round(rng.uniform(-1, 1, (6, 3)), 1), n // 6, 0)    # eyes inside the cloud
    d = unit(rng.normal(size=(n, 3)))
    d[::3] = unit(np.round(d[::3], 0) + 1e-3 * rng.normal(size=(n // 3 + (n % 3 > 0), 3)))  # near the axes
    assert_traced_exactly(q, o, d, np.full(n, 1e-3), np.full(n, 50.0))


def test_overlapping_random_quadrics_seen_from_inside():
    rng = np.random.default_rng(3)
    s = np.c_[rng.uniform(-3, 3, (300, 3)), rng.uniform(0.4, 0.9, 300)]
    c = np.c_[rng.uniform(-3, 3, (40, 3)), rng.uniform(-3, 3, (40, 3)), rng.uniform(0.1, 0.3, 40)]
    n = 4000
    o = np.repeat(rng.uniform(-1, 1, (4, 3)), n // 4, 0)
    assert_traced_exactly(quadric_set(s, c), o, unit(rng.normal(size=(n, 3))), np.full(n, 1e-3), np.full(n, 50.0))


@pytest.mark.parametrize("style", ["spacefill", "ball-and-stick"])
@pytest.mark.slow
def test_real_molecule_from_outside_and_inside(style):
    """Villin (596 atoms): rays from far away and from the middle, at every angle."""
    q = load_molecule(resolve_path("pkg:pdbfixer/tests/data/test.pdb", Path(".")), style)
    centre, radius = q.bounding_sphere()
    rng = np.random.default_rng(1)
    n = 3000
    d = unit(rng.normal(size=(n, 3)))
    far = centre - 3 * radius * d + rng.uniform(-0.5, 0.5, (n, 3)) * radius   # looking about at the centre
    o = np.r_[far, np.broadcast_to(centre, (n, 3))]
    assert_traced_exactly(q, o, np.r_[d, d], np.full(2 * n, 1e-3), np.full(2 * n, 10 * radius))


def test_groups_hold_every_quadric_once_near_each_other():
    rng = np.random.default_rng(2)
    centre = rng.uniform(-5, 5, (3000, 3))
    centre[:40] = 1.234                                                    # a crowded cell: split at the cap
    members, group = quadric_groups.grid_groups(centre, 1.0, cap=16)
    listed = members[members >= 0]
    assert np.array_equal(np.sort(listed), np.arange(len(centre)))
    assert np.array_equal(members[group, (members[group] == np.arange(len(centre))[:, None]).argmax(1)],
                          np.arange(len(centre)))
    assert members.shape[1] == 16
    for row in members:
        pts = centre[row[row >= 0]]
        assert (np.floor(pts.max(0)) - np.floor(pts.min(0)) <= 1).all()    # one grid cell (the origin shifts it)


def test_cover_lists_every_box_holding_a_point():
    rng = np.random.default_rng(4)
    lo = rng.uniform(-4, 4, (500, 3))
    hi = lo + rng.uniform(0.1, 2.0, (500, 3)) * np.where(rng.random((500, 1)) < 0.02, 8.0, 1.0)
    cover = quadric_groups.Cover(lo, hi, 0.7)
    assert len(cover.levels) > 1                                # the large boxes went to coarser levels
    p = rng.uniform(-6, 6, (3000, 3))
    point, box = cover.near(p)
    want = set(zip(*np.nonzero(((p[:, None] >= lo[None]) & (p[:, None] <= hi[None])).all(-1))))
    assert want <= set(zip(point.tolist(), box.tolist()))


def test_quadric_boxes_bound_rotated_quadrics_tightly():
    rng = np.random.default_rng(6)
    s = np.c_[rng.normal(size=(5, 3)), rng.uniform(0.2, 1, 5)]
    c = np.c_[rng.normal(size=(5, 3)), rng.normal(size=(5, 3)), rng.uniform(0.1, 0.5, 5)]
    rot = quadric_groups.random_rotations(10, seed=3)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", rot, rot), np.broadcast_to(np.eye(3), (10, 3, 3)), atol=1e-12)
    lo, hi = quadric_groups.quadric_boxes(s, c, rot)
    # Sample each cylinder's cap rims, in its frame: inside the box and touching it.
    a = rng.uniform(0, 2 * np.pi, 20000)
    for k, cyl in enumerate(c):
        w = unit(cyl[3:6] - cyl[:3])
        u = unit(np.cross(w, [1.0, 0.3, 0.2]))
        v = np.cross(w, u)
        circle = cyl[6] * (np.cos(a)[:, None] * u + np.sin(a)[:, None] * v)
        rim = np.concatenate([cyl[:3] + circle, cyl[3:6] + circle])
        local = rim @ rot[5 + k].T
        assert (local >= lo[5 + k] - 1e-9).all() and (local <= hi[5 + k] + 1e-9).all()
        np.testing.assert_allclose(local.min(0), lo[5 + k], atol=1e-5)
        np.testing.assert_allclose(local.max(0), hi[5 + k], atol=1e-5)
    np.testing.assert_allclose(hi[:5] - lo[:5], 2 * s[:, 3:4] * np.ones(3))
