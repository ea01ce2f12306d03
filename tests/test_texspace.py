"""Texture space of the mesostructure (VDM sec. 3.2) and conventional displacement (numpy only):
texture-space curvature against hand-derived values on the primitives, the curvature range the
VDM table samples, texture-to-world normals, and the subdivided, displaced reference geometry."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.common import geometry, texspace
from vdmbake.assets import primitives
from vdmbake.kernels import vdm
from vdmbake.common.mesh import TriMesh

RNG = np.random.default_rng(2003)
E_U, E_V = np.array([[1.0, 0.0]]), np.array([[0.0, 1.0]])


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def angles(count):
    a = np.arange(count) * np.pi / count
    return np.stack([np.cos(a), np.sin(a)], 1)


# ----------------------------------------------------------------------------- texture_curvature

def test_plane_has_zero_texture_curvature():
    m = primitives.plane(3.0, 4)
    for tiling in ((1.0, 1.0), (5.0, 0.5)):
        c = texspace.texture_curvature(m.frame, m.normals, tiling, angles(16))
        assert c.shape == (len(m.vertices), 16) and not c.any()


@pytest.mark.parametrize("tiling", [(1.0, 1.0), (8.0, 2.0), (3.0, 7.0)])
def test_cylinder_texture_curvature_by_hand(tiling):
    """Side of a cylinder of radius r: J_u = dP/du / t_u runs around (|dP/du| = 2 pi r), J_v along the
    axis; c(e_u) = k |J_u|^2 / s_n with k = 1 / r, s_n = sqrt(|J_u| |J_v|) (J_u is orthogonal to J_v);
    c(e_v) = 0 (the axis is straight); in between Euler's formula, c(e) = c(e_u) e_u^2."""
    r, height = 0.5, 2.0
    m = primitives.cylinder(r, height, 32, 4, 0)
    ju, jv = 2 * np.pi * r / tiling[0], height / tiling[1]
    s_n = np.sqrt(ju * jv)
    expected_u = (1 / r) * ju ** 2 / s_n
    c = texspace.texture_curvature(m.frame, m.normals, tiling, np.concatenate([E_U, E_V, unit([[1.0, 1.0]])]))
    assert np.allclose(c[:, 0], expected_u, rtol=1e-12)
    assert np.allclose(c[:, 1], 0.0, atol=1e-12)
    assert np.allclose(c[:, 2], 0.5 * expected_u, rtol=1e-12)
    # and from the frame itself, the same number
    J = texspace.jacobian(m.frame, tiling)
    by_frame = m.frame.k1 * np.einsum("vi,vi->v", J[..., 0], J[..., 0]) / texspace.normal_scale(J)
    assert np.allclose(c[:, 0], by_frame, rtol=1e-12)


def test_sphere_is_convex_away_from_the_poles():
    """k1 = k2 = 1 / R > 0 (convex): c(e) = |J e|^2 / (R s_n) > 0 for every direction."""
    R, tiling = 2.0, (4.0, 2.0)
    m = primitives.sphere(R, 32, 16)
    c = texspace.texture_curvature(m.frame, m.normals, tiling, angles(12))
    pole = np.abs(m.vertices[:, 2]) > R * (1 - 1e-9)
    assert pole.sum() == 2 * 33
    assert np.isfinite(c).all() and (c[~pole] > 0).all()
    J = texspace.jacobian(m.frame, tiling)[~pole]
    x = np.einsum("vij,dj->vdi", J, angles(12))
    expected = (x ** 2).sum(-1) / (R * texspace.normal_scale(J)[:, None])
    assert np.allclose(c[~pole], expected, rtol=1e-12)


def test_sphere_poles_follow_the_degenerate_map_rule():
    """At a pole dP/du = 0 and s_n = 0: texture_curvature's docstring gives such vertices 0, so the
    table range (curvature_range) is that of the rest of the sphere. Analytically c along v grows
    like 1 / sqrt(sin(polar angle)) towards a pole; on the ring next to it (polar angle pi / 48,
    tiling (8, 4), R = 1) it is |J_v|^1.5 / (R |J_u|^0.5) = 3.07.
    Measured: the south pole (sin 0 = 0 exactly) gets 0, but the north pole's dP/du is sin(pi) * 2 pi
    ~ 7.7e-16, not 0, so s_n ~ 1e-8 passes the s_n > 0 test and c there is ~7e7: curvature_range of
    the default sphere primitive is (0, 7.1e7), and a sphere's VDM table is sampled at
    [0, 6.7e7, 1.3e8, 2.0e8] (curvatures = 4)."""
    R, tiling = 1.0, (8.0, 4.0)
    m = primitives.sphere(R, 96, 48)
    c = texspace.texture_curvature(m.frame, m.normals, tiling, angles(8))
    south, north = m.vertices[:, 2] < -R * (1 - 1e-9), m.vertices[:, 2] > R * (1 - 1e-9)
    assert not c[south].any()
    ju, jv = 2 * np.pi * R * np.sin(np.pi / 48) / tiling[0], np.pi * R / tiling[1]
    ring_next_to_pole = jv ** 1.5 / (R * ju ** 0.5)
    assert ring_next_to_pole == pytest.approx(3.07, abs=0.01)
    lo, hi = texspace.curvature_range(m.frame, m.normals, tiling)
    assert hi <= ring_next_to_pole * (1 + 1e-9), f"sphere curvature range reaches {hi:.3g}"
    assert not c[north].any(), f"north pole texture curvature {np.abs(c[north]).max():.3g}, not 0"


# ----------------------------------------------------------------------------- curvature_range

def test_plane_curvature_range_is_the_single_sample_zero():
    """The 'leave out' rule: a plane needs only c = 0, one curvature sample, whatever the count asked for."""
    m = primitives.plane(2.0, 8)
    lo_hi = texspace.curvature_range(m.frame, m.normals, (2.0, 2.0))
    assert lo_hi == (0.0, 0.0)
    assert vdm.curvature_samples(*lo_hi, 16) == (0.0,)


def torus_extremes(R, r, tiling):
    """Analytic texture curvatures of a torus. At tube angle a, rho = R + r cos a: |J_u| = 2 pi rho / t_u
    (curvature cos a / rho), |J_v| = 2 pi r / t_v (curvature 1 / r), orthogonal, along the principal
    directions, so c(e) lies between A = k1 |J_u|^2 / s_n and B = k2 |J_v|^2 / s_n:
    A = 2 pi cos a sqrt(rho / r) sqrt(t_v) / t_u^1.5, B = 2 pi sqrt(r / rho) sqrt(t_u) / t_v^1.5.
    The least is A at the inner equator (a = pi); the greatest A at the outer one or B at the inner one."""
    tu, tv = tiling
    A = lambda ca: 2 * np.pi * ca * np.sqrt((R + r * ca) / r) * np.sqrt(tv) / tu ** 1.5  # noqa: E731
    B = lambda ca: 2 * np.pi * np.sqrt(r / (R + r * ca)) * np.sqrt(tu) / tv ** 1.5     # noqa: E731
    return A(-1.0), max(A(1.0), B(-1.0))


@pytest.mark.parametrize("tiling", [(1.0, 1.0), (8.0, 2.0), (16.0, 4.0)])
def test_torus_curvature_range_brackets_the_analytic_extremes(tiling):
    R, r = 1.0, 0.35
    lo, hi = torus_extremes(R, r, tiling)
    assert lo < 0 < hi
    # rings even: both equators are vertex rings, and the principal texture directions are among
    # the sampled ones: the range is the analytic one
    m = primitives.torus(R, r, 64, 32)
    got = texspace.curvature_range(m.frame, m.normals, tiling)
    assert got == pytest.approx((lo, hi), rel=1e-9)
    # rings odd: the inner equator is not a vertex: the range lies inside, and near
    m = primitives.torus(R, r, 64, 31)
    glo, ghi = texspace.curvature_range(m.frame, m.normals, tiling)
    assert lo <= glo < 0 < ghi <= hi * (1 + 1e-12)
    assert glo == pytest.approx(lo, rel=0.02) and ghi == pytest.approx(hi, rel=0.02)
    # every vertex and direction lies in the sampled table range
    c = texspace.texture_curvature(m.frame, m.normals, tiling, angles(7))
    assert (c >= glo - 1e-12).all() and (c <= ghi + 1e-12).all()


def test_torus_range_matches_tiling_8_2_figures():
    """The numbers the render tests' torus tables are sampled over (tiling [8, 2])."""
    m = primitives.torus(1.0, 0.35, 64, 32)
    lo, hi = texspace.curvature_range(m.frame, m.normals, (8.0, 2.0))
    assert lo == pytest.approx(-0.535159, abs=1e-6) and hi == pytest.approx(4.610598, abs=1e-6)


# ----------------------------------------------------------------------------- world_normals

def random_frames(count):
    N = unit(RNG.normal(size=(count, 3)))
    J = RNG.normal(size=(count, 3, 2))
    J -= N[:, :, None] * np.einsum("vi,vij->vj", N, J)[:, None, :]    # into the tangent plane
    return J, N


def test_texture_normal_up_is_the_surface_normal():
    J, N = random_frames(200)
    n = texspace.world_normals(J, N, np.tile([0.0, 0.0, 1.0], (200, 1)))
    assert np.allclose(n, N, atol=1e-12)
    m = primitives.torus(1.0, 0.35, 32, 16)
    Jt = texspace.jacobian(m.frame, (8.0, 2.0))
    n = texspace.world_normals(Jt, m.normals, np.tile([0.0, 0.0, 1.0], (len(m.normals), 1)))
    assert np.allclose(n, m.normals, atol=1e-12)


def test_world_normals_are_unit_and_the_inverse_transpose():
    """n_world ~ M^-T n_tex, M = [J_u | J_v | s_n N]: the normal of the mapped mesostructure."""
    J, N = random_frames(500)
    n_tex = unit(RNG.normal(size=(500, 3)))
    n = texspace.world_normals(J, N, n_tex)
    assert np.isfinite(n).all() and np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    s_n = texspace.normal_scale(J)
    M = np.concatenate([J, (s_n[:, None] * N)[:, :, None]], 2)
    ref = unit(np.einsum("vji,vj->vi", np.linalg.inv(M), n_tex))
    assert np.allclose(n, ref, atol=1e-9)
    # a normal is orthogonal to every mapped tangent of the texture-space surface
    t_tex = unit(np.cross(n_tex, RNG.normal(size=(500, 3))))
    t_world = np.einsum("vij,vj->vi", M, t_tex)
    assert np.abs(np.einsum("vi,vi->v", n, t_world)).max() < 1e-9 * np.abs(t_world).max()


@pytest.mark.parametrize("which", ["zero", "rank one"])
def test_world_normals_finite_for_a_degenerate_map(which):
    """A pole: J = 0 (or one column 0): the clamped determinant keeps it finite, the result unit."""
    count = 20
    _, N = random_frames(count)
    J = np.zeros((count, 3, 2))
    if which == "rank one":
        J[:, :, 0] = unit(np.cross(N, RNG.normal(size=(count, 3))))
    n_tex = unit(RNG.normal(size=(count, 3)) + [0, 0, 2])
    n = texspace.world_normals(J, N, n_tex)
    assert np.isfinite(n).all() and np.allclose(np.linalg.norm(n, axis=1), 1.0)
    if which == "zero":
        assert np.allclose(n, N)      # no tangent map: only the normal's part survives
    # the texture normal (0, 0, 1) still maps to N
    assert np.allclose(texspace.world_normals(J, N, np.tile([0.0, 0, 1], (count, 1))), N)


# ----------------------------------------------------------------------------- subdivision

def welded(mesh: TriMesh) -> tuple[np.ndarray, np.ndarray]:
    """The primitive's seam vertices merged: a closed surface (positions, faces)."""
    key = np.round(mesh.vertices, 9)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return mesh.vertices[first], inv.ravel()[mesh.faces]


def edge_use(faces):
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return counts


def test_subdivision_keeps_a_closed_torus_watertight():
    m = primitives.torus(1.0, 0.35, 12, 8)
    pos, faces = welded(m)
    normals = unit(pos - np.c_[unit(pos[:, :2]), np.zeros(len(pos))])   # any unit vectors will do
    assert len(pos) == 12 * 8 and (edge_use(faces) == 2).all()
    f, a = faces, {"pos": pos, "normal": normals}
    for level in range(1, 4):
        v_before, e_before = len(a["pos"]), len(edge_use(f))
        f, a = geometry.subdivide(f, a)
        counts = edge_use(f)
        assert (counts == 2).all(), f"level {level}: an edge is not shared by exactly two faces"
        assert len(f) == 8 * 12 * 2 * 4 ** level
        assert len(a["pos"]) == v_before + e_before          # one new vertex per edge, shared
        assert len(a["pos"]) - len(counts) + len(f) == 0      # Euler characteristic of a torus
        assert np.allclose(np.linalg.norm(a["normal"], axis=1), 1.0)
        assert len(np.unique(np.round(a["pos"], 12), axis=0)) == len(a["pos"])   # no duplicate midpoints


def test_subdivision_interpolates_uvs_and_positions():
    m = primitives.torus(1.0, 0.35, 8, 6)
    attrs = {"pos": m.vertices, "normal": m.normals, "uv": m.uvs}
    f, a = geometry.subdivide(m.faces, attrs)
    e = np.sort(np.concatenate([m.faces[:, [0, 1]], m.faces[:, [1, 2]], m.faces[:, [2, 0]]]), axis=1)
    uniq = np.unique(e, axis=0)
    n = len(m.vertices)
    assert np.array_equal(a["uv"][:n], m.uvs) and np.array_equal(a["pos"][:n], m.vertices)
    assert np.allclose(a["uv"][n:], 0.5 * (m.uvs[uniq[:, 0]] + m.uvs[uniq[:, 1]]))
    assert np.allclose(a["pos"][n:], 0.5 * (m.vertices[uniq[:, 0]] + m.vertices[uniq[:, 1]]))
    mid_n = m.normals[uniq[:, 0]] + m.normals[uniq[:, 1]]
    assert np.allclose(a["normal"][n:], unit(mid_n))

    def uv_area(faces, uv):
        t = uv[faces]
        d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
        return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])

    parent, child = uv_area(m.faces, m.uvs), uv_area(f, a["uv"])
    assert parent.sum() == pytest.approx(1.0) and child.sum() == pytest.approx(1.0)   # the UV square, tiled
    assert np.sign(child).min() == np.sign(parent).min() == 1                          # no flipped child
    assert np.allclose(np.sort(child), np.sort(np.repeat(parent, 4) / 4))             # midpoint split: 4 quarters


# ----------------------------------------------------------------------------- displacement

def torus_s_n(mesh, tiling):
    """s_n = sqrt(|J_u x J_v|) by hand: |dP/du| = 2 pi rho (rho the distance from the axis), |dP/dv| = 2 pi r."""
    rho = np.hypot(mesh.vertices[:, 0], mesh.vertices[:, 1])
    return 2 * np.pi * np.sqrt(rho * 0.35 / (tiling[0] * tiling[1]))


@pytest.mark.parametrize("levels", [0, 1])
def test_zero_depth_or_all_top_heights_leave_the_base(levels):
    m = primitives.torus(1.0, 0.35, 16, 8)
    rnd = RNG.uniform(size=(8, 8))
    base_f, base = m.faces, {"pos": m.vertices}
    for _ in range(levels):
        base_f, base = geometry.subdivide(base_f, {**base, "normal": np.ones_like(base["pos"])})
    for heights, depth in ((rnd, 0.0), (np.ones((8, 8)), 0.1)):
        d = geometry.displaced(m, heights, vdm.height_normals(heights, depth), depth, (4.0, 2.0), levels)
        assert np.array_equal(d.faces, base_f)
        assert np.allclose(d.vertices, base["pos"], atol=1e-15)
        assert np.isfinite(d.normals).all()


@pytest.mark.parametrize("levels", [0, 1])
def test_constant_height_moves_every_vertex_along_its_normal(levels):
    """h constant: the offset surface, depth * s_n * (1 - h) inward along the normal."""
    tiling, depth, h = (4.0, 2.0), 0.05, 0.3
    m = primitives.torus(1.0, 0.35, 16, 8)
    flat = np.full((8, 8), h)
    d = geometry.displaced(m, flat, vdm.height_normals(flat, depth), depth, tiling, levels)
    f, a = m.faces, {"pos": m.vertices, "normal": m.normals, "uv": m.uvs}
    for _ in range(levels):
        f, a = geometry.subdivide(f, a)
    shift = a["pos"] - d.vertices
    dist = np.linalg.norm(shift, axis=1)
    assert np.allclose(shift, a["normal"] * dist[:, None], atol=1e-12)       # along the (interpolated) normal
    if levels == 0:
        assert np.allclose(dist, depth * torus_s_n(m, tiling) * (1 - h), rtol=1e-12)
    else:   # midpoints: s_n of the interpolated, tangent-projected J (not the analytic one of the torus)
        _, a2 = geometry.subdivide(m.faces, {"pos": m.vertices, "normal": m.normals,
                                              "dpdu": m.frame.dpdu, "dpdv": m.frame.dpdv})
        J = np.stack([a2["dpdu"] / tiling[0], a2["dpdv"] / tiling[1]], -1)
        J -= a2["normal"][:, :, None] * np.einsum("vi,vij->vj", a2["normal"], J)[:, None, :]
        assert np.allclose(dist, depth * texspace.normal_scale(J) * (1 - h), rtol=1e-12)
        n0 = len(m.vertices)
        assert np.allclose(dist[:n0], depth * torus_s_n(m, tiling) * (1 - h), rtol=1e-12)
    # a constant height field is flat: its shading normal is the surface normal
    assert np.allclose(d.normals, a["normal"], atol=1e-9)


@pytest.mark.parametrize("size,tiling,shape", [(16, (3.0, 2.0), "plane"), (32, (8.0, 2.0), "torus"),
                                               (4, (1.0, 1.0), "torus")])
def test_reference_levels_bring_edges_under_half_a_texel(size, tiling, shape):
    m = primitives.plane(2.0, 4) if shape == "plane" else primitives.torus(1.0, 0.35, 32, 16)
    levels = geometry.reference_levels(m, size, tiling)
    f, a = m.faces, {"pos": m.vertices, "normal": m.normals, "uv": m.uvs}
    coarser = None
    for _ in range(levels):
        coarser = TriMesh(a["pos"], f, a["normal"], a["uv"])
        f, a = geometry.subdivide(f, a)
    # half a texel up to rounding: an edge of 0.5 + 3e-14 texels (this torus at 32 texels, tiling 8 x 2) needs
    # no extra level, which would quadruple the faces
    assert geometry.edge_texels(TriMesh(a["pos"], f, a["normal"], a["uv"]), size, tiling) <= 0.5 * (1 + 1e-9)
    if levels:   # and no more levels than needed
        assert geometry.edge_texels(coarser, size, tiling) > 0.5
    else:
        assert geometry.edge_texels(m, size, tiling) <= 0.5


def test_reference_levels_figures():
    """Plane of 4 segments, 16 texels x 3 tiles: edges of 12 texels -> 5 levels (12 / 32 <= 0.5 < 12 / 16)."""
    m = primitives.plane(2.0, 4)
    assert geometry.edge_texels(m, 16, (3.0, 2.0)) == pytest.approx(12.0)
    assert geometry.reference_levels(m, 16, (3.0, 2.0)) == 5
