"""The quadric reference's boxes (pure numpy, float64): quadrics grouped by grid cell, each group in a
box of its own random orientation, and which boxes lie near a point.

Why groups: embreex fills an Embree scene triangle by triangle (about 20 us a 12-triangle box), which
made one box a quadric cost 24 s of set-up at a million atoms; a few quadrics a box cut that as many
times. Why each box its own orientation: boxes of one orientation share face planes wherever input
coordinates are rounded alike (PDB files: 0.001 A), and a walk that steps past one face skips every
face within the step of it.
"""
from __future__ import annotations

import numpy as np

GROUP_CAP = 16   # most quadrics a group: the tracer tests them all when the group's box is met
_BITS = 21       # cell coordinates a side: three fit an int64 key


def quadric_boxes(spheres, cylinders, rot):
    """Bounds (lo, hi), (N + M, 3) each, of the spheres then the capped cylinders along the rows of
    each quadric's rotation rot (N + M, 3, 3): a cap of radius r across the unit axis w reaches
    r sqrt(1 - w_i^2) along axis i."""
    rs, rc = rot[:len(spheres)], rot[len(spheres):]
    c0, c1 = np.einsum("nij,nj->ni", rc, cylinders[:, :3]), np.einsum("nij,nj->ni", rc, cylinders[:, 3:6])
    w = (c1 - c0) / np.linalg.norm(c1 - c0, axis=1, keepdims=True)
    ext = cylinders[:, 6:7] * np.sqrt(np.maximum(1.0 - w * w, 0.0))
    s = np.einsum("nij,nj->ni", rs, spheres[:, :3])
    return (np.concatenate([s - spheres[:, 3:4], np.minimum(c0, c1) - ext]),
            np.concatenate([s + spheres[:, 3:4], np.maximum(c0, c1) + ext]))


def random_rotations(n: int, seed: int = 0) -> np.ndarray:
    """n rotation matrices (n, 3, 3) from uniform random unit quaternions (a fixed seed: the reference
    traces the same boxes every run)."""
    a, b, c, d = np.random.default_rng(seed).normal(size=(4, n))
    s = np.sqrt(a * a + b * b + c * c + d * d)
    a, b, c, d = a / s, b / s, c / s, d / s
    return np.stack([np.stack([a*a + b*b - c*c - d*d, 2*(b*c - a*d), 2*(b*d + a*c)], -1),
                     np.stack([2*(b*c + a*d), a*a - b*b + c*c - d*d, 2*(c*d - a*b)], -1),
                     np.stack([2*(b*d - a*c), 2*(c*d + a*b), a*a - b*b - c*c + d*d], -1)], 1)


class Grid:
    """Integer cells of edge `edge` from `origin`, packed into int64 keys."""

    def __init__(self, origin, edge: float, extent: float):
        self.origin = np.asarray(origin, float)
        self.edge = max(edge, extent / 2.0 ** (_BITS - 2), 1e-300)   # every cell index fits its bits

    def cells(self, p):
        return np.floor((p - self.origin) / self.edge).astype(np.int64)

    @staticmethod
    def key(cells):
        """(N,) keys; -1 for a cell outside the grid."""
        inside = ((cells >= 0) & (cells < 1 << _BITS)).all(-1)
        return np.where(inside, (cells[..., 0] << 2 * _BITS) | (cells[..., 1] << _BITS) | cells[..., 2], -1)


def grid_groups(centre, edge: float, cap: int = GROUP_CAP):
    """Points grouped by the grid cell (edge `edge`) they lie in, at most `cap` a group: (members (C, K)
    point indices padded with -1, each point's group)."""
    grid = Grid(centre.min(0), edge, float(np.ptp(centre, 0).max()))
    key = Grid.key(grid.cells(centre))
    order = np.argsort(key, kind="stable")
    key = key[order]
    at = np.arange(len(key))
    rank = at - np.maximum.accumulate(np.where(np.r_[True, key[1:] != key[:-1]], at, 0))
    group = np.cumsum(rank % cap == 0) - 1
    members = np.full((group[-1] + 1, min(cap, int(rank.max()) + 1)), -1, np.int64)
    members[group, rank % cap] = order
    of = np.empty(len(order), np.int64)
    of[order] = group
    return members, of


class Cover:
    """Which boxes (world bounds lo, hi) may hold a point. Levels of grids, edge `edge` times 1, 4,
    16, ...: each box is listed, in the first level where it spans at most 4 cells a side, in every
    cell it overlaps; a point's cell in each level lists them all. A few large quadrics among small
    ones thus cost a level more to look up, never a list for every point."""

    def __init__(self, lo, hi, edge: float):
        self.levels = []
        left = np.arange(len(lo))
        while len(left):
            grid = Grid(lo.min(0), edge * 4 ** len(self.levels), float((hi.max(0) - lo.min(0)).max()))
            a, b = grid.cells(lo[left]), grid.cells(hi[left])
            here = ((b - a) < 4).all(1)
            self.levels.append((grid, *self._cells(left[here], a[here], b[here] - a[here] + 1)))
            left = left[~here]

    @staticmethod
    def _cells(box, a, span):
        """Sorted cell keys with where their boxes start and how many (a key -2 first: no cell), boxes."""
        count = span.prod(1)
        row = np.repeat(np.arange(len(box)), count)
        k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        sy, sz = span[row, 1], span[row, 2]
        key = Grid.key(a[row] + np.stack([k // (sy * sz), (k // sz) % sy, k % sz], 1))
        order = np.argsort(key, kind="stable")
        keys, start, n = np.unique(key[order], return_index=True, return_counts=True)
        return np.r_[-2, keys], np.r_[0, start], np.r_[0, n], box[row[order]]

    def near(self, p):
        """Boxes whose cells hold each point p (N, 3), every box that holds it among them, as pairs:
        (point index, box index)."""
        points, boxes = [], []
        for grid, keys, start, count, box in self.levels:
            key = Grid.key(grid.cells(p))
            at = np.minimum(np.searchsorted(keys, key), len(keys) - 1)
            n = np.where(keys[at] == key, count[at], 0)
            k = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
            points.append(np.repeat(np.arange(len(p)), n))
            boxes.append(box[np.repeat(start[at], n) + k])
        return np.concatenate(points), np.concatenate(boxes)
