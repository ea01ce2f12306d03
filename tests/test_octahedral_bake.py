"""Octahedral impostors, the bake (vdmbake.kernels.octahedral): the octahedral maps, the lattice triangle and
weights of every direction, the views' frames, and captures against an analytic sphere."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.kernels import octahedral as oc
from vdmbake.assets import primitives
from vdmbake.errors import InputError
from vdmbake.common.mesh import TriMesh


def random_directions(n=20000, seed=0, upper=False):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if upper:
        d[:, 2] = np.abs(d[:, 2])
    # The stiff ones: poles, equator, axes, signed zeros, the folds' diagonals.
    special = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [1, 1, 0], [1, -1, 0],
               [-1, 1, 0], [-1, -1, 0], [0.0, -0.0, 1], [-0.0, 0.0, -1], [1, 1, 1], [1, 1, -1], [-1, -1, -1],
               [1e-300, 0, 1], [1, 1e-17, -1e-17]]
    special = np.array(special, float)
    if upper:
        special = special[special[:, 2] >= 0]
    special /= np.linalg.norm(special, axis=1, keepdims=True)
    return np.concatenate([d, special])


@pytest.mark.parametrize("hemi", [False, True])
def test_encode_decode_round_trip(hemi):
    d = random_directions(upper=hemi)
    g = oc.encode(d, hemi)
    assert np.abs(g).max() <= 1.0
    assert np.abs(oc.decode(g, hemi) - d).max() < 1e-14
    # And the other way round, over the whole square (the full map's border points are each other's mirror).
    u = np.linspace(-1, 1, 101)
    grid = np.stack(np.meshgrid(u, u), -1).reshape(-1, 2)
    back = oc.encode(oc.decode(grid, hemi), hemi)
    inside = np.abs(grid).max(1) < 1
    assert np.abs(back - grid)[inside].max() < 1e-14


def test_hemi_map_clamps_below_the_horizon():
    d = np.array([[0.6, -0.8, -0.5], [0.0, 1.0, -1e-9]])
    g = oc.encode(d, hemi=True)
    assert np.allclose(np.abs(g).max(1), 1.0)                 # on the square's border: the horizon
    assert np.allclose(oc.decode(g, True)[:, 2], 0.0, atol=1e-12)


@pytest.mark.parametrize("hemi", [False, True])
@pytest.mark.parametrize("views", [2, 8, 9, 13, 16, 17])
def test_nearest_views_triangle_and_weights(views, hemi):
    """Three lattice views per direction: barycentric weights >= 0 summing to 1 that reproduce the
    direction's map point, the views within one lattice cell of it, and for the full map with odd N
    (creases on the lattice) the angularly nearest view always among them."""
    d = random_directions(upper=hemi)
    idx, w = oc.nearest_views(d, views, hemi)
    assert idx.shape == (len(d), 3, 2) and w.shape == (len(d), 3)
    assert idx.min() >= 0 and idx.max() <= views - 1
    assert w.min() >= -1e-12 and np.abs(w.sum(1) - 1).max() < 1e-12
    lat = oc.lattice(views)
    g = oc.encode(d, hemi)
    assert np.abs((w[..., None] * lat[idx]).sum(1) - g).max() < 1e-12
    # The three are corners of one cell: their indices differ by at most 1.
    assert (np.ptp(idx, axis=1) <= 1).all()
    e, _, _ = oc.view_frames(views, hemi)
    vd = e[idx[..., 1], idx[..., 0]]
    cos = np.einsum("nkc,nc->nk", vd, d)
    nearest = (d @ e.reshape(-1, 3).T).max(1)
    if views % 2 == 1 and not hemi:
        assert (np.abs(cos.max(1) - nearest) < 1e-12).all()
    else:   # measured: the nearest view is among the three for >= 99.6% of directions
        assert np.mean(np.abs(cos.max(1) - nearest) < 1e-12) > 0.99


@pytest.mark.parametrize("hemi", [False, True])
def test_views_own_direction_has_weight_one(hemi):
    views = 9
    e, _, _ = oc.view_frames(views, hemi)
    idx, w = oc.nearest_views(e.reshape(-1, 3), views, hemi)
    top = np.argmax(w, 1)
    assert np.allclose(w.max(1), 1.0, atol=1e-12)
    picked = idx[np.arange(len(top)), top]
    # The view picked has the same direction (the full map's border views repeat directions).
    assert np.abs(e[picked[:, 1], picked[:, 0]] - e.reshape(-1, 3)).max() < 1e-12


def test_weights_continuous_across_cells_and_folds():
    """Directions a hair apart (across lattice lines, the equator fold, the border): the blended
    view direction sum w_k e_k moves by a hair too."""
    views = 13
    e, _, _ = oc.view_frames(views)
    d = random_directions(5000, seed=3)
    step = np.random.default_rng(4).normal(size=d.shape) * 1e-7
    d2 = d + step
    d2 /= np.linalg.norm(d2, axis=1, keepdims=True)

    def blend(x):
        idx, w = oc.nearest_views(x, views)
        return (w[..., None] * e[idx[..., 1], idx[..., 0]]).sum(1)

    assert np.abs(blend(d) - blend(d2)).max() < 1e-5


@pytest.mark.parametrize("hemi", [False, True])
@pytest.mark.parametrize("views", [2, 9, 12])
def test_view_frames_orthonormal(views, hemi):
    basis = oc.map_basis([0.3, -0.2, 0.9])
    e, u, v = oc.view_frames(views, hemi, basis)
    for a in (e, u, v):
        assert np.abs(np.linalg.norm(a, axis=-1) - 1).max() < 1e-14
    assert np.abs(np.cross(u, v) - e).max() < 1e-14
    g = oc.lattice(views)
    assert np.abs(e - oc.decode(np.stack(np.meshgrid(g, g), -1), hemi) @ basis).max() < 1e-14
    assert np.abs(basis @ basis.T - np.eye(3)).max() < 1e-15
    assert np.allclose(oc.map_basis([0, 0, 1]), np.eye(3))


@pytest.fixture(scope="module")
def sphere_atlas():
    """A tessellated unit sphere far from the origin, 9 x 9 views of 48^2 texels."""
    m = primitives.sphere(1.0, 128, 64)
    m = TriMesh(m.vertices + np.array([2.0e4, -1.0e4, 3.0e3]), m.faces, m.normals)
    return oc.bake(m, oc.Settings(9, 48))


def test_capture_of_a_sphere(sphere_atlas):
    """Every view of a sphere is the same disk: coverage, depth (cap - sqrt(r^2 - x^2 - y^2)) / (2 cap)
    and the normal (x, y, sqrt(r^2 - x^2 - y^2)) / r in the view's frame, against the analytic sphere."""
    a = sphere_atlas
    n, res = a.settings.views, a.settings.resolution
    assert a.coverage.shape == (n * res, n * res)
    assert abs(a.radius - 1.0) < 1e-9 and np.allclose(a.centre, [2.0e4, -1.0e4, 3.0e3])
    assert abs(a.capture - oc.capture_half(a.radius, res)) < 1e-12
    g = (np.arange(res) + 0.5) / res * 2 - 1
    x, y = np.meshgrid(g * a.capture, g * a.capture)
    rho2 = x * x + y * y
    z = np.sqrt(np.maximum(1.0 - rho2, 0.0))
    tiles = lambda arr: arr.reshape(n, res, n, res, *arr.shape[2:]).swapaxes(1, 2)   # [j, i, b, a]
    cov, depth = tiles(a.coverage), tiles(a.depth)
    normal = oc.decode(tiles(a.normal))
    # Coverage: the disk, except texel centres within the tessellation's sagitta of the rim
    # (64 rings: 1 - cos(pi / 64) = 1.2e-3 of the radius).
    rim = np.abs(np.sqrt(rho2) - 1.0) < 1.5e-3
    assert ((cov > 0.5) == (rho2 < 1.0))[:, :, ~rim].all()
    inner = rho2 < 0.9 ** 2
    # Depth: measured max 5.8e-4 x 2 cap (the facets' sagitta, seen obliquely); normal: 0.068 degrees.
    err = np.abs(depth - (a.capture - z) / (2 * a.capture))[:, :, inner]
    assert err.max() < 8e-4
    cos = (normal * np.stack([x, y, z], -1)).sum(-1)[:, :, inner]
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 0.1
    assert (depth[cov < 0.5] == 1.0).all() and (np.abs(normal[cov < 0.5] - [0, 0, 1]) < 1e-12).all()


def test_tiles_keep_empty_rings(sphere_atlas):
    """EMPTY rings of texels around every tile stay empty, so filtering never crosses views."""
    a = sphere_atlas
    n, res, k = a.settings.views, a.settings.resolution, oc.EMPTY
    t = a.coverage.reshape(n, res, n, res)
    assert t[:, :k].max() == 0 and t[:, -k:].max() == 0 and t[:, :, :, :k].max() == 0 and t[:, :, :, -k:].max() == 0


def test_bake_is_deterministic_and_counts_rays():
    m = primitives.torus(1.0, 0.35, 32, 16)
    a, b = (oc.bake(m, oc.Settings(5, 16, hemi=True)) for _ in range(2))
    for f in ("normal", "depth", "coverage"):
        assert np.array_equal(getattr(a, f), getattr(b, f))
    assert a.rays == 1 + 25 * 16 * 16
    assert a.coverage.sum() > 0


def test_open_surface_seen_from_behind_faces_the_viewer():
    """A single triangle: every view that covers it stores a normal facing that view (as the reference
    flips a back face), so the code's z is >= 0 where covered."""
    m = TriMesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]), np.array([[0.0, 0, 1]] * 3))
    a = oc.bake(m, oc.Settings(5, 32))
    covered = a.coverage > 0.5
    assert covered.sum() > 0
    assert oc.decode(a.normal[covered])[:, 2].min() >= 0.0


@pytest.mark.parametrize("settings, words", [
    (oc.Settings(1, 64), "views = 1"),
    (oc.Settings(9, 8), "resolution = 8"),
    (oc.Settings(64, 512), "at most 16384"),
])
def test_bad_settings_refused(settings, words):
    with pytest.raises(InputError, match=words):
        oc.bake(primitives.sphere(1.0, 8, 4), settings)


def test_stored_atlas_extrapolates_around_silhouettes():
    """to_part, what the bundle stores: covered texels as baked; the empty texels within two rings of
    covered ones extrapolated from them (on a sphere's rim the depth keeps falling towards the centre
    plane: below 1), farther ones as baked (depth 1, code 0); all within range; nothing enters the
    EMPTY rings' outer ring of any tile, so no view reaches into another."""
    from vdmbake.kernels.billboard_maps import PAD

    n, res = 5, 32
    a = oc.bake(primitives.sphere(1.0, 48, 24), oc.Settings(n, res))
    p = oc.to_part(a)
    cov = a.coverage > 0.5
    assert np.array_equal(p.coverage, a.coverage) and (p.views, p.resolution, p.hemi) == (n, res, False)
    assert np.array_equal(p.depth[cov], a.depth[cov]) and np.array_equal(p.normal[cov], a.normal[cov])
    near = np.zeros_like(cov)
    for di in range(-PAD, PAD + 1):
        for dj in range(-PAD, PAD + 1):
            near |= np.roll(np.roll(cov, di, 0), dj, 1)
    ring = near & ~cov
    assert ring.any() and (p.depth[ring] < 1.0).all()
    assert (p.depth[~near] == 1.0).all() and (p.normal[~near] == 0.0).all()
    assert p.depth.min() >= 0 and p.depth.max() <= 1 and np.abs(p.normal).max() <= 1
    edge = np.zeros((res, res), bool)
    edge[[0, -1], :] = edge[:, [0, -1]] = True
    assert not near[np.tile(edge, (n, n))].any()
