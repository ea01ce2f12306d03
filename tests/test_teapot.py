"""The Utah teapot primitive (vdmbake/assets/teapot.py): the patch data, the Bezier evaluation, the welded
tessellation (border, normals, UVs, frame), and the teapot through the renderer with a mesostructure
(the VDM paper's Fig. 9 scene) and without one. Bounds are the figures measured on llvmpipe (2-core
machine) with modest headroom, each measurement in a comment beside it."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.assets import primitives, teapot
from vdmbake.common.geometry import boundary_edges
from vdmbake.common.mesh import weld

import meso_scenes
from meso_scenes import ORBIT, mean, render
from scenes import TINY_HEAD, bake_and_render, rows_by_label


def rotation_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])


def de_casteljau(points: np.ndarray, t: float) -> np.ndarray:
    """A Bezier curve of any degree at t by repeated linear interpolation (points (k, ...))."""
    while len(points) > 1:
        points = (1.0 - t) * points[:-1] + t * points[1:]
    return points[0]


def patch_by_de_casteljau(ctrl: np.ndarray, s: float, t: float) -> dict:
    """Position and derivatives of a bicubic patch by de Casteljau on the control net and on its
    difference nets (the hodographs: d/ds of a degree-3 net is 3 x the degree-2 net of row differences)."""
    ds, dt = 3.0 * np.diff(ctrl, axis=0), 3.0 * np.diff(ctrl, axis=1)
    f = lambda net, a, b: de_casteljau(np.stack([de_casteljau(row, b) for row in net]), a)  # noqa: E731
    return {"P": f(ctrl, s, t), "Ps": f(ds, s, t), "Pt": f(dt, s, t), "Pss": f(2.0 * np.diff(ds, axis=0), s, t),
            "Pst": f(3.0 * np.diff(ds, axis=1), s, t), "Ptt": f(2.0 * np.diff(dt, axis=1), s, t)}


# ----------------------------------------------------------------------------- the data

def test_the_classic_data():
    """32 patches over 306 points (4 of them unused, as in every copy of the set); the rim, body, lid
    and bottom are four quarter turns of one patch each (to rounding), the whole set is mirror
    symmetric about y = 0, and the extents are the classic ones."""
    C = teapot.control_points()
    assert C.shape == (32, 4, 4, 3)
    assert sorted(len(r) for r in teapot.GROUPS.values()) == [4, 4, 4, 4, 8, 8]
    assert sorted(p for r in teapot.GROUPS.values() for p in r) == list(range(32))
    for first in (0, 4, 8, 20, 24):            # rim, upper body, lower body, knob, lid: clockwise from +X
        for k in range(4):
            assert np.allclose(C[first] @ rotation_z(-90.0 * k).T, C[first + k], atol=1e-12)
    for k in range(4):                         # bottom: anticlockwise
        assert np.allclose(C[28] @ rotation_z(90.0 * k).T, C[28 + k], atol=1e-12)
    points = {tuple(p) for p in C.reshape(-1, 3).round(9)}
    assert points == {tuple(p) for p in (C.reshape(-1, 3) * [1, -1, 1]).round(9)}
    assert np.allclose(C.reshape(-1, 3).min(0), [-3.0, -2.0, 0.0]) and np.allclose(C.reshape(-1, 3).max(0), [3.525, 2.0, 3.15])


def test_the_body_is_a_surface_of_revolution():
    """Points of the rim, body, lid and bottom at one parameter s share their height exactly and their radius to
    within the data's cubic quarter circles (0.45 % of the radius, on the lid 0.6 %; the measured spread is in
    docs/mesostructure.md)."""
    g = np.linspace(0.0, 1.0, 33)
    s, t = np.repeat(g, 33), np.tile(g, 33)
    for name, bound in (("rim", 0.0045), ("body", 0.0045), ("lid", 0.006), ("bottom", 0.0045)):
        for p in teapot.GROUPS[name]:
            P = teapot.evaluate(teapot.control_points()[p], s, t)["P"].reshape(33, 33, 3)
            r = np.hypot(P[..., 0], P[..., 1])
            assert np.ptp(P[..., 2], axis=1).max() < 1e-12
            assert (np.ptp(r, axis=1) <= bound * r.max(1) + 1e-12).all(), name


# ----------------------------------------------------------------------------- evaluation

def test_evaluation_matches_de_casteljau():
    rng = np.random.default_rng(7)
    C = teapot.control_points()
    for p in rng.choice(32, 8, replace=False):
        s, t = rng.random(5), rng.random(5)
        got = teapot.evaluate(C[p], s, t)
        for i in range(5):
            want = patch_by_de_casteljau(C[p], s[i], t[i])
            for key, value in want.items():
                assert np.allclose(got[key][i], value, rtol=1e-12, atol=1e-12), (p, key)


def test_bernstein_basis():
    t = np.linspace(0.0, 1.0, 11)
    assert np.allclose(teapot.bernstein(t).sum(1), 1.0)
    assert np.allclose(teapot.bernstein(t, 1).sum(1), 0.0) and np.allclose(teapot.bernstein(t, 2).sum(1), 0.0)
    h = 1e-6
    assert np.allclose((teapot.bernstein(t + h) - teapot.bernstein(t - h)) / (2 * h), teapot.bernstein(t, 1), atol=1e-8)


def test_shape_tensor_is_the_normals_rate_of_turn():
    """T(x, x) = dN/dtau . dP/dtau / |dP/dtau|^2 along any parameter direction (central differences of the
    analytic unit normal), at random interior parameters of every patch."""
    rng = np.random.default_rng(3)
    C = teapot.control_points()
    h = 1e-5
    unit = lambda d: (lambda n: n / np.linalg.norm(n, axis=1, keepdims=True))(np.cross(d["Pt"], d["Ps"]))  # noqa: E731
    for p in range(32):
        s, t = 0.05 + 0.9 * rng.random(6), 0.05 + 0.9 * rng.random(6)
        a = rng.random(6) * 2 * np.pi
        ds, dt = np.cos(a), np.sin(a)
        d = teapot.evaluate(C[p], s, t)
        T = teapot._shape_tensor(d)
        x = ds[:, None] * d["Ps"] + dt[:, None] * d["Pt"]
        dn = (unit(teapot.evaluate(C[p], s + h * ds, t + h * dt))
              - unit(teapot.evaluate(C[p], s - h * ds, t - h * dt))) / (2 * h)
        rate = np.einsum("ni,ni->n", dn, x) / np.einsum("ni,ni->n", x, x)
        want = np.einsum("ni,nij,nj->n", x, T, x) / np.einsum("ni,ni->n", x, x)
        assert np.allclose(rate, want, rtol=1e-5, atol=1e-5 * np.abs(want).max()), p


# ----------------------------------------------------------------------------- the mesh

@pytest.mark.parametrize("n", [2, 8, 16])
def test_welded_border_is_the_classic_gaps(n):
    """After welding, every edge is shared by two triangles except 16 n border edges: the rim's inner
    lip and the lid's edge (the gap between lid and pot, n per quarter each), the handle's two ends and
    the spout's two ends (n per half tube each); no edge is used more than twice, no triangle collapses.
    At n = 8 the count is the VDM paper's Fig. 9 teapot: 4032 triangles."""
    m = primitives.build("teapot", {"size": 3.15, "segments": n})
    assert len(m.faces) == 32 * 2 * n * n - 8 * n
    ids = weld(m.vertices)
    f = ids[m.faces]
    assert ((f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])).all()
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    counts = np.unique(edges, axis=0, return_counts=True)[1]
    assert counts.max() == 2 and (counts == 1).sum() == 16 * n
    border = boundary_edges(m.faces, ids)
    ends = m.vertices[border]                          # (E, 2, 3): both ends of each border edge
    r = np.hypot(ends[..., 0], ends[..., 1])
    ring = lambda radius: np.isclose(r, radius, rtol=0.005).all(1) & np.isclose(ends[..., 2], 2.4).all(1)  # noqa: E731
    lip, lid = ring(1.4), ring(1.3)                    # to the cubic quarter circles' 0.41 %
    handle, spout = (ends[..., 0] < -1.45).all(1), (ends[..., 0] > 1.65).all(1)
    assert [lip.sum(), lid.sum(), handle.sum(), spout.sum()] == [4 * n, 4 * n, 4 * n, 4 * n]


def test_normals_are_unit_and_outward():
    m = primitives.build("teapot", {"size": 3.15, "segments": 16})
    assert np.allclose(np.linalg.norm(m.normals, axis=1), 1.0)
    tri = m.vertices[m.faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    # the winding agrees with the normals at every corner (measured min cos 0.684 at 16 segments, at the
    # spout's lip, where the surface folds over in a few cells)
    cos = np.einsum("fj,fkj->fk", fn / np.linalg.norm(fn, axis=1, keepdims=True), m.normals[m.faces])
    assert cos.min() > 0.5
    # the body (not the rim's inner lip, not the bottom) faces away from the axis
    radial = m.vertices[:, :2] / np.maximum(np.hypot(m.vertices[:, 0], m.vertices[:, 1]), 1e-12)[:, None]
    body = (m.vertices[:, 2] > 0.15) & (m.vertices[:, 2] < 2.3) & (np.abs(m.vertices[:, 1]) > 0.7)  # off handle, spout
    assert body.sum() > 1000 and (np.einsum("ij,ij->i", m.normals[body, :2], radial[body]) > 0.3).all()
    # the two collapsed patch edges: their limit normals, straight up and down
    top = np.isclose(m.vertices, [0, 0, 3.15]).all(1)
    bottom = np.isclose(m.vertices, [0, 0, 0]).all(1)
    assert top.any() and bottom.any()
    assert np.allclose(m.normals[top], [0, 0, 1]) and np.allclose(m.normals[bottom], [0, 0, -1])
    # the enclosed volume is positive (the classic gaps are small; measured 25.87 at 16 segments)
    assert 25.0 < np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6 < 26.5


def test_uvs_and_their_charts():
    """UVs finite in [0, 1]; each copy of a point in one chart has the same UV, but for the u seam of
    the turn (u 0 and 1) and the collapsed edges (any u); the maps are right-handed seen from outside."""
    m = primitives.build("teapot", {"size": 3.15, "segments": 8})
    assert np.isfinite(m.uvs).all() and m.uvs.min() >= 0.0 and m.uvs.max() <= 1.0
    f = m.frame
    pole = np.isclose(m.vertices[:, :2], 0).all(1)
    # right-handed: (dP/du x dP/dv) . n = sin(angle between them) |dP/du| |dP/dv| > 0 (measured min
    # sin 0.449, where the tubes' parameter lines meet askew); dP/du vanishes on the collapsed edges
    handed = np.einsum("ij,ij->i", np.cross(f.dpdu, f.dpdv), m.normals)
    scale = np.linalg.norm(f.dpdu, axis=1) * np.linalg.norm(f.dpdv, axis=1)
    assert (handed[~pole] > 0.4 * scale[~pole]).all() and np.allclose(f.dpdu[pole], 0.0)
    # copies of one point: the same v and u, but at the collapsed edges (any u, along the edge), at the
    # seam of each chart's turn (u differs by the chart's u span: 1 for the pot and the lid, the tube's
    # span for the handle and the spout) and where the handle's lower end touches the body, at the
    # control point (-2, 0, 0.9) that both use (copies in two charts)
    spans = {round(sum(teapot.layout()[p][2] for p in patches), 9) for patches, _, _ in
             (chart[0] for chart in teapot.CHARTS.values())}
    assert len(spans) == 3 and 1.0 in spans
    touch = np.isclose(m.vertices, [-2.0, 0.0, 0.9]).all(1)
    # the body's copy and the handle's keep their own normals (measured 114 degrees apart)
    assert touch.sum() == 3 and len(np.unique(m.normals[touch].round(6), axis=0)) == 2
    ids = weld(m.vertices)
    for i in np.flatnonzero(np.bincount(ids) > 1):
        uv = m.uvs[ids == i]
        if pole[ids == i].any():
            assert np.ptp(uv[:, 1]) < 1e-12
        elif not touch[ids == i].any():
            assert np.ptp(uv[:, 1]) < 1e-12 and round(np.ptp(uv[:, 0]), 9) in spans
    # no triangle spans a seam: its UV edges are at most one cell of its chart
    d = np.abs(m.uvs[m.faces] - m.uvs[np.roll(m.faces, 1, axis=1)])
    assert d[..., 0].max() <= 0.25 / 8 + 1e-12 and d[..., 1].max() <= max(p[4] for p in teapot.layout().values()) / 8 + 1e-12


def test_frame_is_finite_and_consistent():
    m = primitives.build("teapot", {"size": 2.0, "segments": 8})
    f = m.frame
    for a in (f.dpdu, f.dpdv, f.k1, f.k2, f.d1):
        assert np.isfinite(a).all()
    assert (f.k1 >= f.k2).all()
    assert np.allclose(np.linalg.norm(f.d1, axis=1), 1.0)
    assert np.allclose(np.einsum("ij,ij->i", f.d1, m.normals), 0.0, atol=1e-12)
    assert np.allclose(np.einsum("ij,ij->i", f.dpdv, m.normals), 0.0, atol=1e-9)
    # the collapsed edges are umbilic by the 4-fold symmetry (k1 = k2), dP/du vanishes there
    pole = np.isclose(m.vertices[:, :2], 0).all(1)
    assert np.allclose(f.k1[pole], f.k2[pole], rtol=1e-3) and np.allclose(f.dpdu[pole], 0.0)
    # size scales positions, tangents and radii of curvature alike
    big = primitives.build("teapot", {"size": 4.0, "segments": 8})
    assert np.allclose(big.vertices, 2 * m.vertices) and np.allclose(big.frame.k1, f.k1 / 2)
    assert np.allclose(big.frame.dpdu, 2 * f.dpdu) and np.allclose(big.uvs, m.uvs)


def test_frame_against_the_normals_rate_of_turn_on_the_mesh():
    """The welded mesh's frame: along every edge, II(e, e) from k1, k2, d1 (Euler) against the turn of the
    vertex normals (N_j - N_i) . (P_j - P_i) / |P_j - P_i|^2, relative to the larger of 1 and the largest |k| at
    the edge's ends. The patches meet with continuous normals but not continuous curvature, so the border rows
    disagree by the jump: the median, 90th and 99th percentiles stay within their bounds (first order in the
    cell size)."""
    m = primitives.build("teapot", {"size": 3.15, "segments": 64})
    f = m.frame
    e = np.concatenate([m.faces[:, [0, 1]], m.faces[:, [1, 2]], m.faces[:, [2, 0]]])
    dp = m.vertices[e[:, 1]] - m.vertices[e[:, 0]]
    rate = np.einsum("ij,ij->i", m.normals[e[:, 1]] - m.normals[e[:, 0]], dp) / np.einsum("ij,ij->i", dp, dp)
    u = dp / np.linalg.norm(dp, axis=1, keepdims=True)
    ii = lambda k: f.k1[k] * np.einsum("ij,ij->i", u, f.d1[k]) ** 2 \
        + f.k2[k] * np.einsum("ij,ij->i", u, np.cross(m.normals[k], f.d1[k])) ** 2  # noqa: E731
    k = np.maximum(np.maximum(np.abs(f.k1), np.abs(f.k2))[e].max(1), 1.0)
    err = np.abs(rate - 0.5 * (ii(e[:, 0]) + ii(e[:, 1]))) / k
    assert np.median(err) < 0.0003 and np.percentile(err, 90) < 0.005 and np.percentile(err, 99) < 0.03


# ----------------------------------------------------------------------------- rendered

def test_plain_teapot_mesh_matches_its_reference(tmp_path):
    """The tessellated teapot drawn by `mesh` against the same triangles traced by Embree (64^2, the paper's 8
    segments): mean and p95 ΔLuv near 0 and IoU 1 (what remains lies on shadow edges: the renderer's shadow map
    against the traced shadow rays)."""
    teapot_object = '[[objects]]\nname = "t"\nprimitive = "teapot"\ntechniques = { mesh = {} }\n'
    r, _ = bake_and_render(tmp_path, TINY_HEAD.replace("[32, 32]", "[64, 64]") + teapot_object, "--no-flip")
    assert r.exit_code == 0, r.output
    row = rows_by_label(r)["mesh"]
    assert row["mean_dluv"] < 0.2 and row["p95_dluv"] < 0.5 and row["iou"] >= 0.999


@pytest.mark.slow
def test_teapot_with_bricks(tmp_path):
    """VDM Fig. 9: the teapot with a brick mesostructure, 64^2, two orbit frames, every mesostructure technique
    against the displaced teapot (16 segments: VDM interpolates the curvature per vertex, and at 8 the tight rim
    and knob spread theirs over the body's large triangles). Each within its bound, ranked relief < vdm < bump <
    mesh and pom < bump, vdm and displaced near IoU 1."""
    obj = 'primitive = "teapot"\nparams = { size = 1.0, segments = 16 }'
    text = meso_scenes.scene(ORBIT.format(count=2), obj, 'mesh = {}, vdm = { k = ["all"] }, pom = { steps = [16] }, '
                             'relief = { iterations = [16] }, bump = {}, displaced = { levels = [1] }',
                             size=16, tiling=(16, 6), res=64, shadow_map=512, curvatures=16)
    rows, _ = render(tmp_path, text)
    assert mean(rows, "vdm@all") <= 1.6                                # 1.410
    assert mean(rows, "pom@16") <= 1.85                                # 1.640
    assert mean(rows, "relief@16") <= 0.65                             # 0.533
    assert mean(rows, "bump") <= 2.2                                   # 1.970
    assert mean(rows, "displaced@1") <= 1.9                            # 1.699
    assert mean(rows, "relief@16") < mean(rows, "vdm@all") < mean(rows, "bump") < mean(rows, "mesh")
    assert mean(rows, "pom@16") < mean(rows, "bump")
    assert rows["vdm@all"]["iou"] >= 0.995                             # 0.9966
    assert rows["displaced@1"]["iou"] >= 0.999                         # 0.9995
