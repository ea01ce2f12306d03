"""Estimated surface frames (vdmbake.kernels.curvature) against the primitives' analytic ones.

Every bound sits a little above the value measured when it was set (the comment beside it)."""
from __future__ import annotations

import numpy as np
import trimesh

from vdmbake.assets import primitives
from vdmbake.kernels.curvature import estimate_frame
from vdmbake.common.mesh import rotation_xyz
from vdmbake.common.mesh import TriMesh, vertex_normals


def _estimate(m: TriMesh, normals=None):
    return estimate_frame(m.vertices, m.faces, m.normals if normals is None else normals, m.uvs)


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def _rel(est, ref):
    return np.linalg.norm(est - ref, axis=1) / np.linalg.norm(ref, axis=1)


def _sorted_pair(f):
    return np.sort(np.stack([f.k1, f.k2], 1), 1)


def _assert_valid(f, normals):
    for name in ("dpdu", "dpdv", "k1", "k2", "d1"):
        assert np.isfinite(getattr(f, name)).all(), name
    assert np.allclose(np.linalg.norm(f.d1, axis=1), 1.0)
    assert np.abs(_dot(f.d1, normals)).max() < 1e-12
    assert (f.k1 >= f.k2).all()                                          # documented ordering


def test_sphere_with_exact_normals_is_exact():
    m = primitives.sphere(2.0, 96, 48)
    f = _estimate(m)
    _assert_valid(f, m.normals)
    # dN = dP / R along every edge, so the per-face fit is exact: only rounding is left, the pole
    # rows (which hold zero-area faces, area < 1e-17) included ...
    tri = m.vertices[m.faces]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    used = np.zeros(len(m.vertices), bool)
    used[m.faces[area > 1e-9].ravel()] = True                           # real faces: area >= 1.1e-3
    assert np.abs(f.k1[used] - 0.5).max() < 1e-13 and np.abs(f.k2[used] - 0.5).max() < 1e-13  # measured 6.6e-15
    # ... except two pole copies that only zero-area faces touch: no estimate, zero curvature.
    assert (~used).sum() == 2 and not f.k1[~used].any() and not f.k2[~used].any()


def test_sphere_with_mesh_normals():
    """As a mesh file arrives: welded vertices, area-weighted vertex normals (not exact)."""
    m = primitives.sphere(2.0, 96, 48)
    welded = trimesh.Trimesh(m.vertices, m.faces, process=False)
    welded.merge_vertices()
    v, faces = np.asarray(welded.vertices), np.asarray(welded.faces)
    n = vertex_normals(v, faces)
    f = estimate_frame(v, faces, n, np.zeros((len(v), 2)))
    _assert_valid(f, n)
    away = np.abs(v[:, 2]) < 0.95 * 2.0                                 # away from the poles
    err = np.abs(np.concatenate([f.k1[away], f.k2[away]]) - 0.5) / 0.5
    assert np.median(err) < 2e-3                                        # measured 1.1e-3
    assert np.percentile(err, 95) < 1e-2                                # measured 6.7e-3
    assert err.max() < 1e-2                                             # measured 7.5e-3


def test_torus_principal_curvatures_and_directions():
    a, b = 1.0, 0.35
    m = primitives.torus(a, b, 96, 48)
    f = _estimate(m)
    _assert_valid(f, m.normals)
    cos_theta = (np.hypot(m.vertices[:, 0], m.vertices[:, 1]) - a) / b
    analytic = np.sort(np.stack([np.full(len(cos_theta), 1 / b), cos_theta / (a + b * cos_theta)], 1), 1)
    assert np.allclose(_sorted_pair(m.frame), analytic)
    err = np.abs(_sorted_pair(f) - analytic).ravel() * b                # relative to the largest |k|, 1/b
    assert np.median(err) < 1e-3                                        # measured 7.7e-4
    assert np.percentile(err, 95) < 3e-3                                # measured 2.2e-3
    assert err.max() < 2e-2                                             # measured 1.2e-2
    # The estimated direction whose curvature is nearer the analytic k1 is the analytic d1.
    same = np.abs(f.k1 - m.frame.k1) < np.abs(f.k2 - m.frame.k1)
    d = np.where(same[:, None], f.d1, np.cross(m.normals, f.d1))
    separated = np.abs(m.frame.k1 - m.frame.k2) > 0.5 / b             # everywhere on this torus
    misalign = 1 - np.abs(_dot(d, m.frame.d1))[separated]
    assert separated.mean() > 0.99
    assert np.median(misalign) < 1e-7                                   # measured 2.5e-8
    assert misalign.max() < 1e-3                                        # measured 3.8e-4


def test_vase_curvatures():
    m = primitives.vase(0.5, 1.5, 96, 96)
    f = _estimate(m)
    _assert_valid(f, m.normals)
    k_max = np.abs(_sorted_pair(m.frame)).max()                         # 8.3, around the neck
    err = np.abs(_sorted_pair(f) - _sorted_pair(m.frame)) / k_max
    inner = (m.uvs[:, 1] > 0) & (m.uvs[:, 1] < 1)                       # off the two open rims
    assert np.median(err[inner]) < 2e-4                                 # measured 1.4e-4
    assert np.percentile(err[inner], 95) < 1e-3                         # measured 8.4e-4
    assert err[inner].max() < 1.2e-2                                    # measured 9.1e-3
    assert err[~inner].max() < 2.5e-2                                   # one-sided rims: measured 1.7e-2


def test_cylinder_orders_the_curvatures_with_their_directions():
    m = primitives.cylinder(0.5, 2.0, 64, 8, 0)
    f = _estimate(m)
    _assert_valid(f, m.normals)
    assert np.abs(f.k1 - 2.0).max() < 1e-12 and np.abs(f.k2).max() < 1e-12   # measured 1.3e-15, 5.6e-17
    assert (1 - np.abs(_dot(f.d1, m.frame.d1))).max() < 1e-12                 # measured 4.4e-16


def test_plane_is_flat_with_exact_tangents():
    m = primitives.plane(2.0, 16)
    f = _estimate(m)
    _assert_valid(f, m.normals)
    assert not f.k1.any() and not f.k2.any()
    assert np.allclose(f.dpdu, m.frame.dpdu, rtol=0, atol=1e-14)        # measured 0
    assert np.allclose(f.dpdv, m.frame.dpdv, rtol=0, atol=1e-14)


def test_sphere_tangents():
    m = primitives.sphere(2.0, 96, 48)
    f = _estimate(m)
    u = m.uvs[:, 0]
    sel = (u > 0) & (u < 1) & (np.abs(m.normals[:, 2]) < 0.9)           # off the seam and the poles
    du, dv = _rel(f.dpdu[sel], m.frame.dpdu[sel]), _rel(f.dpdv[sel], m.frame.dpdv[sel])
    assert np.median(du) < 2e-3 and du.max() < 7e-3                     # measured 1.3e-3, 5.1e-3
    assert np.median(dv) < 2e-3 and dv.max() < 2e-3                     # measured 1.1e-3, 1.3e-3


def test_torus_tangents_converge():
    errors = []
    for segments, rings in ((96, 48), (192, 96)):
        m = primitives.torus(1.0, 0.35, segments, rings)
        f = _estimate(m)
        u, v = m.uvs.T
        sel = (u > 0) & (u < 1) & (v > 0) & (v < 1)                      # off the seams
        du, dv = _rel(f.dpdu[sel], m.frame.dpdu[sel]), _rel(f.dpdv[sel], m.frame.dpdv[sel])
        errors.append(np.median(dv))
        if segments == 96:
            assert du.max() < 2e-3                                      # measured 1.4e-3
            assert dv.max() < 4e-3                                      # measured 3.6e-3
    assert errors[1] < 0.3 * errors[0]                                  # second order: measured 0.25


def test_degenerate_input_stays_finite():
    m = primitives.plane(1.0, 2)                                        # 9 vertices, 8 faces, flat
    v = np.concatenate([m.vertices, m.vertices[[4, 4]], [[5.0, 5.0, 0.0]], m.vertices[[0, 1, 3]]])
    uv = np.concatenate([m.uvs, m.uvs[[4, 4]], [[0.2, 0.2]], np.full((3, 2), 0.3)])
    # 9, 10: duplicates of the centre vertex 4; 11: isolated; 12-14: a good triangle, zero UV area
    faces = np.concatenate([m.faces, [[9, 10, 4],      # three coincident points
                                      [0, 1, 2],       # collinear: zero area (and zero UV area)
                                      [0, 4, 4],       # repeated index
                                      [12, 13, 14]]])
    n = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    f = estimate_frame(v, faces, n, uv)
    _assert_valid(f, n)
    assert not f.k1.any() and not f.k2.any()
    assert not f.dpdu[9:].any() and not f.dpdv[9:].any()              # no usable face
    assert np.abs(f.dpdu[:9] - [1.0, 0.0, 0.0]).max() < 1e-14           # the plane's own, unchanged
    assert np.abs(f.dpdv[:9] - [0.0, 1.0, 0.0]).max() < 1e-14


def test_rigid_motions_and_scale():
    m = primitives.torus(1.0, 0.35, 48, 24)
    f = _estimate(m)
    r, t = rotation_xyz((30.0, -70.0, 115.0)), np.array([3.0, -5.0, 7.0])
    g = estimate_frame(m.vertices @ r.T + t, m.faces, m.normals @ r.T, m.uvs)
    assert np.abs(g.k1 - f.k1).max() < 1e-12 and np.abs(g.k2 - f.k2).max() < 1e-12   # measured 1.9e-14
    for name in ("d1", "dpdu", "dpdv"):                                              # measured 3.2e-14
        assert np.abs(getattr(g, name) - getattr(f, name) @ r.T).max() < 1e-12, name
    s = 3.7
    g = estimate_frame(m.vertices * s, m.faces, m.normals, m.uvs)
    assert np.abs(g.k1 * s - f.k1).max() < 1e-12 and np.abs(g.k2 * s - f.k2).max() < 1e-12  # measured 4.4e-15
    assert np.abs(g.d1 - f.d1).max() < 1e-12 and np.abs(g.dpdu - s * f.dpdu).max() < 1e-12


def test_sign_follows_the_normals_not_the_winding():
    m = primitives.torus(1.0, 0.35, 48, 24)
    f = _estimate(m)
    inward = _estimate(m, -m.normals)                   # k -> -k: the larger becomes minus the smaller
    assert np.abs(inward.k1 + f.k2).max() < 1e-12 and np.abs(inward.k2 + f.k1).max() < 1e-12
    assert np.abs(_dot(inward.d1, f.d1)).max() < 1e-12  # so d1 turns to the old d2
    clockwise = estimate_frame(m.vertices, m.faces[:, ::-1], m.normals, m.uvs)
    assert np.abs(clockwise.k1 - f.k1).max() < 1e-12 and np.abs(clockwise.k2 - f.k2).max() < 1e-12


def test_mesh_file_with_uvs_gets_an_estimated_frame(tmp_path):
    """A torus exported to OBJ (UVs, no frame) bakes a VDM over the curvature range that the analytic frame of
    the same primitive gives (within 2%)."""
    import json

    from click.testing import CliRunner

    from vdmbake.cli import main as bake_main

    m = primitives.torus(1.0, 0.35, 96, 48)
    trimesh.Trimesh(m.vertices, m.faces, process=False,
                    visual=trimesh.visual.TextureVisuals(uv=m.uvs)).export(tmp_path / "torus.obj")
    meso = 'mesostructure = { height = "bumps", size = 8, depth = 0.05, tiling = [16, 4], phi = 4, theta = 2, curvatures = 2 }'
    runner = CliRunner()
    ranges = {}
    for source in ('mesh = "torus.obj"', 'primitive = "torus"\nparams = { segments = 96, rings = 48 }'):
        (tmp_path / "s.toml").write_text(f'[[objects]]\nname = "t"\n{source}\n{meso}\ntechniques = {{ vdm = {{ k = [1] }} }}\n')
        r = runner.invoke(bake_main, [str(tmp_path / "s.toml"), "-o", str(tmp_path / "b.bundle"), "--force"])
        assert r.exit_code == 0, r.output
        c = json.loads((tmp_path / "b.bundle" / "manifest.json").read_text())["objects"]["t"]["techniques"]["vdm"]["curvatures"]
        ranges[source[:4]] = (c[0], c[-1])
    assert np.allclose(ranges["mesh"], ranges["prim"], rtol=0.02, atol=0.01)
