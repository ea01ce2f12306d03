"""Height fields and rays for the tests of the exact hierarchical tracer (test_heightfield_trace.py) and its GLSL
twin (test_twins.py): a library module, it holds no tests."""
from __future__ import annotations

import numpy as np

from vdmbake.assets import heightfields
from vdmbake.common import pyramid as P


def slot_field(n=16, kind="slot"):
    """Depth 0 everywhere but one column at depth 1 (a one-texel slot), or the reverse (a one-texel wall)."""
    s = np.zeros((n, n), np.float32) if kind == "slot" else np.ones((n, n), np.float32)
    s[:, n // 2] = 1.0 - s[0, 0]
    return s


def fields():
    rng = np.random.default_rng(7)
    cliffs = 1.0 - heightfields.pattern("cliffs", 16)
    return {
        "random 8x8": rng.random((8, 8)).astype(np.float32),
        "binary 13x6": (rng.random((13, 6)) > 0.5).astype(np.float32),   # vertical walls, non-power-of-two
        "cliffs 16": cliffs.astype(np.float32),
        "slot 16": slot_field(16, "slot"),
        "wall 16": slot_field(16, "wall"),
        "flat 5x7": np.full((5, 7), 0.25, np.float32),
        "bricks 32": (0.3 * (1.0 - heightfields.pattern("bricks", 32))).astype(np.float32),
    }


def random_rays(pyr, rng, count, far=False):
    """(count, 9): origin, t0, direction, t1, bend; a mixture of generic, axis-aligned, straight-down,
    grazing, on-the-grid and bent rays (depth o.z + d.z t + bend t^2, both signs)."""
    ny, nx = pyr.cells
    zhi = float(pyr.levels[-1][0, 0, 1])
    rays = []
    for k in range(count):
        if pyr.mode == P.WRAP:
            base = 1e4 if far else 0.0
            o = np.array([base + rng.uniform(-2 * nx, 2 * nx), base + rng.uniform(-2 * ny, 2 * ny),
                          rng.uniform(-0.3, 0.2) * max(zhi, 0.1)])
        else:
            o = np.array([rng.uniform(0, nx), rng.uniform(0, ny), rng.uniform(-0.3, 0.2) * max(zhi, 0.1)])
        d = np.array([rng.normal(), rng.normal(), rng.uniform(-0.2, 0.5)])
        kind = k % 8
        if kind == 1:
            d[:2] = 0.0                                   # straight down (or up)
            d[2] = abs(d[2]) + 0.1
        elif kind == 2:
            d[rng.integers(2)] = 0.0                      # axis-aligned
        elif kind == 3:
            o[:2] = np.round(o[:2])                       # from a sample point (cell corner)
            d[0] = 0.0                                    # along a cell edge
        elif kind == 4:
            d[2] = 0.002 * rng.uniform(0.1, 1.0)          # grazing
        elif kind == 5:
            o[:2] = np.round(o[:2])
            d[:2] = np.array([1.0, 1.0]) * rng.choice([-1, 1], 2)   # diagonal through cell corners
        elif kind == 6:
            d[2] = 0.0                                    # horizontal
        elif kind == 7:
            d[2] = abs(d[2])                              # bent: convex (turning back up) or concave
            bend = rng.choice([-1.0, 1.0]) * rng.uniform(0.001, 0.2)
        rays.append([*o, 0.0, *d, rng.uniform(0.5, 20.0), bend if kind == 7 else 0.0])
    return np.array(rays)
