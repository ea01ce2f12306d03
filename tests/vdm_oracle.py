"""Test oracles for the VDM bake, independent of the kernels they check (vdmbake/kernels/vdm.py)."""
from __future__ import annotations

import numpy as np

from vdmbake.kernels import vdm
from vdmbake.common.embree import RayScene


def bent(s, h, c):
    """A point at arc length s along the surface and depth h below it, after the surface is bent to
    curvature c about the origin: on the circle of radius R = 1 / c about (0, -R) the surface point is
    at angle s / R, and depth h moves it toward the centre. c = 0: the plane itself."""
    s, h = np.asarray(s, float), np.asarray(h, float)
    if c == 0:
        return s, -h
    R = 1.0 / c
    return (R - h) * np.sin(s / R), (R - h) * np.cos(s / R) - R


def vdm_exact(heights: np.ndarray, depth: float, sampling: vdm.Sampling, c: float) -> np.ndarray:
    """The curved VDM by ray casting the truly bent mesostructure (the oracle for vdm.vdm_curved).

    For each azimuth the patch is bent into a cylinder of curvature c along that azimuth, about
    the tile centre; the cylinder's rotational symmetry makes the geometry seen from every entry
    point the same as bending about that point. l is read from the hit's unbent coordinate.
    Valid while |c| * (0.5 + reach) < pi / 2 (the bent patch must not wrap onto itself)."""
    n = sampling.size
    pad = vdm.padding_texels(depth, sampling)
    v, f = vdm.mesostructure_mesh(heights, depth, pad)
    flat_z = v[:, 2]
    c_tex = (np.arange(n) + 0.5) / n
    Y, X = np.meshgrid(c_tex, c_tex, indexing="ij")
    out = np.empty((n, n, sampling.n_phi, sampling.n_theta), np.float32)
    for pi_, phi in enumerate(sampling.phis):
        cp, sp = np.cos(phi), np.sin(phi)
        u = (v[:, 0] - 0.5) * cp + (v[:, 1] - 0.5) * sp          # along the azimuth, from the centre
        w = -(v[:, 0] - 0.5) * sp + (v[:, 1] - 0.5) * cp
        bx, by = bent(u, -flat_z, c)
        scene = RayScene(np.stack([bx, w, by], 1), f)
        up = ((X - 0.5) * cp + (Y - 0.5) * sp).ravel()           # entry points on the bent surface
        wp = (-(X - 0.5) * sp + (Y - 0.5) * cp).ravel()
        px, py = bent(up, np.zeros_like(up), c)
        a = up * c                                               # the surface normal turned by u c
        normal = np.stack([np.sin(a), np.zeros_like(a), np.cos(a)], 1)
        tangent = np.stack([np.cos(a), np.zeros_like(a), -np.sin(a)], 1)
        for ti, th in enumerate(sampling.thetas):
            d = -(np.sin(th) * tangent + np.cos(th) * normal)    # -V in the local frame of each entry point
            o = np.stack([px, wp, py], 1) + normal * 1e-4 * depth
            hits = scene.intersect(o, d)
            hit = hits.prim >= 0
            tri = f[hits.prim[hit]]
            wts = np.stack([1 - hits.u[hit] - hits.v[hit], hits.u[hit], hits.v[hit]], 1)
            l = np.full(len(o), -1.0)
            l[hit] = np.abs((wts * u[tri]).sum(1) - up[hit])
            res = np.where(hit, l / np.sin(th), -1.0)
            out[:, :, pi_, ti] = res.reshape(n, n)
    return out
