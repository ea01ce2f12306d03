"""The VDM bake (Wang et al. 2003): zero-curvature ray casting against analytic answers, the
Appendix curvature resampling against ray casting the truly bent geometry, MVM and SVD."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.kernels import vdm

from vdm_oracle import bent, vdm_exact

N = 32


def waves(n=N):
    x = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return 0.5 + 0.25 * np.sin(2 * x)[None, :] + 0.25 * np.cos(x)[:, None]


@pytest.mark.parametrize("h,depth", [(1.0, 0.1), (0.5, 0.1), (0.0, 0.1), (0.0, 0.5), (0.3, 0.02)])
def test_flat_floor_is_analytic(h, depth):
    """A constant height: every ray meets the floor at depth (1 - h) / cos(theta); no -1."""
    s = vdm.Sampling(N, n_phi=8)
    d, rays, _ = vdm.vdm_flat(np.full((N, N), h), depth, s)
    assert rays == N * N * 8 * 8
    assert np.abs(d - depth * (1 - h) / np.cos(s.thetas)).max() < 1e-6
    assert d.min() >= 0


def test_depth_zero_is_all_zero_without_rays():
    d, rays, _ = vdm.vdm_flat(waves(), 0.0, vdm.Sampling(N, n_phi=4))
    assert rays == 0 and not d.any()


def test_cliffs_stay_finite_and_hit():
    """Vertical walls (a 0 -> 1 step between neighbours) and a one-texel slot."""
    h = np.zeros((N, N))
    h[8:24, 8:24] = 1.0
    h[:, 4] = 0.0
    d, _, _ = vdm.vdm_flat(h, 0.2, vdm.Sampling(N, n_phi=16))
    assert np.isfinite(d).all() and d.min() >= 0
    assert (d[12, 12] == 0).all()  # on the plateau the surface is hit where the ray enters
    # From the floor next to a wall, looking across the wall (ray heading into it), d is cut short.
    s = vdm.Sampling(N, n_phi=16)
    floor_only = d[16, 6, :, -1]
    assert floor_only.min() < 0.2 / np.cos(s.thetas[-1]) * 0.5


def test_zero_curvature_resampling_is_the_identity():
    s = vdm.Sampling(N, n_phi=8)
    flat, _, _ = vdm.vdm_flat(waves(), 0.05, s)
    assert np.array_equal(vdm.vdm_curved(flat, s, 0.0)[0], flat)


@pytest.mark.parametrize("c", [-3.0, -0.5, -1e-3, 1e-3, 0.5, 2.0, 3.0])
def test_bend_is_the_circle_it_claims(c):
    """The Appendix's bending (vdm.bend, written with sinc for c -> 0) against the closed form on the
    circle of radius 1 / c (which loses digits as c -> 0, so tiny curvatures are checked against the
    plane below), for arc lengths up to a quarter turn and depths from 0 to 0.2."""
    s = np.linspace(-0.5, 0.5, 41)[:, None] * min(1.0, np.pi / 2 / abs(c))
    h = np.array([0.0, 0.01, 0.05, 0.2])[None, :]
    x, y = vdm.bend(s, h, c)
    xe, ye = bent(s, h, c)
    assert np.abs(x - xe).max() < 1e-12 and np.abs(y - ye).max() < 1e-12


def test_bend_is_continuous_at_zero_curvature():
    s, h = np.linspace(0.0, 0.5, 11), np.full(11, 0.05)
    x0, y0 = vdm.bend(s, h, 0.0)
    assert np.array_equal(x0, s) and np.array_equal(y0, -h)
    x, y = vdm.bend(s, h, 1e-12)
    assert np.abs(x - s).max() < 1e-12 and np.abs(y + h).max() < 1e-12


def _appendix_row(d, th, c):
    """The Appendix's resampling of one row written out directly (the oracle for the vectorised kernel):
    bend each hit, theta' = atan2(x, -y), drop hits not above every earlier angle, interpolate linearly."""
    pts, horizon = [], 0.0
    top = -np.inf
    for dk, tk in zip(d, th):
        if dk < 0:
            continue
        if dk == 0:
            a, e = tk, 0.0
        else:
            x, y = vdm.bend(np.array(dk * np.sin(tk)), np.array(dk * np.cos(tk)), c)
            a = float(np.arctan2(x, -y))
            e = dk * np.sin(tk) / np.sin(a)
        if a > top:
            pts.append((a, e))
            horizon = max(horizon, np.pi / 2 if dk == 0 else a)
        top = max(top, a)
    out = np.full(len(th), -1.0)
    if pts:
        a, e = np.array(pts).T
        out = np.interp(th, a, e)
        if c > 0:
            out[th > a[-1]] = -1.0
    return out, min(horizon, np.pi / 2)


def test_vectorised_resampling_against_the_appendix_row_by_row():
    """Random rows (misses, hits at the entry point, long grazing hits) at mild and at extreme curvatures
    (past a half turn: s c >= pi, or deeper than the centre: h c >= 1): the kernel matches the direct form."""
    rng = np.random.default_rng(7)
    s = vdm.Sampling(8, n_phi=4)
    d = rng.uniform(0.0, 0.6, (400, s.n_theta)).astype(np.float32)
    d[rng.random(d.shape) < 0.1] = -1.0
    d[rng.random(d.shape) < 0.05] = 0.0
    for c in (-2.0, 0.7, 3.0, 12.0, 40.0):
        got, horizon = vdm.vdm_curved_rows(d, s, c)
        for i in range(len(d)):
            want, want_h = _appendix_row(d[i].astype(np.float64), s.thetas, c)
            assert np.allclose(got[i], want, atol=2e-5, rtol=1e-5), (c, i, got[i], want)
            assert abs(horizon[i] - want_h) < 1e-6, (c, i)


def test_appendix_resampling_against_bent_ray_casting():
    """The Appendix approximation measured against the exact bent geometry (the figures reported)."""
    s = vdm.Sampling(N, n_phi=8)
    h = waves()
    flat, _, _ = vdm.vdm_flat(h, 0.05, s)
    exact0 = vdm_exact(h, 0.05, s, 0.0)
    assert np.abs(exact0 - flat).max() < 1e-3  # the oracle agrees with the flat bake at c = 0
    for c in (-1.0, 0.5, 1.0):
        exact = vdm_exact(h, 0.05, s, c)
        approx = vdm.vdm_curved(flat, s, c)[0]
        both = (exact >= 0) & (approx >= 0)
        err = np.abs(exact - approx)[both]
        assert err.mean() < 0.15 * exact[exact >= 0].mean()     # measured: 5-10 % of the mean d
        assert ((exact < 0) != (approx < 0)).mean() < 0.05       # measured: 0 (concave), 2.5-3 % (convex)
        if c < 0:
            assert (approx >= 0).all()  # a concave surface cannot be left


def test_convex_surfaces_have_silhouettes_at_grazing_angles():
    s = vdm.Sampling(N, n_phi=8)
    flat, _, _ = vdm.vdm_flat(waves(), 0.05, s)
    d = vdm.vdm_curved(flat, s, 3.0)[0]
    invalid_by_theta = (d < 0).mean(axis=(0, 1, 2))
    assert invalid_by_theta[0] == 0 and invalid_by_theta[-1] > 0.5
    assert np.all(np.diff(invalid_by_theta) >= -1e-9)  # more grazing, more rays leave the surface


def test_mvm_and_compression():
    s = vdm.Sampling(16, n_phi=8, curvatures=vdm.curvature_samples(-1.0, 2.0, 4))
    table, theta_mvm, _ = vdm.bake_tables(waves(16), 0.05, s)
    assert table.shape == (16, 16, 8, 8, 4) and theta_mvm.shape == (16, 16, 8, 4)
    # MVM for c <= 0: the upper edge of the bin of the largest theta with a valid displacement.
    valid = table >= 0
    last = np.where(valid, np.arange(8)[None, None, None, :, None], -1).max(3)
    assert np.allclose(theta_mvm[..., :2], np.where(last >= 0, (last + 1) * np.pi / 16, 0.0)[..., :2])
    assert np.allclose(theta_mvm[..., 0], np.pi / 2)  # c = -1: concave, every direction hits
    # For c > 0 the exact horizon, bracketed by the last valid and the first invalid sample.
    lo = np.where(last >= 0, s.thetas[np.maximum(last, 0)], 0.0)[..., 2:]
    hi = np.where(last < 7, s.thetas[np.minimum(last + 1, 7)], np.pi / 2)[..., 2:]
    assert np.all((theta_mvm[..., 2:] >= lo - 1e-6) & (theta_mvm[..., 2:] <= hi + 1e-6))
    assert (theta_mvm[..., 2:] > lo + 1e-3).mean() > 0.5      # and it is a finer estimate than the samples
    c8 = vdm.compress(table, theta_mvm, 8, report=(1, 2, 4))
    assert sorted(c8.errors) == [1, 2, 4, 8] and c8.W.shape[-1] == 8
    energies = [c8.errors[k].energy for k in (1, 2, 4, 8)]
    rms = [c8.errors[k].rms_vdm for k in (1, 2, 4, 8)]
    assert all(a <= b + 1e-12 for a, b in zip(energies, energies[1:])) and energies[-1] > 0.99
    assert all(a >= b - 1e-7 for a, b in zip(rms, rms[1:]))       # more eigenfunctions, less error
    # The truncated errors are those of a separate decomposition at that k.
    assert abs(vdm.compress(table, theta_mvm, 2).errors[2].rms_vdm - rms[1]) < 1e-6
    full = vdm.compress(table, theta_mvm, 10_000)   # k above the rank is capped, and reconstructs
    assert full.W.shape[-1] == full.rank <= 8 * 4 + 4
    e = full.errors[full.rank]
    assert e.rms_vdm < 1e-4 and e.rms_mvm < 1e-4


def test_curvature_samples():
    assert vdm.curvature_samples(0.0, 0.0, 16) == (0.0,)
    c = vdm.curvature_samples(-2.0, 3.0, 16)
    assert len(c) == 16 and c[0] == -2.0 and c[-1] == 3.0


@pytest.mark.slow
@pytest.mark.plots   # vdm.png is report.plot's
def test_bench_quick_smoke(tmp_path, monkeypatch, no_warm_up):
    """make bench's VDM script runs end to end (small tables, bricks on a torus at 96x96) and writes its report.
    Its torus coarser (64 x 16 segments) and its shadow map 512 texels: the same rows, tables and report at a
    third of the CPU time."""
    import json

    from click.testing import CliRunner

    import bench.vdm
    from helpers import edited

    name, primitive, _, tiling = bench.vdm.SURFACES[0]
    monkeypatch.setattr(bench.vdm, "SURFACES", [(name, primitive, "{ segments = 64, rings = 16 }", tiling)])
    edited(monkeypatch, bench.vdm, "SCENE", "warmup = 1\n", "warmup = 1\nshadow_map = 512\n")
    r = CliRunner().invoke(bench.vdm.main, ["-o", str(tmp_path), "--quick"])
    assert r.exit_code == 0, r.output
    report = json.loads((tmp_path / "vdm.json").read_text())
    labels = {row["label"] for row in report["rows"]}
    assert {"vdm@2", "vdm@8", "vdm@8r1", "vdm@8r4", "pom@16", "bump", "displaced@1", "mesh"} <= labels
    assert all(row["nonfinite"] == 0 for row in report["rows"])
    paper = report["paper_bake"]
    assert paper["rays"] == 32 * 32 * 8 * 8 and paper["compressed"]["all"]["rms_vdm"] < 1e-4
    assert paper["storage_chosen"] in paper["storage_k8"] and paper["storage_k8"]["float32"]["rms_vdm"] == 0
    inter = report["interleaved"]["torus-bricks"]
    assert {"vdm@8 original lookup", "vdm@8", "vdm@8r4", "pom@16"} <= set(inter["rows"])
    c = inter["costs"]["vdm@8r4"]["passes"]["frame"]     # test_vdm_render.py test_costs_per_fragment's rules
    views, lit = c["steps"] - 4 * c["searches"], 5 * c["searches"] - c["steps"]
    assert 0 < lit <= views <= c["fragments"] and c["fetches"] <= 18 * c["fragments"]
    assert (tmp_path / "vdm.md").read_text().count("\n") > 20 and (tmp_path / "vdm.png").is_file()
