"""The enhanced-billboard bake (Vichitvejpaisal 2005, chapter 3): the greedy and axis builders,
the maps reprojected onto known surfaces, and the robustness cases of sec. 3.4 and 4.3."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.kernels import billboards as bb
from vdmbake.assets import primitives
from vdmbake.errors import InputError
from vdmbake.common.mesh import TriMesh, vertex_normals

R = 64


def mesh_of(vertices, faces) -> TriMesh:
    v, f = np.asarray(vertices, float), np.asarray(faces, np.int64)
    return TriMesh(v, f, vertex_normals(v, f))


def degenerate_count(mesh: TriMesh) -> int:
    """Faces with no usable area (the sphere's poles: collapsed up to float rounding)."""
    tri = mesh.vertices[mesh.faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    return int((area <= 1e-12 * (2 * mesh.bounding_sphere()[1]) ** 2).sum())


def points(b: bb.Billboard) -> np.ndarray:
    """(R, R, 3) world position of every texel: the box corner + texel centre in u, v + depth along w."""
    g = (np.arange(b.alpha.shape[0]) + 0.5) / b.alpha.shape[0]
    row, col = np.meshgrid(g, g, indexing="ij")
    uvw = np.stack([col * b.size[0], row * b.size[1], b.depth * b.size[2]], -1)
    return b.origin + uvw @ b.axes


def captured(result: bb.Result) -> np.ndarray:
    return np.concatenate(list(result.faces) + [np.zeros(0, np.int64)])


def check(result: bb.Result, mesh: TriMesh, settings: bb.Settings):
    """What holds for every bake: shapes, dtypes, finite values, frames, disjoint captures that face
    the viewer, and every face either captured or counted once in leftover."""
    res = settings.resolution
    tri = mesh.vertices[mesh.faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    assert len(result.faces) == len(result.billboards)
    for b, faces in zip(result.billboards, result.faces):
        assert np.isfinite(b.origin).all() and b.origin.shape == (3,)
        assert np.allclose(b.axes @ b.axes.T, np.eye(3), atol=1e-12)
        assert np.allclose(np.cross(b.axes[0], b.axes[1]), b.axes[2], atol=1e-12)
        assert np.isfinite(b.size).all() and (b.size > 0).all()
        assert len(faces) and len(np.unique(faces)) == len(faces)
        assert (fn[faces] @ -b.axes[2] > settings.min_cos).all()
        assert b.alpha.dtype == b.depth.dtype == b.normal.dtype == np.float32
        assert b.alpha.shape == b.depth.shape == (res, res) and b.normal.shape == (res, res, 3)
        for a in (b.alpha, b.depth, b.normal):
            assert np.isfinite(a).all()
        hit = b.alpha == 1
        assert np.isin(b.alpha, (0, 1)).all() and hit.any()
        assert (b.depth >= 0).all() and (b.depth <= 1).all() and (b.depth[~hit] == 1).all()
        assert np.allclose(np.linalg.norm(b.normal[hit], axis=1), 1, atol=1e-5) and not b.normal[~hit].any()
        assert (b.normal[hit] @ b.axes[2] <= 1e-6).all()  # shading normals face the viewer, -w
    got = captured(result)
    assert len(np.unique(got)) == len(got)
    assert set(result.leftover) == {"too_small", "perpendicular", "hidden", "over_budget"}
    assert all(type(n) is int and n >= 0 for n in result.leftover.values())
    assert len(got) + sum(result.leftover.values()) == len(mesh.faces)
    assert result.rays >= len(result.billboards) * res * res


def run(mesh, **kw) -> bb.Result:
    settings = bb.Settings(resolution=R, **kw)
    result = bb.bake(mesh, settings)
    check(result, mesh, settings)
    return result


def test_candidate_directions():
    d = bb.candidate_directions(36, 18)
    assert d.shape == (648, 3) and np.allclose(np.linalg.norm(d, axis=1), 1)
    assert len(np.unique(np.round(d, 9), axis=0)) == 648          # no repeated poles
    assert np.abs(d[:, 2]).max() == pytest.approx(np.cos(np.pi / 36))  # elevations at bin centres
    assert np.allclose(d.mean(0), 0, atol=1e-12)                 # evenly around the sphere


@pytest.mark.parametrize("w", [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0.6, -0.8, 0], [0.2, 0.3, -0.932]])
def test_view_frame_is_right_handed_orthonormal(w):
    w = np.asarray(w, float) / np.linalg.norm(w)
    f = bb.view_frame(w)
    assert np.allclose(f @ f.T, np.eye(3)) and np.allclose(np.cross(f[0], f[1]), f[2]) and np.array_equal(f[2], w)


def test_single_triangle():
    mesh = mesh_of([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    r = run(mesh)
    assert len(r.billboards) == 1 and r.faces[0].tolist() == [0]
    assert r.leftover == {"too_small": 0, "perpendicular": 0, "hidden": 0, "over_budget": 0}
    b = r.billboards[0]
    hit = b.alpha == 1
    assert 0.4 < hit.mean() < 0.6                                  # a triangle fills half its box
    assert np.abs(points(b)[hit][:, 2]).max() < 1e-5               # reprojected onto z = 0
    assert np.allclose(b.normal[hit], [0, 0, 1], atol=1e-6)


def test_flat_coplanar_mesh():
    mesh = primitives.plane(2.0, 8)
    r = run(mesh)
    assert len(r.billboards) == 1 and len(r.faces[0]) == len(mesh.faces)
    b = r.billboards[0]
    assert np.abs(points(b)[b.alpha == 1][:, 2]).max() < 1e-5
    # Axis mode sees the plane head-on from -Z only (edge-on from +-X, +-Y, from behind at +Z):
    # a flat box, given a small depth, with the plane in its middle and covering every texel.
    a = run(mesh, mode="axis")
    assert a.candidates == 6 and len(a.billboards) == 1
    b = a.billboards[0]
    assert np.array_equal(b.axes[2], [0, 0, -1]) and 0 < b.size[2] < 1e-3
    assert (b.alpha == 1).all() and np.allclose(b.depth, 0.5, atol=1e-3)
    assert np.allclose(b.normal, [0, 0, 1], atol=1e-6)


def test_polygon_edge_on_from_every_axis_is_perpendicular():
    """Normal (1,1,1)/sqrt(3): |n . axis| = 0.577 for all six axis views, below min_cos = 0.6."""
    mesh = mesh_of([[1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 1, 2]])
    a = run(mesh, mode="axis", min_cos=0.6)
    assert a.billboards == [] and a.leftover["perpendicular"] == 1 and a.candidates == 6
    g = run(mesh, min_cos=0.6)  # some of the 648 greedy candidates look at it nearly head-on
    assert len(g.billboards) == 1 and g.leftover["perpendicular"] == 0


def test_translated_far_from_origin_matches_up_to_the_translation():
    mesh = primitives.torus(1.0, 0.35, 24, 12)
    shift = np.array([1e5, -2e5, 1e5])
    near = run(mesh)
    far = run(TriMesh(mesh.vertices + shift, mesh.faces, mesh.normals))
    assert len(near.billboards) == len(far.billboards) and near.leftover == far.leftover
    assert all(np.array_equal(a, b) for a, b in zip(near.faces, far.faces))
    for a, b in zip(near.billboards, far.billboards):
        assert np.array_equal(a.axes, b.axes)
        assert np.abs(a.origin + shift - b.origin).max() < 1e-9 and np.abs(a.size - b.size).max() < 1e-9
        assert np.array_equal(a.alpha, b.alpha)
        assert np.abs(a.depth - b.depth).max() < 1e-6 and np.abs(a.normal - b.normal).max() < 1e-6


def test_intersecting_triangles():
    """Sec. 4.3: intersecting polygons must not hide each other. A big triangle A in z = 0 and a
    small one B on z = 0.2 x passing through it: both are captured, every texel lies on A or B,
    and where one billboard holds both, its depth map keeps the front-most: B's upper half over A,
    never B's lower half through A."""
    mesh = mesh_of([[-3, -3, 0], [3, -3, 0], [0, 3, 0], [-0.5, -0.5, -0.1], [0.5, -0.5, 0.1], [0, 0.5, 0]],
                   [[0, 1, 2], [3, 4, 5]])
    r = run(mesh)
    assert sorted(captured(r).tolist()) == [0, 1] and sum(r.leftover.values()) == 0
    for b, faces in zip(r.billboards, r.faces):
        p = points(b)[b.alpha == 1]
        assert np.minimum(np.abs(p[:, 2]), np.abs(p[:, 2] - 0.2 * p[:, 0])).max() < 1e-5
        if len(faces) == 2:
            assert p[:, 2].min() > -1e-5 and p[:, 2].max() > 0.05


def test_sub_pixel_and_degenerate_triangles_are_counted():
    plane = primitives.plane(1.0, 4)
    tiny = 1e-4 * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    visible = [tiny + [x, y, 0.1] for x, y in [(0.45, 0.45), (-0.45, 0.45), (-0.45, -0.45)]]
    hidden = [tiny + [x, 0, -0.1] for x in (0.0, 0.05)]                  # under the plane, facing it
    flat = [np.array([[0, 0, 0.2], [0.1, 0, 0.2], [0.2, 0, 0.2]]), np.full((3, 3), 0.3)]  # zero area
    extra = np.concatenate(visible + hidden + flat)
    n0 = len(plane.vertices)
    mesh = mesh_of(np.concatenate([plane.vertices, extra]),
                   np.concatenate([plane.faces, n0 + np.arange(len(extra)).reshape(-1, 3)]))
    r = run(mesh)
    f0 = len(plane.faces)
    assert set(range(f0 + 3)) <= set(captured(r).tolist())   # the plane and the tiny visible ones
    assert r.leftover == {"too_small": 4, "perpendicular": 0, "hidden": 0, "over_budget": 0}


def test_open_mesh_with_holes():
    sphere = primitives.sphere(1.0, 32, 16)
    keep = np.arange(len(sphere.faces)) % 7 != 3
    mesh = TriMesh(sphere.vertices, sphere.faces[keep], sphere.normals)
    r = run(mesh)
    # Outer faces all captured; through the holes only back faces show, never projected.
    assert len(captured(r)) == len(mesh.faces) - degenerate_count(mesh)
    assert r.leftover["too_small"] == degenerate_count(mesh) and r.leftover["hidden"] == 0
    for b in r.billboards:
        assert np.abs(np.linalg.norm(points(b)[b.alpha == 1], axis=1) - 1).max() < 0.01


def test_empty_mesh_and_bad_settings_are_input_errors():
    empty = TriMesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3)))
    with pytest.raises(InputError, match="empty"):
        bb.bake(empty)
    tri = mesh_of([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    for bad in ({"mode": "spiral"}, {"resolution": 0}, {"min_cos": 1.0}, {"max_depth": 0.0}):
        with pytest.raises(InputError):
            bb.bake(tri, bb.Settings(**bad))


def test_greedy_against_axis_baseline():
    """Sec. 4.2: the greedy choice needs fewer billboards than the axis projection on the sphere, both capturing
    every non-degenerate face; on the torus the axis views leave the inner ring's faces hidden, and the greedy
    views capture every face."""
    sphere = primitives.sphere(1.0, 48, 24)
    g, a = run(sphere), run(sphere, mode="axis")
    whole = len(sphere.faces) - degenerate_count(sphere)   # the poles' collapsed triangles
    assert len(captured(g)) == len(captured(a)) == whole
    assert g.leftover["too_small"] == a.leftover["too_small"] == degenerate_count(sphere)
    assert len(g.billboards) < len(a.billboards) == 6
    torus = primitives.torus(1.0, 0.35, 48, 24)
    g, a = run(torus), run(torus, mode="axis")
    assert len(captured(g)) == len(torus.faces) > len(captured(a))
    assert a.leftover["hidden"] == len(torus.faces) - len(captured(a)) > 0


def test_maps_reproject_onto_the_sphere():
    mesh = primitives.sphere(1.0, 64, 32)
    r = run(mesh)
    sag = 1 - np.cos(np.hypot(np.pi / 64, np.pi / 64))  # chord sag across a cell's diagonal
    for b in r.billboards:
        p = points(b)[b.alpha == 1]
        radius = np.linalg.norm(p, axis=1)
        assert np.abs(radius - 1).max() < sag
        assert (np.sum(b.normal[b.alpha == 1] * p / radius[:, None], axis=1) > 0.99).all()


def test_depth_limit_splits_layers():
    """e_depth (sec. 3.2 step 7): two squares facing +Z, one unit apart in depth, side by side.
    Within the limit they share one billboard; beyond it the far one gets its own."""
    a, b = primitives.plane(1.0, 2), primitives.plane(1.0, 2)
    mesh = TriMesh.concatenate([a, TriMesh(b.vertices + [2.0, 0, -1.0], b.faces, b.normals)])
    diameter = 2 * mesh.bounding_sphere()[1]
    one = run(mesh, mode="axis", max_depth=1.1 / diameter)
    assert len(one.billboards) == 1 and one.billboards[0].size[2] == pytest.approx(1.0, abs=1e-3)
    two = run(mesh, mode="axis", max_depth=0.9 / diameter)
    assert [sorted(f.tolist()) for f in two.faces] == [list(range(8)), list(range(8, 16))]
    assert all(np.array_equal(x.axes[2], [0, 0, -1]) and x.size[2] < 1e-3 for x in two.billboards)


def test_max_billboards_leaves_the_rest_over_budget():
    mesh = primitives.torus(1.0, 0.35, 24, 12)
    r = run(mesh, max_billboards=2)
    assert len(r.billboards) == 2 and r.leftover["over_budget"] == len(mesh.faces) - len(captured(r)) > 0


def test_deterministic_and_logged():
    mesh = primitives.vase(1.0, 2.0, 24, 12)
    lines = []
    first = bb.bake(mesh, bb.Settings(resolution=R), log=lines.append)
    second = bb.bake(mesh, bb.Settings(resolution=R))
    assert first.leftover == second.leftover and first.rays == second.rays
    assert len(first.billboards) == len(second.billboards)
    assert all(np.array_equal(a, b) for a, b in zip(first.faces, second.faces))
    for a, b in zip(first.billboards, second.billboards):
        for name in ("origin", "axes", "size", "alpha", "depth", "normal"):
            assert np.array_equal(getattr(a, name), getattr(b, name))
    assert sum(line.startswith("billboard ") for line in lines) == len(first.billboards)


def test_a_mesh_no_billboard_can_capture_is_refused_at_bake(tmp_path):
    """Collinear triangles have no area, so no projection captures them: the bake says so (exit 2)
    instead of writing a bundle the renderer cannot draw. Since issue 14 a mesh without area is refused
    for every technique when it is loaded (vdmbake.assets.meshes.validate), before the billboards' own check."""
    from click.testing import CliRunner

    from vdmbake.cli import main as bake_main

    (tmp_path / "line.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n")
    (tmp_path / "s.toml").write_text('[[objects]]\nname = "line"\nmesh = "line.obj"\n'
                                     'techniques = { billboards = { variants = ["axis-improved"], resolution = 8 } }\n')
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s.toml"), "-o", str(tmp_path / "b.bundle")])
    assert r.exit_code == 2 and "no area" in r.stderr, r.output
    assert not (tmp_path / "b.bundle").exists()
