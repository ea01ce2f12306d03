"""The Utah teapot (Newell 1975): its 32 bicubic Bezier patches (vdmbake/assets/data/teapot.txt) tessellated
with exact normals, UVs and the SurfaceFrame the mesostructure techniques need (pure numpy).

A patch is P(s, t) = sum_ij B_i(s) B_j(t) C_ij over its 4 x 4 control points C (row i along s, column j
along t), B the cubic Bernstein basis. Every patch of the classic data is oriented alike: the outward
normal is dP/dt x dP/ds (checked by tests: the body's normals point away from the axis, the enclosed
volume is positive). Normals, tangents and curvatures come from the patch derivatives, not from the
triangles:
* normal n = (P_t x P_s) / |P_t x P_s|. Where a patch edge collapses to a point (the lid knob's top and
  the bottom's centre: the row s = 0 of those patches is one control point), P_t vanishes along it;
  there P_t = s P_st + O(s^2), so the limit normal is P_st x P_s, which is what is used.
* principal curvatures (do Carmo, sec. 3-3) from the fundamental forms I = X^T X, II_ab = P_ab . n with
  X = [P_s, P_t]: the world-space shape tensor T = -X I^-1 II I^-1 X^T (k > 0 where the surface bends
  away from its normal, the SurfaceFrame convention); at a collapsed edge, where I is singular, it is
  taken at s = 1e-4 (its limit, to that order).
* texture tangents dP/du, dP/dv: the patch derivatives by the chain rule through the UV layout below.

Welding: the grid vertices of neighbouring patches coincide where the patches share a border (the
data's shared control points make the shared border curves bit-identical); they become one vertex
where their UVs agree too (a UV seam keeps its copies, as any UV-mapped mesh does), and every copy of a
point of one piece gets the mean of the patch normals and shape tensors there (the patches meet with
tangent continuity, so the means only smooth rounding). Triangles that collapse where a patch edge
does are dropped: at 8 segments that leaves 4032 triangles, the count of Wang2003 Fig. 9's
teapot (Wang et al. 2003). The teapot is not closed: the rim's inner lip and the lid's edge leave the
classic gap between lid and pot, and the handle's and the spout's ends are open where they enter the
body (tests/test_teapot.py measures the border).

UVs: four pieces (charts), each its patches laid side by side: the pot (bottom, lower body, upper
body, rim, one surface of revolution from the bottom's centre to the rim's inner lip) and the lid (lid
and knob, from its edge to the knob's top) with u = the fraction of the turn and v up the profile, as
the built-in surfaces of revolution have them (vdmbake.common.geometry.revolve); the handle and the spout
with u around the tube (its seam on the underside) and v along it. Within a chart each patch spans its
share of u evenly and of v in proportion to its length along v, so a tile has one size along the
profile; across charts one UV unit is the same world length (the pot's v: its profile's length; u: its
widest turn), so a tiled mesostructure has one scale on every piece. Every map is right-handed seen
from outside ((dP/du x dP/dv) . n > 0).
"""
from __future__ import annotations

from functools import lru_cache
from importlib.resources import files

import numpy as np

from ..bundle import budget
from ..common.geometry import grid_faces, onb
from ..common.mesh import SurfaceFrame, TriMesh, weld

DATA = files(__package__) / "data" / "teapot.txt"   # package data (pyproject.toml), found in any install
HEIGHT = 3.15   # of the classic data, bottom (z = 0) to the knob's top

# The classic grouping of the patches (0-based).
GROUPS = {"rim": range(0, 4), "body": range(4, 12), "handle": range(12, 16), "spout": range(16, 20),
          "lid": range(20, 28), "bottom": range(28, 32)}

# The UV layout: chart -> rows of patches along v (first row at v = 0), each row's patches along u
# (first at u = 0), with whether a patch's t and s run against u and v ((1 - t), (1 - s)).
# Pot and lid: the body, rim, knob and lid patches run clockwise seen from above and downward (or
# outward), the bottom's anticlockwise and outward from its centre.
CHARTS = {
    "pot": [((28, 29, 30, 31), False, False), ((11, 10, 9, 8), True, True), ((7, 6, 5, 4), True, True),
            ((3, 2, 1, 0), True, True)],
    "lid": [((27, 26, 25, 24), True, True), ((23, 22, 21, 20), True, True)],
    "handle": [((12, 13), False, False), ((14, 15), False, False)],
    "spout": [((17, 16), False, False), ((19, 18), False, False)],
}
REVOLVED = ("pot", "lid")   # charts of revolution: u spans the whole turn, 0 to 1

_COLLAPSED = 1e-9      # |P_t x P_s| below this (relative to |P_s| |P_st|) is a collapsed edge
_NUDGE = 1e-4          # where the shape tensor of a collapsed edge is taken instead


@lru_cache(maxsize=1)
def control_points() -> np.ndarray:
    """(32, 4, 4, 3) float64: the patches' control points, classic units (3.15 tall), +Z up."""
    lines = [line.strip() for line in DATA.read_text().splitlines() if line.strip() and not line.startswith("#")]
    n = int(lines[0])
    index = np.array([[int(x) for x in line.split(",")] for line in lines[1:1 + n]]) - 1
    m = int(lines[1 + n])
    points = np.array([[float(x) for x in line.split(",")] for line in lines[2 + n:2 + n + m]])
    assert index.shape == (32, 16) and points.shape == (306, 3) and len(lines) == 2 + n + m, DATA
    out = points[index].reshape(32, 4, 4, 3)
    out.setflags(write=False)
    return out


def bernstein(t: np.ndarray, derivative: int = 0) -> np.ndarray:
    """(N, 4): the cubic Bernstein polynomials (or their first or second derivative) at t (N,)."""
    t = np.asarray(t, np.float64)[:, None]
    s = 1.0 - t
    if derivative == 0:
        return np.concatenate([s ** 3, 3 * s * s * t, 3 * s * t * t, t ** 3], 1)
    if derivative == 1:
        return 3 * np.concatenate([-s * s, s * s - 2 * s * t, 2 * s * t - t * t, t * t], 1)
    return 6 * np.concatenate([s, t - 2 * s, s - 2 * t, t], 1)


def evaluate(ctrl: np.ndarray, s: np.ndarray, t: np.ndarray) -> dict[str, np.ndarray]:
    """A patch's position and first and second derivatives at the parameters (s, t) (N,) each:
    "P", "Ps", "Pt", "Pss", "Pst", "Ptt", (N, 3) each."""
    b = {d: bernstein(s, d) for d in range(3)}
    c = {d: bernstein(t, d) for d in range(3)}
    f = lambda i, j: np.einsum("ni,nj,ijk->nk", b[i], c[j], ctrl)  # noqa: E731
    return {"P": f(0, 0), "Ps": f(1, 0), "Pt": f(0, 1), "Pss": f(2, 0), "Pst": f(1, 1), "Ptt": f(0, 2)}


def _shape_tensor(d: dict) -> np.ndarray:
    """(N, 3, 3) T = -X I^-1 II I^-1 X^T, X = [P_s, P_t], n = P_t x P_s / |P_t x P_s|: T(x, x) is the
    normal curvature along a unit tangent x."""
    X = np.stack([d["Ps"], d["Pt"]], -1)
    n = np.cross(d["Pt"], d["Ps"])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    first = np.einsum("nki,nkj->nij", X, X)
    second = np.einsum("nk,nijk->nij", n, np.stack([np.stack([d["Pss"], d["Pst"]], 1),
                                                   np.stack([d["Pst"], d["Ptt"]], 1)], 1))
    inv = np.linalg.inv(first)
    return -np.einsum("nai,nij,njk,nbk->nab", X, inv @ second, inv, X)


def _lengths(ctrl: np.ndarray, along_s: bool) -> float:
    """The mean length of a patch's parameter lines along s (or t): 8-point Gauss-Legendre over 9 lines."""
    x, w = np.polynomial.legendre.leggauss(8)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    lines = np.linspace(0.0, 1.0, 9)
    s, t = (np.repeat(x, 9), np.tile(lines, 8)) if along_s else (np.tile(lines, 8), np.repeat(x, 9))
    d = evaluate(ctrl, s, t)["Ps" if along_s else "Pt"]
    return float((np.linalg.norm(d, axis=1).reshape(8, 9) * w[:, None]).sum(0).mean())


@lru_cache(maxsize=1)
def layout() -> dict[int, tuple]:
    """patch -> (chart, u0, du, v0, dv, t reversed, s reversed): the patch spans u0 .. u0 + du and
    v0 .. v0 + dv of its chart (scale-free: from the classic data's lengths)."""
    C = control_points()
    rows = {name: [(p, rt, rs, np.mean([_lengths(C[i], True) for i in p]), sum(_lengths(C[i], False) for i in p))
                   for p, rt, rs in spec] for name, spec in CHARTS.items()}
    unit_v = sum(r[3] for r in rows["pot"])                 # the pot's profile, bottom centre to lip
    unit_u = max(r[4] for r in rows["pot"])                 # the pot's widest turn
    out = {}
    for name, chart in rows.items():
        turn = 1.0 if name in REVOLVED else np.mean([r[4] for r in chart]) / unit_u   # one u span per chart
        v0 = 0.0
        for patches, rt, rs, along, _ in chart:
            du = turn / len(patches)
            for k, p in enumerate(patches):
                out[p] = (name, k * du, du, v0, along / unit_v, rt, rs)
            v0 += along / unit_v
    return out


def _mean(x: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """The mean of the rows of x (N, ...) sharing an id, per id 0 .. ids.max()."""
    acc = np.zeros((ids.max() + 1, *x.shape[1:]))
    np.add.at(acc, ids, x)
    return acc / np.bincount(ids).reshape(-1, *([1] * (x.ndim - 1)))


def bake_bytes(segments: int) -> int:
    """The peak memory of teapot(segments), estimated (vdmbake.bundle.budget): 1200 bytes per grid point of
    its 32 patches (measured: 1081 to 1095 at 128 and 256 segments, reading the mesh part back included)."""
    return 32 * (segments + 1) ** 2 * 1200


def teapot(size: float, segments: int) -> TriMesh:
    """The teapot `size` tall along +Z, its bottom's centre at the origin, the spout along +X; each
    patch an n x n grid (n = segments)."""
    n = segments
    budget.check(bake_bytes(n), f"the teapot of {n} segments", "use fewer segments")
    C = control_points() * (size / HEIGHT)
    g = np.linspace(0.0, 1.0, n + 1)
    s, t = np.repeat(g, n + 1), np.tile(g, n + 1)           # row-major (n+1)^2 grid: rows along s
    parts = {k: [] for k in ("P", "n", "uv", "dpdu", "dpdv", "T", "chart")}
    charts = list(CHARTS)
    for p in range(len(C)):
        chart, u0, du, v0, dv, rt, rs = layout()[p]
        d = evaluate(C[p], s, t)
        cross = np.cross(d["Pt"], d["Ps"])
        scale = np.linalg.norm(d["Ps"], axis=1) * np.linalg.norm(d["Pst"], axis=1) + 1e-300
        collapsed = np.linalg.norm(cross, axis=1) <= _COLLAPSED * scale
        # the limit normal along a collapsed s = 0 edge (the only kind the teapot has): P_st x P_s
        assert not collapsed.any() or (s[collapsed] == 0).all(), f"patch {p}: a collapse other than at s = 0"
        cross[collapsed] = np.cross(d["Pst"], d["Ps"])[collapsed]
        normal = cross / np.linalg.norm(cross, axis=1, keepdims=True)
        # the shape tensor of a collapsed edge is singular there: taken a little inside instead
        T = _shape_tensor(evaluate(C[p], s + _NUDGE * collapsed, t) if collapsed.any() else d)
        su, sv = (-1.0 if rt else 1.0), (-1.0 if rs else 1.0)
        uv = np.stack([u0 + du * ((1.0 - t) if rt else t), v0 + dv * ((1.0 - s) if rs else s)], 1)
        parts["P"].append(d["P"])
        parts["n"].append(normal)
        parts["uv"].append(uv)
        parts["dpdu"].append(d["Pt"] * (su / du))
        parts["dpdv"].append(d["Ps"] * (sv / dv))
        parts["T"].append(T)
        parts["chart"].append(np.full(len(s), charts.index(chart)))
    a = {k: np.concatenate(v) for k, v in parts.items()}
    faces = np.concatenate([grid_faces(n, n) + p * (n + 1) ** 2 for p in range(len(C))])

    # One vertex per point, chart and UV; normals and shape tensors averaged per point of a chart.
    w = weld(a["P"])
    point = np.unique(np.stack([a["chart"], w], 1), axis=0, return_inverse=True)[1].ravel()
    key = np.column_stack([point, np.round(a["uv"] * 2.0 ** 32)])
    _, first, vertex = np.unique(key, axis=0, return_index=True, return_inverse=True)
    vertex = vertex.ravel()
    normal = _mean(a["n"], point)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    T = _mean(a["T"], point)
    e1, e2 = onb(normal)                                    # the shape tensor on the tangent plane
    m = np.stack([np.stack([np.einsum("ni,nij,nj->n", x, T, y) for y in (e1, e2)], -1) for x in (e1, e2)], -2)
    k, vec = np.linalg.eigh(m)                              # ascending: k2, k1
    d1 = vec[:, 0, 1, None] * e1 + vec[:, 1, 1, None] * e2
    frame = SurfaceFrame(_mean(a["dpdu"], vertex), _mean(a["dpdv"], vertex), k[:, 1][point[first]],
                         k[:, 0][point[first]], d1[point[first]])
    f = vertex[faces]
    ids = w[faces]
    keep = (ids[:, 0] != ids[:, 1]) & (ids[:, 1] != ids[:, 2]) & (ids[:, 2] != ids[:, 0])
    return TriMesh(a["P"][first], f[keep], normal[point[first]], a["uv"][first], frame)
