"""Geometry: built-in primitives, mesh transforms and normals, coarse simplification, the Embree wrapper."""
from __future__ import annotations

import types

import numpy as np
import pytest

from vdmbake.kernels import coarse
from vdmbake.assets import primitives
from vdmbake.common.embree import RayScene
from vdmbake.common.mesh import rotation_xyz, transformed
from vdmbake.common.mesh import TriMesh, vertex_normals
from vdmbake.scene import Transform

FAR = np.array([1e5, -2e5, 3e5])  # "far from the origin": float32 spacing there is 0.0078-0.031

PRIMS = {
    "plane": ("plane", dict(size=2.5, segments=16)),
    "sphere": ("sphere", dict(radius=1.3, segments=128, rings=64)),
    "cylinder": ("cylinder", dict(radius=0.7, height=2.0, segments=128, rings=16, caps=0)),
    "cylinder_caps": ("cylinder", dict(radius=0.7, height=2.0, segments=128, rings=16, caps=1)),
    "cone": ("cone", dict(radius=0.6, height=1.5, segments=128, rings=32, caps=1)),
    "torus": ("torus", dict(major=1.0, minor=0.3, segments=128, rings=64)),
    "vase": ("vase", dict(radius=0.5, height=1.5, segments=128, rings=128)),
}


def _build(key) -> TriMesh:
    name, params = PRIMS[key]
    return primitives.build(name, primitives.PRIMITIVES[name][1](**params))


def _angle_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


def _face_normals(v, f):
    tri = v[f]
    return np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])


def _signed_volume(v, f):
    tri = v[f]
    return np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0


def _weld(mesh: TriMesh):
    """Merge vertices equal in position AND analytic normal (the duplicated seam column and
    pole rows), keeping apart those that differ on purpose (cylinder side vs cap rim).
    Returns (vertices, faces without degenerate-by-index triangles, map old -> new)."""
    key = np.round(np.hstack([mesh.vertices, mesh.normals]), 9)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    f = inv[mesh.faces]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    return mesh.vertices[first], f[keep], inv


def _welded_sphere(radius=1.0, segments=128, rings=64) -> TriMesh:
    m = primitives.sphere(radius, segments, rings)
    v, f, inv = _weld(m)
    return TriMesh(v, f, v / radius)


# ---------------------------------------------------------------------------------------------
# Primitives
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("key", list(PRIMS))
def test_primitive_normals_unit_and_uvs_in_range(key):
    m = _build(key)
    assert m.vertices.shape == m.normals.shape and m.faces.shape[1] == 3
    assert m.faces.min() >= 0 and m.faces.max() < len(m.vertices)
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-12)
    assert m.uvs is not None and m.uvs.shape == (len(m.vertices), 2)
    assert m.uvs.min() >= 0.0 and m.uvs.max() <= 1.0
    assert np.isfinite(m.vertices).all() and np.isfinite(m.normals).all()


@pytest.mark.parametrize("key", list(PRIMS))
def test_primitive_normals_match_face_normal_estimate(key):
    """Analytic normals vs area-weighted face normals of the (welded) fine mesh, within 1 degree. Welding joins
    the seam column and the pole rows, so every vertex, poles included, sees all its faces (the worst is the
    vase's open rim, where only one side contributes)."""
    m = _build(key)
    v, f, inv = _weld(m)
    est = vertex_normals(v, f)[inv]
    ang = _angle_deg(est, m.normals)
    if key == "cone":   # the apex has no normal (each copy keeps its column's slant): left out
        ang = ang[(np.hypot(m.vertices[:, 0], m.vertices[:, 1]) > 1e-9) | (m.vertices[:, 2] < 0)]
    assert ang.max() < 1.0, f"worst vertex {ang.argmax()} at {m.vertices[ang.argmax()]}: {ang.max():.2f} deg"


@pytest.mark.parametrize("key", list(PRIMS))
def test_primitive_faces_counter_clockwise_from_outside(key):
    m = _build(key)
    fn = _face_normals(m.vertices, m.faces)
    area2 = np.linalg.norm(fn, axis=1)
    ok = area2 > 1e-12 * area2.max()  # skip the zero-area triangles at the sphere's poles
    assert ok.mean() > 0.95
    for k in range(3):
        dots = np.einsum("ij,ij->i", fn[ok], m.normals[m.faces[ok, k]])
        assert (dots > 0).all(), f"{(dots <= 0).sum()} faces wound against vertex {k}'s normal"


def test_sphere_normals_are_radial():
    m = _build("sphere")
    r = np.linalg.norm(m.vertices, axis=1)
    np.testing.assert_allclose(r, 1.3, atol=1e-12)
    np.testing.assert_allclose(m.normals, m.vertices / r[:, None], atol=1e-12)


@pytest.mark.parametrize("key,expected", [
    ("sphere", 4.0 / 3.0 * np.pi * 1.3 ** 3),
    ("torus", 2.0 * np.pi ** 2 * 1.0 * 0.3 ** 2),
])
def test_closed_primitive_signed_volume(key, expected):
    """Divergence theorem: positive and close to the analytic volume proves outward winding and
    scale. Inscribed polyhedra are slightly smaller: the error is O(cell angle^2), ~3e-3 here."""
    m = _build(key)
    vol = _signed_volume(m.vertices, m.faces)
    assert vol > 0
    assert vol == pytest.approx(expected, rel=5e-3)
    assert vol < expected  # vertices on the surface, faces inside it


def test_capped_cylinder_volume_is_exact_prism():
    """With caps the cylinder is closed: its volume is exactly the inscribed regular n-gon prism."""
    r, h, n = 0.7, 2.0, 128
    m = primitives.cylinder(r, h, n, 16, 1)
    expected = h * 0.5 * n * r * r * np.sin(2 * np.pi / n)
    assert _signed_volume(m.vertices, m.faces) == pytest.approx(expected, rel=1e-12)
    # without caps the side alone is open: the (origin-dependent) flux misses the two disks
    side = primitives.cylinder(r, h, n, 16, 0)
    assert abs(_signed_volume(side.vertices, side.faces) - expected) > 0.1 * expected


def test_cone_volume_is_exact_pyramid():
    """The closed cone is the pyramid over the inscribed regular n-gon: V = h n r^2 sin(2 pi / n) / 6."""
    r, h, n = 0.6, 1.5, 128
    m = primitives.cone(r, h, n, 8, 1)
    assert _signed_volume(m.vertices, m.faces) == pytest.approx(h * n * r * r * np.sin(2 * np.pi / n) / 6, rel=1e-12)


def test_cylinder_caps_face_outwards():
    m = _build("cylinder_caps")
    z = m.vertices[:, 2]
    cap = np.abs(m.normals[:, 2]) > 0.5
    assert cap.any()
    # top cap normals +Z, bottom -Z
    np.testing.assert_array_equal(np.sign(m.normals[cap, 2]), np.sign(z[cap]))


def test_plane_layout():
    m = _build("plane")
    np.testing.assert_allclose(m.vertices.min(0), [-1.25, -1.25, 0.0])
    np.testing.assert_allclose(m.vertices.max(0), [1.25, 1.25, 0.0])
    np.testing.assert_array_equal(m.normals, np.tile([0.0, 0.0, 1.0], (len(m.vertices), 1)))
    # u follows +x, v follows +y
    np.testing.assert_allclose(m.uvs[:, 0], m.vertices[:, 0] / 2.5 + 0.5, atol=1e-12)
    np.testing.assert_allclose(m.uvs[:, 1], m.vertices[:, 1] / 2.5 + 0.5, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Transforms and vertex normals
# ---------------------------------------------------------------------------------------------

def test_transformed_nonuniform_scale_keeps_normals_perpendicular():
    m = _build("sphere")
    t = Transform(scale=(1.0, 2.5, 0.4), rotate_deg=(10.0, -25.0, 40.0), translate=(3.0, -1.0, 2.0))
    out = transformed(m, t)
    v, f, inv = _weld(out)  # normals weld the same way: transformed duplicates stay duplicates
    est = vertex_normals(v, f)[inv]
    ang = _angle_deg(out.normals, est)
    assert ang.max() < 2.0, f"{ang.max():.2f} deg"
    np.testing.assert_allclose(np.linalg.norm(out.normals, axis=1), 1.0, atol=1e-12)
    # The test discriminates: transforming normals like points (M n) is off by tens of degrees.
    mm = rotation_xyz(t.rotate_deg) @ np.diag(t.scale)
    naive = m.normals @ mm.T
    naive /= np.linalg.norm(naive, axis=1, keepdims=True)
    assert _angle_deg(naive, est).max() > 20.0
    # Positions: scale, then rotate, then translate.
    np.testing.assert_allclose(out.vertices, m.vertices @ mm.T + np.array(t.translate), atol=1e-12)
    # Ellipsoid volume = sphere volume * |det|, and still positive (outward winding).
    assert _signed_volume(out.vertices - np.array(t.translate), out.faces) == pytest.approx(
        _signed_volume(m.vertices, m.faces) * 1.0 * 2.5 * 0.4, rel=1e-9)


def test_transformed_mirror_keeps_outward_winding():
    """A negative scale (rejected by the scene loader, but handled by transformed()) must flip
    the winding so faces stay counter-clockwise from outside."""
    m = _build("torus")
    out = transformed(m, types.SimpleNamespace(scale=(-1.0, 1.0, 1.0), rotate_deg=(0.0, 0.0, 0.0),
                                               translate=(0.0, 0.0, 0.0)))
    assert _signed_volume(out.vertices, out.faces) > 0
    fn = _face_normals(out.vertices, out.faces)
    assert (np.einsum("ij,ij->i", fn, out.normals[out.faces[:, 0]]) > 0).all()


def test_rotation_xyz_orthonormal_det_one():
    rng = np.random.default_rng(3)
    for ang in rng.uniform(-360, 360, size=(20, 3)):
        r = rotation_xyz(ang)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)


def test_rotation_xyz_axes_and_order():
    np.testing.assert_allclose(rotation_xyz((0, 0, 90)) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rotation_xyz((90, 0, 0)) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(rotation_xyz((0, 90, 0)) @ [0, 0, 1], [1, 0, 0], atol=1e-15)
    # X first, then Y (extrinsic): y -> z (about X), then z -> x (about Y).
    # The opposite order would give y -> y -> z.
    np.testing.assert_allclose(rotation_xyz((90, 90, 0)) @ [0, 1, 0], [1, 0, 0], atol=1e-15)


def test_vertex_normals_degenerate_and_isolated():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0],   # a proper triangle in z = 0
                  [2, 0, 0],                          # collinear with 0 and 1
                  [5, 5, 5]], float)                  # used by no face
    f = np.array([[0, 1, 2], [0, 1, 3], [1, 3, 3]])
    n = vertex_normals(v, f)
    assert np.isfinite(n).all()
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(n[:3], np.tile([0, 0, 1.0], (3, 1)), atol=1e-12)
    # The triangle's normal for vertices it touches, whatever the fallback for the others.
    v2 = v.copy()
    v2[2] = [0, -1, 0]  # flips the proper triangle: its vertices must follow, to -Z
    np.testing.assert_allclose(vertex_normals(v2, f)[:3], np.tile([0, 0, -1.0], (3, 1)), atol=1e-12)


def test_vertex_normals_area_weighted():
    # Vertex 0 shared by a big triangle in z=0 and a small one in x=0: leans toward the big one.
    v = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [0, 0, -1], [0, 1, 0]], float)
    f = np.array([[0, 1, 2], [0, 3, 4]])
    n = vertex_normals(v, f)
    big, small = 8.0, 0.5  # areas; face normals +Z and +X, so the sum is (2*0.5, 0, 2*8)
    expected = np.array([2 * small, 0, 2 * big])
    np.testing.assert_allclose(n[0], expected / np.linalg.norm(expected), atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Coarse meshes
# ---------------------------------------------------------------------------------------------

def test_simplify_sphere_tenfold():
    m = primitives.sphere(2.0, 128, 64)  # as the bake sees it: seam and poles unwelded
    c = coarse.simplify(m, 0.1)
    assert 0.09 * len(m.faces) <= len(c.faces) <= 0.11 * len(m.faces)
    used = np.unique(c.faces)
    r = np.linalg.norm(c.vertices[used], axis=1)
    assert np.abs(r - 2.0).max() < 0.01 * 2.0  # measured 0.63% of R
    assert c.uvs is None
    np.testing.assert_allclose(np.linalg.norm(c.normals, axis=1), 1.0, atol=1e-12)
    assert _signed_volume(c.vertices, c.faces) == pytest.approx(4 / 3 * np.pi * 8.0, rel=0.03)


def test_simplify_ratio_one_is_identity():
    m = _build("torus")
    c = coarse.simplify(m, 1.0)
    assert c.vertices is m.vertices and c.faces is m.faces


def test_simplify_far_from_origin_same_shape():
    """A welded sphere at the origin and the same at 1e5 simplify to the same shape: the radius error of the
    coarse mesh is the same both ways (without the re-centring in simplify() the far one comes out clearly
    worse)."""
    m = _welded_sphere(1.0)
    far = TriMesh(m.vertices + FAR, m.faces, m.normals)
    c0, c1 = coarse.simplify(m, 0.1), coarse.simplify(far, 0.1)
    assert len(c1.faces) == len(c0.faces)
    e0 = np.abs(np.linalg.norm(c0.vertices[np.unique(c0.faces)], axis=1) - 1.0).max()
    e1 = np.abs(np.linalg.norm(c1.vertices[np.unique(c1.faces)] - FAR, axis=1) - 1.0).max()
    assert e0 < 0.01
    assert e1 == pytest.approx(e0, abs=1e-6)


# ---------------------------------------------------------------------------------------------
# Embree
# ---------------------------------------------------------------------------------------------

def _sphere_rays(n=300, dist=5.0, seed=1):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u * dist, -u, u


@pytest.mark.parametrize("offset", [np.zeros(3), FAR], ids=["origin", "far"])
def test_embree_hits_unit_sphere(offset):
    m = primitives.sphere(1.0, 128, 64)
    scene = RayScene(m.vertices + offset, m.faces)
    o, d, u = _sphere_rays()
    h = scene.intersect(o + offset, d)
    assert (h.prim >= 0).all()
    # Inscribed polyhedron: the surface lies between r = cos(dphi/2) cos(dtheta/2) and 1.
    r_in = np.cos(np.pi / 128) * np.cos(np.pi / 128)
    assert (h.t >= 4.0 - 1e-5).all() and (h.t <= 5.0 - r_in + 1e-5).all()
    np.testing.assert_allclose(np.linalg.norm(h.ng, axis=1), 1.0, atol=1e-6)
    # Ng is the cross(v1-v0, v2-v0) direction: outward here, so it faces the incoming ray.
    assert (np.einsum("ij,ij->i", h.ng, u) > 0.99).all()
    # The hit point lies on the hit triangle's plane to float32 precision relative to the
    # anchor, far away included (without the anchor it would be off by ~1e-2 at 1e5).
    p = o + h.t[:, None] * d  # relative to the sphere centre
    tri = m.vertices[m.faces[h.prim]]
    fn = _face_normals(m.vertices, m.faces[h.prim])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    assert np.abs(np.einsum("ij,ij->i", p - tri[:, 0], fn)).max() < 1e-5  # measured 8e-7
    # and at the barycentric position it reports
    bary = (1 - h.u - h.v)[:, None] * tri[:, 0] + h.u[:, None] * tri[:, 1] + h.v[:, None] * tri[:, 2]
    assert np.abs(bary - p).max() < 1e-5


def test_embree_far_matches_origin():
    m = primitives.sphere(1.0, 128, 64)
    o, d, _ = _sphere_rays(seed=5)
    h0 = RayScene(m.vertices, m.faces).intersect(o, d)
    h1 = RayScene(m.vertices + FAR, m.faces).intersect(o + FAR, d)
    np.testing.assert_array_equal(h1.prim, h0.prim)
    np.testing.assert_allclose(h1.t, h0.t, atol=1e-4)


def test_embree_misses_and_tfar():
    m = primitives.sphere(1.0, 64, 32)
    scene = RayScene(m.vertices, m.faces)
    o = np.array([[5.0, 0.1, 0.2], [5.0, 0.1, 0.2], [5.0, 3.0, 0.0], [5.0, 0.1, 0.2]])
    d = np.array([[-1.0, 0, 0], [1.0, 0, 0], [-1.0, 0, 0], [-1.0, 0, 0]])
    h = scene.intersect(o, d, tfar=np.array([np.inf, np.inf, np.inf, 3.0]))
    assert h.prim[0] >= 0 and np.isfinite(h.t[0])
    assert (h.prim[1:] == -1).all() and np.isinf(h.t[1:]).all()
    # t is in units of the direction's length
    h2 = scene.intersect(o[:1], 2 * d[:1])
    assert h2.t[0] == pytest.approx(h.t[0] / 2, rel=1e-6)


def test_embree_occluded():
    m = primitives.sphere(1.0, 64, 32)
    scene = RayScene(m.vertices + FAR, m.faces)
    o = FAR + np.array([[5.0, 0.1, 0.2], [5.0, 0.1, 0.2], [5.0, 0.1, 0.2], [0.0, 0.0, 1.5]])
    d = np.array([[-1.0, 0, 0], [1.0, 0, 0], [-1.0, 0, 0], [0.0, 0.0, 1.0]])
    occ = scene.occluded(o, d, tfar=np.array([np.inf, np.inf, 3.0, np.inf]))
    assert occ.tolist() == [True, False, False, False]
    # a shadow ray leaving the surface outward is free; one going inward is blocked
    p = FAR + np.array([[0.0, 0.0, 1.0 + 1e-4]])
    assert scene.occluded(p, np.array([[0.0, 0.0, 1.0]])).tolist() == [False]
    assert scene.occluded(p, np.array([[0.0, 0.0, -1.0]])).tolist() == [True]
    assert scene.rays_cast == 6
