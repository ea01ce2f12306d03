"""A min/max mip pyramid of a depth field and the exact first hit of a ray with its bilinear surface.

The hierarchical height-field tracer of Tevs, Ihrke & Seidel 2008 ("maximum mipmaps") and Drobot 2009
(quadtree displacement mapping), made exact for the bilinearly interpolated surface: this module is its
pure numpy twin (the bake's pyramid, and a reference traversal and brute-force hit for the tests);
shaders/include/heightfield_trace.glsl is the GPU traversal and documents the same conventions.

Depth field and surface. `samples` (H, W) holds depths (>= 0, larger = deeper) at texel centres. Sample
(i, j) (row i, column j) lies at sample coordinates (x, y) = (j, i); in GL texture coordinates of an H x W
texture that is ((j + 0.5) / W, (i + 0.5) / H), so x = s * W - 0.5, y = t * H - 0.5. The surface is the
bilinear interpolation of the samples: level-0 cell (i, j) is the square [j, j + 1] x [i, i + 1] and its
patch is spanned by the four samples at its corners, c00 = (i, j), c01 = (i, j + 1), c10 = (i + 1, j),
c11 = (i + 1, j + 1). A ray p(t) = o + d t runs in (x, y, depth); it is on or below the surface where its
depth is >= the surface's.

Modes. WRAP: a tiled field (repeat addressing, e.g. a mesostructure tile): H x W cells, indices mod (H, W),
the surface repeats with period (W, H). CLAMP: a bounded map (e.g. a billboard's depth map, its caller
supplying a one-texel border): (H - 1) x (W - 1) cells, the surface exists on [0, W - 1] x [0, H - 1] only.

Pyramid layout. Level 0 texel (i, j) holds [min, max] of the four corner samples of cell (i, j): a
bilinear patch is a convex combination of its corners, so it lies within that interval. Level L texel
(i, j) holds [min, max] over the level-0 cells [i 2^L, (i + 1) 2^L) x [j 2^L, (j + 1) 2^L) that exist:
ceil(n / 2^L) texels per axis of n level-0 cells (non-power-of-two sizes: the last texel of an axis covers
the remainder). The top level has a single texel over the whole field.

GL texture (texture_levels): one RGBA32F texture with a full mip chain over the level-0 cell grid padded to
powers of two (GL mip sizes halve with floor). Level 0: the four corners (c00, c01, c10, c11) of each cell;
level L >= 1: (min, max, min, max). The min and max of the four components are then the interval at every
level, so one texelFetch per cell visit serves both the interval test and, at level 0, the exact patch.
Padding texels are never fetched (the traversal keeps indices inside each level's ceil(n / 2^L)).
texture_atlas packs the same texels into one image without the padding (level origins passed to the
include's HF_FETCH), for cell counts far from a power of two.

Empty cells (build's `empty` mask, e.g. a billboard's uncovered texels) have no surface: an empty
interval, HUGE corners (a surface no ray reaches), so rays pass them at every level; intervals above
them come from the non-empty cells, and `holes` marks the cells that hold empty ones (see level_texels
for how the texture says so). Leaving such a cell, the ray's side is unknown (no surface joins an empty
cell to the next): it must come from above the next surface to hit it, so there is no wall at a
surface's border.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

WRAP, CLAMP = "wrap", "clamp"
MODES = (WRAP, CLAMP)
HUGE = 1e30


@dataclass(frozen=True)
class Pyramid:
    samples: np.ndarray               # (H, W) float32 depths at texel centres
    mode: str                         # WRAP or CLAMP
    levels: tuple[np.ndarray, ...]    # level L: (ceil(ny / 2^L), ceil(nx / 2^L), 2) float32 [min, max]

    @property
    def cells(self) -> tuple[int, int]:
        """(ny, nx) level-0 cells."""
        return self.levels[0].shape[:2]

    @property
    def top(self) -> int:
        return len(self.levels) - 1

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.levels)

    @functools.cached_property
    def holes(self) -> tuple[np.ndarray, ...]:
        """Per level, (rows, columns) bool: the cell holds an empty level-0 cell (build's `empty`)."""
        out = [self.levels[0][..., 0] >= HUGE]
        for a in self.levels[1:]:
            h = out[-1]
            h = np.pad(h, ((0, h.shape[0] % 2), (0, h.shape[1] % 2)), mode="edge")
            out.append(h.reshape(h.shape[0] // 2, 2, h.shape[1] // 2, 2).any(axis=(1, 3)))
        return tuple(out)


def corners(samples: np.ndarray, mode: str) -> np.ndarray:
    """(ny, nx, 4) the corner samples (c00, c01, c10, c11) of every level-0 cell."""
    s = np.asarray(samples, np.float32)
    if mode == WRAP:
        right = np.roll(s, -1, 1)
        return np.stack([s, right, np.roll(s, -1, 0), np.roll(right, -1, 0)], -1)
    return np.stack([s[:-1, :-1], s[:-1, 1:], s[1:, :-1], s[1:, 1:]], -1)


def _reduce(a: np.ndarray) -> np.ndarray:
    """One level up: each texel the [min, max] of the (up to) 2 x 2 below it."""
    ny, nx = a.shape[:2]
    a = np.pad(a, ((0, ny % 2), (0, nx % 2), (0, 0)), mode="edge")   # a repeated row changes no min/max
    b = a.reshape(a.shape[0] // 2, 2, a.shape[1] // 2, 2, 2)
    return np.stack([b[..., 0].min(axis=(1, 3)), b[..., 1].max(axis=(1, 3))], -1)


def build(samples: np.ndarray, mode: str, empty: np.ndarray | None = None) -> Pyramid:
    """The min/max pyramid of a depth field (see the module's docstring for the layout). empty: optional
    (ny, nx) bool over the level-0 cells, True where the field has no surface (a billboard's uncovered
    texels): such a cell's interval is [HUGE, -HUGE] (empty), and above it min and max come from the
    non-empty cells only; `holes` says which cells hold an empty one."""
    s = np.asarray(samples, np.float32)
    if mode not in MODES:
        raise ValueError(f"pyramid mode {mode!r}: use one of {MODES}")
    if s.ndim != 2 or min(s.shape) < (1 if mode == WRAP else 2):
        raise ValueError(f"depth field of shape {s.shape}: need 2-D, at least {1 if mode == WRAP else 2} per side")
    if not np.isfinite(s).all():
        raise ValueError("depth field has non-finite values")
    c = corners(s, mode)
    levels = [np.stack([c.min(-1), c.max(-1)], -1)]
    if empty is not None:
        if np.shape(empty) != levels[0].shape[:2]:
            raise ValueError(f"empty mask of shape {np.shape(empty)}: the field has {levels[0].shape[:2]} cells")
        levels[0][np.asarray(empty, bool)] = (HUGE, -HUGE)
    while max(levels[-1].shape[:2]) > 1:
        levels.append(_reduce(levels[-1]))
    return Pyramid(s, mode, tuple(np.ascontiguousarray(a) for a in levels))


def texture_levels(p: Pyramid) -> list[np.ndarray]:
    """The RGBA32F mip chain (level L: (max(1, Py >> L), max(1, Px >> L), 4), Px, Py the cell grid's sides
    rounded up to powers of two): corners at level 0, (min, max, min, max) above; zero padding."""
    ny, nx = p.cells
    py, px = 1 << math.ceil(math.log2(ny)), 1 << math.ceil(math.log2(nx))
    out = []
    for L, a in enumerate(p.levels):
        t = np.zeros((max(1, py >> L), max(1, px >> L), 4), np.float32)
        t[:a.shape[0], :a.shape[1]] = level_texels(p, L)
        out.append(t)
    return out


def level_texels(p: Pyramid, L: int) -> np.ndarray:
    """(ceil(ny / 2^L), ceil(nx / 2^L), 4) what the tracer fetches at level L: the corners at level 0 (HUGE
    for empty cells), (min, max, min, max) above; a cell above level 0 holding empty cells has (min, HUGE,
    min, max): its components' max (HUGE) says it has holes, w keeps the max of its non-empty cells; HUGE
    throughout if it is all empty."""
    if L == 0:
        return np.where(p.holes[0][..., None], np.float32(HUGE), corners(p.samples, p.mode))
    mn, mx = p.levels[L][..., 0], p.levels[L][..., 1]
    t = np.stack([mn, np.where(p.holes[L], np.float32(HUGE), mx), mn, mx], -1)
    return np.where((mn >= HUGE)[..., None], np.float32(HUGE), t)


def texture_atlas(p: Pyramid) -> tuple[np.ndarray, np.ndarray]:
    """The same texels as texture_levels without power-of-two padding, for fields whose cell count is not a
    power of two (a billboard's R + 1 cells: padding would quadruple it): one RGBA32F image, level 0 at
    (0, 0), levels 1.. stacked top to bottom in a column to its right. Returns the image (rows, columns, 4)
    and origins (levels, 2): the (x, y) texel where each level starts (the include's HF_FETCH adds it)."""
    ny, nx = p.cells
    col = p.levels[1].shape[1] if p.top > 0 else 0
    height = max(ny, sum(a.shape[0] for a in p.levels[1:]))
    out = np.zeros((height, nx + col, 4), np.float32)
    origins = np.zeros((len(p.levels), 2), np.int32)
    y = 0
    for L in range(len(p.levels)):
        t = level_texels(p, L)
        if L > 0:
            origins[L] = (nx, y)
            y += t.shape[0]
        out[origins[L, 1]:origins[L, 1] + t.shape[0], origins[L, 0]:origins[L, 0] + t.shape[1]] = t
    return out, origins


def occupied_boxes(p: Pyramid, level: int) -> np.ndarray:
    """(n, 2, 3) the boxes [lo, hi] in the bordered map's sample coordinates (x, y, depth) of the non-empty
    cells at `level` of a pyramid: each the cell's square times the depth interval of its non-empty level-0
    cells. Every point of the bilinear surface lies in one of them, so a ray that enters none reaches no
    surface, and one that does reaches none before its first entry (the billboards' occupancy pre-pass)."""
    level = min(level, p.top)
    ny, nx = p.cells
    lo0, hi0 = p.levels[0][..., 0], p.levels[0][..., 1]
    hi0 = np.where(lo0 >= HUGE, -np.inf, hi0)          # max over non-empty cells only
    k = 1 << level
    pad_y, pad_x = -ny % k, -nx % k
    hi = np.pad(hi0, ((0, pad_y), (0, pad_x)), constant_values=-np.inf)
    hi = hi.reshape(hi.shape[0] // k, k, hi.shape[1] // k, k).max(axis=(1, 3))
    lo = p.levels[level][..., 0]
    i, j = np.nonzero(lo < HUGE)
    return np.stack([np.stack([j * k, i * k, lo[i, j]], 1),
                     np.stack([np.minimum((j + 1) * k, nx), np.minimum((i + 1) * k, ny), hi[i, j]], 1)], 1)


def to_parts(p: Pyramid) -> dict[str, dict[str, np.ndarray]]:
    """EXR parts (vdmbake.formats.exr): 'samples' (channel 'depth.Z') and one part per level, 'L00', 'L01', ...
    (channels 'min.Z', 'max.Z'). The mode is the caller's to record."""
    parts = {"samples": {"depth.Z": p.samples}}
    for L, a in enumerate(p.levels):
        parts[f"L{L:02d}"] = {"min.Z": a[..., 0], "max.Z": a[..., 1]}
    return parts


def from_parts(parts: dict[str, dict[str, np.ndarray]], mode: str, empties: bool = False) -> Pyramid:
    """The Pyramid that to_parts wrote. ValueError unless its levels are the ones its samples make in `mode`:
    L00, L01, ... up to the single texel, each ceil(n / 2^L) cells per axis (not a level missing, out of
    order, or built in the other mode), and unless every interval holds the surface below it (what the
    tracer relies on to skip a cell). empties: level-0 cells may be marked empty ([HUGE, -HUGE], a
    billboard's uncovered texels)."""
    s = np.asarray(parts["samples"]["depth.Z"], np.float32)
    if mode not in MODES or s.ndim != 2 or min(s.shape) < (1 if mode == WRAP else 2):
        raise ValueError(f"samples of shape {s.shape} make no {mode!r} pyramid")
    ny, nx = s.shape if mode == WRAP else (s.shape[0] - 1, s.shape[1] - 1)
    top = (max(ny, nx) - 1).bit_length()                 # levels until one texel: ceil(log2(n))
    names = sorted(k for k in parts if k.startswith("L"))
    if names != [f"L{L:02d}" for L in range(top + 1)]:
        raise ValueError(f"levels {', '.join(names)} where {mode} samples of {s.shape[0]} x {s.shape[1]} make "
                         f"L00 to L{top:02d}")
    levels = []
    for L, k in enumerate(names):
        if not {"min.Z", "max.Z"} <= set(parts[k]):
            raise ValueError(f"level {k} lacks its min.Z or max.Z channel")
        a = np.stack([parts[k]["min.Z"], parts[k]["max.Z"]], -1).astype(np.float32)
        if a.shape[:2] != (-(-ny >> L), -(-nx >> L)):
            raise ValueError(f"level {k} has {a.shape[0]} x {a.shape[1]} cells where {mode} samples of "
                             f"{s.shape[0]} x {s.shape[1]} make {-(-ny >> L)} x {-(-nx >> L)}")
        levels.append(a)
    # Level 0 must hold each cell's corner samples, each level above the level below it (then every level holds
    # the surface, as the tracer assumes when it skips a cell); empty cells hold nothing.
    if mode == WRAP:
        right = np.roll(s, -1, 1)
        four = (s, right, np.roll(s, -1, 0), np.roll(right, -1, 0))
    else:
        four = (s[:-1, :-1], s[:-1, 1:], s[1:, :-1], s[1:, 1:])
    lo, hi = np.minimum(np.minimum(four[0], four[1]), np.minimum(four[2], four[3])), \
        np.maximum(np.maximum(four[0], four[1]), np.maximum(four[2], four[3]))
    held = (levels[0][..., 0] <= lo) & (levels[0][..., 1] >= hi)
    if not (held | (empties & (levels[0][..., 0] >= HUGE))).all():
        raise ValueError("level L00 has intervals that do not hold the surface its samples make")
    for L in range(1, len(levels)):
        below = _reduce(levels[L - 1])
        if not (np.all(levels[L][..., 0] <= below[..., 0]) and np.all(levels[L][..., 1] >= below[..., 1])):
            raise ValueError(f"level L{L:02d} has intervals that do not hold the level below it")
    return Pyramid(s, mode, tuple(levels))


# ------------------------------------------------------------------------------------------ the exact patch

def patch_hit(c: np.ndarray, u0: float, v0: float, z0: float, du: float, dv: float, dz: float, length: float,
              inside: bool, bend: float = 0.0) -> tuple[float, bool]:
    """The first hit within one cell: the ray at local (u0, v0, z0) (u along x, v along y, 0..1 over the
    cell) moving by (du, dv) per unit s, its depth z0 + dz s + bend s^2, for s in [0, length]. f(s) = depth
    of the ray - depth of the patch = A s^2 + B s + C. `inside`: the ray was on or below the surface just
    before s = 0.
    Returns (s or -1, inside at s = length). A hit is where f passes from < 0 to >= 0, or s = 0 when
    f(0) >= 0 and the ray was not inside (it reaches the surface exactly at the cell's entry)."""
    s, end_inside, _ = patch_hit_sides(c, u0, v0, z0, du, dv, dz, length, inside, bend)
    return s, end_inside


def patch_hit_sides(c: np.ndarray, u0: float, v0: float, z0: float, du: float, dv: float, dz: float,
                    length: float, inside: bool, bend: float = 0.0, outside: bool | None = None
                    ) -> tuple[float, bool, bool]:
    """patch_hit, and with `outside` given, hits from below too (two-sided traces): `outside` False when the
    ray was known to be below just before s = 0 (True: above or unknown). A hit from below is where f passes
    from >= 0 to < 0, or s = 0 when f(0) < 0 and the ray was known below. Returns (s or -1, inside at
    s = length, True if the hit is from below)."""
    c00, c01, c10, c11 = (float(x) for x in c)
    e = c00 - c01 - c10 + c11
    C = z0 - (c00 + (c01 - c00) * u0 + (c10 - c00) * v0 + e * u0 * v0)
    B = dz - (c01 - c00 + e * v0) * du - (c10 - c00 + e * u0) * dv
    A = bend - e * du * dv
    end_inside = A * length * length + B * length + C >= 0.0
    lo, hi = _roots(A, B, C)
    first = lo if lo >= 0.0 else hi
    if C < 0.0:
        s = first                                # the first root at or after 0 is an entry (f rises to 0)
        back = 0.0 if outside is False else (hi if (A < 0.0 and lo < hi and hi > 0.0) else HUGE)
    else:                                        # inside: the ray must leave (f < 0 between the roots) and return
        s = 0.0 if not inside else (hi if (A > 0.0 and lo < hi and hi > 0.0) else HUGE)
        back = first                             # where it leaves, from below
    from_below = outside is not None and back < s
    if from_below:
        s = back
    return (s, True, from_below) if 0.0 <= s <= length else (-1.0, end_inside, False)


def _roots(A: float, B: float, C: float) -> tuple[float, float]:
    """Real roots of A s^2 + B s + C, sorted (HUGE where none), by the stable form of Numerical Recipes
    (sec. 5.6): q = -(B + sign(B) sqrt(B^2 - 4 A C)) / 2, roots q / A and C / q."""
    disc = B * B - 4.0 * A * C
    if disc < 0.0:
        return HUGE, HUGE
    q = -0.5 * (B + math.copysign(math.sqrt(disc), B))
    r1 = q / A if A != 0.0 else HUGE
    r2 = C / q if q != 0.0 else HUGE
    return min(r1, r2), max(r1, r2)


# ------------------------------------------------------------------------------------------ the traversal

@dataclass
class TraceStats:
    visits: int = 0          # cell visits (loop iterations, one texture fetch each)
    from_below: bool = False # two-sided traces: the hit is from below the surface
    exhausted: bool = False  # the iteration cap stopped it
    t_reached: float = 0.0   # the t the traversal had reached when it returned


def trace(p: Pyramid, o, d, t0: float, t1: float, reentry: bool = False, bend: float = 0.0,
          max_iter: int = 1 << 16, start_level: int = 64, stats: TraceStats | None = None,
          two_sided: bool = False) -> float:
    """The first hit t in [t0, t1] of the ray o + d t (sample coordinates, depth) with the bilinear
    surface, or -1: the numpy twin of heightfield_trace.glsl's hf_trace_general (same steps, float64).
    bend: the ray's depth is o.z + d.z t + bend t^2 (a ray over a curved base surface; the path in x, y
    stays straight).
    reentry=False: the first t at which the ray is on or below the surface (t0 itself if it starts there).
    reentry=True: the first t at which it passes from above the surface onto or below it; a ray that starts
    on or below must first come out (a shadow ray from a hit, or a call resumed after a rejected hit).
    two_sided=True: the first t at which it passes through the surface either way (the ray's side unknown
    at t0, as with reentry); stats.from_below says which way (hf_trace_two_sided, hf_from_below)."""
    st = stats if stats is not None else TraceStats()
    o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
    ny, nx = p.cells
    n = (nx, ny)
    wrap = p.mode == WRAP
    if not wrap:                                      # clip to the domain [0, nx] x [0, ny]
        for a in range(2):
            if d[a] != 0.0:
                ta, tb = sorted(((0.0 - o[a]) / d[a], (n[a] - o[a]) / d[a]))
                t0, t1 = max(t0, ta), min(t1, tb)
            elif not 0.0 <= o[a] <= n[a]:
                return -1.0
    st.t_reached = t0
    if not t0 <= t1:
        return -1.0
    step = [1 if d[a] >= 0.0 else -1 for a in range(2)]
    inv = [1.0 / d[a] if d[a] != 0.0 else HUGE for a in range(2)]
    t = t0
    level = min(p.top, start_level)
    tile = [0, 0]
    idx = [0, 0]
    pos = o + d * t
    for a in range(2):                                # the tile and the starting cell; on a boundary, the side ahead
        if wrap:
            tile[a] = math.floor(pos[a] / n[a])
            if pos[a] - tile[a] * n[a] == 0.0 and step[a] < 0:
                tile[a] -= 1
        x = pos[a] - tile[a] * n[a]
        k = math.floor(x / (1 << level))
        if x == k * (1 << level) and step[a] < 0:
            k -= 1
        idx[a] = min(max(k, 0), p.levels[level].shape[1 - a] - 1)
    inside = reentry or two_sided          # below the surface, or on an unknown side
    outside = True                         # above, or unknown: False only when known below (two-sided)
    for _ in range(max_iter):
        st.visits += 1
        size = 1 << level
        counts = [p.levels[level].shape[1], p.levels[level].shape[0]]
        exits = []
        for a in range(2):
            lo = idx[a] * size
            bound = min(lo + size, n[a]) if step[a] > 0 else lo
            exits.append((tile[a] * n[a] + bound - o[a]) * inv[a] if d[a] != 0.0 else HUGE)
        te = min(exits[0], exits[1], t1)
        zmin, zmax = (float(x) for x in p.levels[level][idx[1], idx[0]])
        holey = bool(p.holes[level][idx[1], idx[0]])
        z = lambda x: o[2] + x * (d[2] + bend * x)
        tv = min(max(-d[2] / (2.0 * bend), t), te) if bend != 0.0 else t    # the parabola's vertex, clamped
        za, zb, zv = z(t), z(te), z(tv)
        above = outside and max(za, zb, zv) < zmin
        below = inside and min(za, zb, zv) > zmax
        if not (above or below):
            if level > 0:                             # descend (Tevs et al. 2008)
                if za < zmin and outside:             # nothing to hit before the ray reaches the cell's min depth
                    lo, hi = _roots(bend, d[2] + 2.0 * bend * t, za - zmin)
                    t = min(t + (lo if lo >= 0.0 else hi), te)
                    inside, outside = False, True
                pos = o + d * t
                level -= 1
                half = 1 << level
                for a in range(2):
                    mid = tile[a] * n[a] + (2 * idx[a] + 1) * half
                    upper = pos[a] > mid or (pos[a] == mid and step[a] > 0)
                    idx[a] = min(2 * idx[a] + int(upper), p.levels[level].shape[1 - a] - 1)
                continue
            ci = corners_at(p, idx[1], idx[0])
            u0 = o[0] + d[0] * t - (tile[0] * n[0] + idx[0])
            v0 = o[1] + d[1] * t - (tile[1] * n[1] + idx[1])
            s, inside, st.from_below = patch_hit_sides(ci, u0, v0, za, d[0], d[1], d[2] + 2.0 * bend * t, te - t,
                                                       inside, bend, outside if two_sided else None)
            if s >= 0.0:
                st.t_reached = t + s
                return t + s
            outside = not (two_sided and inside)
        else:
            # a skipped cell holding an empty cell leaves the ray's side unknown where it leaves (there is no
            # surface across an empty cell): it must then come from the other side of the next surface to
            # hit it, so a ray passing beneath (or above) a surface's border finds no wall there
            inside = below or holey
            outside = not two_sided or above or holey
        # leave the cell by the side(s) the ray exits through; ascend if a parent boundary was crossed
        if te >= t1:
            st.t_reached = t1
            return -1.0
        t = te
        up = False
        for a in range(2):
            if exits[a] != te:
                continue
            i = idx[a] + step[a]
            if not 0 <= i < counts[a]:
                if not wrap:
                    st.t_reached = t
                    return -1.0                       # left the domain
                tile[a] += step[a]
                i = 0 if step[a] > 0 else counts[a] - 1
                up = True
            up = up or i >> 1 != idx[a] >> 1
            idx[a] = i
        if up and level < p.top:
            level += 1
            idx = [i >> 1 for i in idx]
    st.exhausted = True
    st.t_reached = t
    return -1.0


def corners_at(p: Pyramid, i: int, j: int) -> np.ndarray:
    s = p.samples
    h, w = s.shape
    i1, j1 = (i + 1) % h, (j + 1) % w
    return np.array([s[i, j], s[i, j1], s[i1, j], s[i1, j1]], np.float64)


# ------------------------------------------------------------------------------------------ brute force

def bilinear(samples: np.ndarray, mode: str, x, y):
    """The surface's depth at sample coordinates (x, y), float64 (a CLAMP field's coordinates are clamped to it)."""
    s = np.asarray(samples, np.float64)
    h, w = s.shape
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    j0, i0 = np.floor(x), np.floor(y)
    fx, fy = x - j0, y - i0
    if mode == WRAP:
        j0, i0 = j0.astype(np.int64) % w, i0.astype(np.int64) % h
        j1, i1 = (j0 + 1) % w, (i0 + 1) % h
    else:
        x, y = np.clip(x, 0, w - 1), np.clip(y, 0, h - 1)
        j0, i0 = np.clip(np.floor(x), 0, w - 2).astype(np.int64), np.clip(np.floor(y), 0, h - 2).astype(np.int64)
        fx, fy = x - j0, y - i0
        j1, i1 = j0 + 1, i0 + 1
    return (1 - fy) * ((1 - fx) * s[i0, j0] + fx * s[i0, j1]) + fy * ((1 - fx) * s[i1, j0] + fx * s[i1, j1])


def first_hit(samples: np.ndarray, mode: str, o, d, t0: float, t1: float, reentry: bool = False,
              bend: float = 0.0) -> float:
    """The same answer as trace() by brute force, independent of its traversal and patch algebra: the cell
    lines the ray crosses cut [t0, t1] into pieces on which f(t) = ray depth - surface depth is a quadratic
    (fitted through three points of bilinear()); its roots cut them further into pieces of constant sign,
    read off at their midpoints."""
    s = np.asarray(samples, np.float64)
    h, w = s.shape
    o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
    if mode == CLAMP:
        for a, n in ((0, w - 1), (1, h - 1)):
            if d[a] != 0.0:
                ta, tb = sorted(((0.0 - o[a]) / d[a], (n - o[a]) / d[a]))
                t0, t1 = max(t0, ta), min(t1, tb)
            elif not 0.0 <= o[a] <= n:
                return -1.0
    if not t0 <= t1:
        return -1.0

    def f(t):
        return o[2] + (d[2] + bend * t) * t - bilinear(s, mode, o[0] + d[0] * t, o[1] + d[1] * t)

    cuts = [np.array([t0, t1])]
    for a in range(2):                                  # where the ray crosses cell lines x = k or y = k
        if d[a] != 0.0:
            a0, a1 = sorted((o[a] + d[a] * t0, o[a] + d[a] * t1))
            cuts.append((np.arange(math.ceil(a0), math.floor(a1) + 1) - o[a]) / d[a])
    cuts = np.unique(np.clip(np.concatenate(cuts), t0, t1))
    ta, tb = cuts[:-1], cuts[1:]
    ln = tb - ta
    f0, fm, f1 = f(ta), f(0.5 * (ta + tb)), f(tb)
    with np.errstate(divide="ignore", invalid="ignore"):
        A = 2.0 * (f1 - 2.0 * fm + f0) / ln ** 2       # f(ta + x) = A x^2 + B x + C on each piece
        B = (4.0 * fm - 3.0 * f0 - f1) / ln
        disc = B * B - 4.0 * A * f0
        sq = np.sqrt(np.maximum(disc, 0.0))
        q = -0.5 * (B + np.where(B < 0, -sq, sq))
        roots = np.stack([np.where(A != 0, q / A, np.nan), np.where(q != 0, f0 / q, np.nan)], 1)
    roots[~(disc >= 0)] = np.nan
    x = roots + ta[:, None]
    inside = (roots >= 0) & (roots <= ln[:, None])
    pts = np.unique(np.concatenate([cuts, x[inside]]))
    pts = pts[(pts >= t0) & (pts <= t1)]
    if not reentry and f(t0) >= 0.0:
        return float(t0)
    neg = f(0.5 * (pts[:-1] + pts[1:])) < 0.0          # above the surface on each piece
    first_above = 0 if (not reentry and f(t0) < 0.0) else (int(np.argmax(neg)) if neg.any() else None)
    if first_above is None:
        return -1.0
    after = np.nonzero(~neg[first_above:])[0]
    if after.size:
        return float(pts[first_above + after[0]])
    return float(t1) if f(t1) >= 0.0 else -1.0
