// Exact hierarchical ray tracing of a bilinearly interpolated depth field through its min/max mip pyramid
// (Tevs, Ihrke & Seidel 2008, "maximum mipmaps"; Drobot 2009, quadtree displacement mapping). The numpy
// twin, with the pyramid's layout, is vdmbake/common/pyramid.py (build, texture_levels, trace).
//
// INTERFACE
//   float hf_trace(vec3 o, vec3 d, float t0, float t1)
//       The first t in [t0, t1] at which the ray o + d t is on or below the surface (t0 itself if it starts
//       there), or -1.0 if there is none (or the iteration cap ran out: see hf_exhausted).
//   float hf_trace_reentry(vec3 o, vec3 d, float t0, float t1)
//       The first t in [t0, t1] at which the ray passes from above the surface onto or below it: a ray that
//       starts on or below must first come out. For a shadow ray from a hit, and to resume just past a hit
//       the caller rejected (e.g. a billboard's empty texel): call again with t0 = the rejected t.
//   float hf_trace_general(vec3 o, vec3 d, float k, float t0, float t1, bool reentry)
//       Either of the above (reentry selects) for a bent ray: its depth is o.z + d.z t + k t^2 while its
//       path in (x, y) stays straight, e.g. a ray over a curved base surface of normal curvature c along
//       the ray, k = -c |d.xy|^2 / 2 in the field's units (curved relief mapping, Oliveira & Policarpo 2005).
//   float hf_trace_two_sided(vec3 o, vec3 d, float t0, float t1)
//       The first t in [t0, t1] at which the ray passes through the surface either way (its side unknown at
//       t0, as with reentry); hf_from_below is then true if it came from below (e.g. a billboard's open
//       surface seen from behind, or from inside a closed model).
//   After any call: hf_exhausted is true if HF_MAX_ITER cell visits ran out (the result is then -1.0);
//   hf_t_reached is the t the traversal had reached (the hit, t1, or where the cap stopped it; the ray is
//   above the surface there). Counts (cost_count.glsl): every call is a search, every cell visit a step and
//   one fetch of the pyramid.
//
// COORDINATES. (x, y) are sample coordinates: sample (i, j) (row i, column j) of the H x W depth field
// lies at (j, i), i.e. x = s W - 0.5, y = t H - 0.5 for GL texture coordinates (s, t) of the field. z is
// depth in the field's units, growing into the surface. t is the caller's ray parameter (d need not be unit).
// A mesostructure tile of N^2 texels at tile coordinate T, depth in texture units: o = (T N - 0.5, 0),
// d = (-V.xy N, V.z). A billboard's R^2 map with a one-texel border (R + 2 samples): x = st R + 0.5.
//
// SURFACE AND MODES. Level-0 cell (i, j) is the square [j, j + 1] x [i, i + 1], its patch the bilinear
// interpolation of its four corner samples. Default (wrap): a tiled field, W x H cells repeating with
// period (W, H). HF_CLAMP: a bounded field, (W - 1) x (H - 1) cells; the ray is clipped to the domain
// [0, W - 1] x [0, H - 1] and has no hit outside it.
//
// DATA (the caller binds; vdmbake/common/pyramid.py texture_levels builds it):
//   u_hf        RGBA32F, a full mip chain over the level-0 cell grid padded to powers of two; level 0:
//               the corners (c00, c01, c10, c11) = samples (i, j), (i, j+1), (i+1, j), (i+1, j+1) of each
//               cell; level L >= 1: (min, max, min, max) over the level-0 cells [i 2^L, (i+1) 2^L) x
//               [j 2^L, (j+1) 2^L). Read with texelFetch only (no filtering). One fetch serves a visit at
//               any level, which on llvmpipe beats an RG32F min/max chain plus a gather of the corner
//               samples (every branch's fetches are paid there; docs/mesostructure.md).
//               Empty cells (pyramid.build's `empty`, e.g. a billboard's uncovered texels) hold HF_HUGE
//               corners: rays pass them. Above level 0 a cell holding empty ones is (min, HF_HUGE, min, max).
//   u_hf_cells  ivec2 (cells along x, cells along y) at level 0;  u_hf_top  the top level (one texel).
//   Define HF_FETCH(ivec2 cell, int level) before the include to read another texture (e.g. a layer of a
//   texture array; then u_hf is not declared).
//
// OPTIONS (#define before the include): HF_CLAMP; HF_MAX_ITER (cell visits per call, a constant or a
// uniform; default 256); HF_START_LEVEL (the level the descent starts from, capped at the top; default the
// top: the whole field).
//
// THE TRAVERSAL (one pyramid fetch per loop iteration). At the current cell of level L, the ray's segment
// [t, te] inside it (te: where it leaves through a cell side, or t1) is tested against the cell's depth
// interval [zmin, zmax]: the ray cannot reach the surface there if its depth stays below zmin over the
// segment (above the surface), nor, while it is known to be inside, if it stays beyond zmax (the depth's
// range over the segment: its ends, and the vertex of a bent ray's parabola if it lies between). Then:
//   miss     step into the neighbour cell through the side the ray leaves by (both on a corner), and
//            ascend one level if that crossed a boundary of the parent level (Tevs et al. 2008);
//   L > 0    descend into the child that holds the ray, first moving t to where the ray reaches zmin;
//   L = 0    solve the ray against the cell's bilinear patch: along the ray the patch's depth is quadratic
//            in t (and a bent ray's too), so f(t) = ray depth - patch depth = A t^2 + B t + C exactly,
//            solved by the stable form of Numerical Recipes (sec. 5.6). A hit is where f passes from < 0
//            to >= 0 (or the cell's entry, if f >= 0 there and the ray was not inside).
// Robustness in float32: cells are tracked by integer indices (level, cell, tile) and stepped by integer
// arithmetic, never re-derived from a rounded position, so the loop cannot stall on a cell boundary and
// every cell along the ray is visited in order; exits come from exact integer boundaries; the patch is
// solved in cell-local coordinates from the cell's entry point. A hit that rounding pushes just past a
// cell's exit is caught at the next cell's entry (f >= 0 there and the ray not inside).

#include "cost_count.glsl"
#ifndef HF_MAX_ITER
#define HF_MAX_ITER 256
#endif
#ifndef HF_START_LEVEL
#define HF_START_LEVEL 64
#endif
#ifndef HF_FETCH
uniform sampler2D u_hf;
#define HF_FETCH(cell, level) texelFetch(u_hf, cell, level)
#endif
uniform ivec2 u_hf_cells;
uniform int u_hf_top;

bool hf_exhausted = false;
bool hf_from_below = false;
float hf_t_reached = 0.0;

const float HF_HUGE = 1e30;

// Component-wise logic and selection (GLSL 4.3 has no && on bvec and no mix on ivec).
bvec2 hf_and(bvec2 a, bvec2 b) { return bvec2(a.x && b.x, a.y && b.y); }
ivec2 hf_select(ivec2 a, ivec2 b, bvec2 c) { return ivec2(c.x ? b.x : a.x, c.y ? b.y : a.y); }

// Real roots of A s^2 + B s + C, sorted, HF_HUGE where there is none (Numerical Recipes sec. 5.6:
// q = -(B + sign(B) sqrt(B^2 - 4 A C)) / 2, roots q / A and C / q; no cancellation).
vec2 hf_roots(float A, float B, float C) {
    float disc = B * B - 4.0 * A * C;
    if (disc < 0.0) return vec2(HF_HUGE);
    float q = -0.5 * (B + (B < 0.0 ? -sqrt(disc) : sqrt(disc)));
    float r1 = A != 0.0 ? q / A : HF_HUGE;
    float r2 = q != 0.0 ? C / q : HF_HUGE;
    return vec2(min(r1, r2), max(r1, r2));
}

// The first root >= 0 of A s^2 + B s + C (HF_HUGE if none): e.g. where a bent ray reaches a given depth.
float hf_first_root(float A, float B, float C) {
    vec2 r = hf_roots(A, B, C);
    return r.x >= 0.0 ? r.x : r.y;
}

float hf_run(vec3 o, vec3 d, float k, float t0, float t1, bool reentry, bool two_sided) {
    SEARCH();
    bool inside = reentry || two_sided;    // below the surface, or on an unknown side
    bool outside = true;                   // above, or unknown: false only when known below (two-sided)
    hf_from_below = false;
    ivec2 n = u_hf_cells;
    hf_exhausted = false;
    hf_t_reached = t0;
    bvec2 moving = notEqual(d.xy, vec2(0.0));
    vec2 inv = 1.0 / mix(vec2(1.0), d.xy, moving);
#if defined(HF_CLAMP)
    // clip [t0, t1] to the domain [0, W - 1] x [0, H - 1] (slab test)
    vec2 ta = -o.xy * inv, tb = (vec2(n) - o.xy) * inv;
    vec2 lo = mix(vec2(-HF_HUGE), min(ta, tb), moving), hi = mix(vec2(HF_HUGE), max(ta, tb), moving);
    if (any(hf_and(not(moving), lessThan(o.xy, vec2(0.0)))) || any(hf_and(not(moving), greaterThan(o.xy, vec2(n)))))
        return -1.0;
    t0 = max(t0, max(lo.x, lo.y));
    t1 = min(t1, min(hi.x, hi.y));
#endif
    if (!(t0 <= t1)) return -1.0;
    ivec2 stp = ivec2(d.x >= 0.0 ? 1 : -1, d.y >= 0.0 ? 1 : -1);
    bvec2 back = lessThan(stp, ivec2(0));
    float t = t0;
    int level = min(u_hf_top, HF_START_LEVEL);
    vec2 pos = o.xy + d.xy * t;
    // the tile and the starting cell; a point on a boundary belongs to the side the ray moves to
    ivec2 tile = ivec2(0);
#if !defined(HF_CLAMP)
    tile = ivec2(floor(pos / vec2(n)));
    tile -= ivec2(hf_and(equal(pos, vec2(tile * n)), back));
#endif
    vec2 x = (pos - vec2(tile * n)) / float(1 << level);
    ivec2 idx = ivec2(floor(x));
    idx -= ivec2(hf_and(equal(x, vec2(idx)), back));
    idx = clamp(idx, ivec2(0), ((n - 1) >> level));
    float tv0 = k != 0.0 ? -0.5 * d.z / k : t0;    // where a bent ray's depth turns (its parabola's vertex)
    for (int it = 0; it < HF_MAX_ITER; ++it) {
        STEP();
        int size = 1 << level;
        ivec2 lo_edge = idx * size;
        ivec2 bound = hf_select(lo_edge, min(lo_edge + size, n), not(back));
        vec2 ex = mix(vec2(HF_HUGE), (vec2(tile * n + bound) - o.xy) * inv, moving);
        float te = min(min(ex.x, ex.y), t1);
        vec4 c = FETCH(HF_FETCH(idx, level));
        float zmin = min(min(c.x, c.y), min(c.z, c.w));
        // a cell holding empty cells (pyramid.py level_texels: (min, HUGE, min, max) above level 0, HUGE
        // corners at level 0) has holes; w keeps the max of its non-empty cells above level 0
        bool holey = max(c.y, c.w) >= HF_HUGE;
        float zmax = level > 0 ? c.w : max(max(c.x, c.y), max(c.z, c.w));
        float tv = clamp(tv0, t, te);
        float za = o.z + t * (d.z + k * t), zb = o.z + te * (d.z + k * te), zv = o.z + tv * (d.z + k * tv);
        float dz = d.z + 2.0 * k * t;                                // the ray's depth per unit t at t
        bool above = outside && max(max(za, zb), zv) < zmin;
        bool below = inside && min(min(za, zb), zv) > zmax;
        // One quadratic per visit. Level 0: f(s) = ray depth - patch depth at t + s, the ray at cell-local
        // uv0 (corners c = c00, c01, c10, c11). Above it: where the ray's depth reaches zmin.
        float e = c.x - c.y - c.z + c.w;
        vec2 uv0 = o.xy + d.xy * t - vec2(tile * n + idx);
        float A = k - e * d.x * d.y;
        float B = dz - (c.y - c.x + e * uv0.y) * d.x - (c.z - c.x + e * uv0.x) * d.y;
        float C = za - (c.x + (c.y - c.x) * uv0.x + (c.z - c.x) * uv0.y + e * uv0.x * uv0.y);
        if (level > 0) {
            A = k;
            B = dz;
            C = za - zmin;
        }
        vec2 r = hf_roots(A, B, C);
        float first = r.x >= 0.0 ? r.x : r.y;
        if (!(above || below)) {
            if (level > 0) {
                // descend (Tevs et al. 2008), first to where the ray reaches the cell's min depth
                if (za < zmin && outside) {
                    t = clamp(t + first, t, te);
                    inside = false;
                    outside = true;
                }
                pos = o.xy + d.xy * t;
                level -= 1;
                vec2 mid = vec2(tile * n + (2 * idx + 1) * (1 << level));
                ivec2 upper = ivec2(greaterThan(pos, mid)) | ivec2(hf_and(equal(pos, mid), not(back)));
                idx = min(2 * idx + upper, (n - 1) >> level);
                continue;
            }
            // A hit where f rises to 0 from above (the first root at or after 0), or at the cell's entry if
            // the ray is on or below the surface there and was not inside; if it was inside, f must dip
            // below 0 between the roots (A > 0) and the ray comes back at the second.
            float s = C < 0.0 ? first : (!inside ? 0.0 : ((A > 0.0 && r.x < r.y && r.y > 0.0) ? r.y : HF_HUGE));
            // Two-sided: from below, where f falls from >= 0 below 0, or at the entry if f < 0 there and the
            // ray was known below (pyramid.py patch_hit_sides).
            float sb = C < 0.0 ? (!outside ? 0.0 : ((A < 0.0 && r.x < r.y && r.y > 0.0) ? r.y : HF_HUGE)) : first;
            bool from_below = two_sided && sb < s;
            s = from_below ? sb : s;
            float len = te - t;
            if (s >= 0.0 && s <= len) {
                hf_t_reached = t + s;
                hf_from_below = from_below;
                return t + s;
            }
            inside = (A * len + B) * len + C >= 0.0;
            outside = !(two_sided && inside);
        } else {
            // a skipped cell holding an empty cell (holes) leaves the ray's side unknown where it leaves
            // (no surface joins an empty cell to the next): it must come from the other side of the next
            // surface to hit it, so there is no wall at the border of a surface
            inside = below || holey;
            outside = !two_sided || above || holey;
        }
        // leave the cell by the side(s) the ray exits through; ascend if a parent boundary was crossed
        if (te >= t1) {
            hf_t_reached = t1;
            return -1.0;
        }
        t = te;
        ivec2 next = idx + stp * ivec2(equal(ex, vec2(te)));
        ivec2 count = ((n - 1) >> level) + 1;
        bvec2 out_lo = lessThan(next, ivec2(0)), out_hi = greaterThanEqual(next, count);
#if defined(HF_CLAMP)
        if (any(out_lo) || any(out_hi)) {
            hf_t_reached = t;
            return -1.0;
        }
        bool up = any(notEqual(next >> 1, idx >> 1));
#else
        tile += ivec2(out_hi) - ivec2(out_lo);
        next = hf_select(hf_select(next, count - 1, out_lo), ivec2(0), out_hi);
        bool up = any(notEqual(next >> 1, idx >> 1)) || any(out_lo) || any(out_hi);
#endif
        idx = next;
        if (up && level < u_hf_top) {
            level += 1;
            idx >>= 1;
        }
    }
    hf_exhausted = true;
    hf_t_reached = t;
    return -1.0;
}

float hf_trace_general(vec3 o, vec3 d, float k, float t0, float t1, bool reentry) {
    return hf_run(o, d, k, t0, t1, reentry, false);
}

float hf_trace_two_sided(vec3 o, vec3 d, float t0, float t1) {
    return hf_run(o, d, 0.0, t0, t1, true, true);
}

float hf_trace(vec3 o, vec3 d, float t0, float t1) {
    return hf_trace_general(o, d, 0.0, t0, t1, false);
}

float hf_trace_reentry(vec3 o, vec3 d, float t0, float t1) {
    return hf_trace_general(o, d, 0.0, t0, t1, true);
}
