// Ray / depth-map intersection of one enhanced billboard (Vichitvejpaisal2005 §3.3 step 2.2),
// in the billboard's texture space: s = (u, v, depth) in the unit box, depth 0 at the box front, 1 at
// its back. The maps of all billboards are layers of two texture arrays:
//   u_maps  RGBA32F, linear: world unit normal (xyz) and depth (w), with a one-texel border; the border
//           and the empty texels next to covered ones are extrapolated from them (techniques/billboards.py),
//           so bilinear filtering at a map's edge or silhouette follows the surface's slope;
//   u_alpha R8, read per texel: 0 marks an empty texel, which a ray passes through.
// THESIS (Vichitvejpaisal2005 §4.1): 100 fixed steps of sqrt(2)/100 (the ray length sqrt(2), the diagonal of the unit
// depth map) from the box entry; the first sample whose depth is within the hit range e of the map's
// (and whose texel is covered) is the hit. Samples past the box exit end the search (no hit).
// IMPROVED: one step per texel that the ray's projection onto the map crosses (MIN_STEPS to 2 R); a hit where the ray passes from in front of the map to behind it (a sign change),
// refined by bisection and a final secant step, then alpha-tested at the refined point (an empty texel
// lets the ray go on). THESIS tests the sample's own texel; IMPROVED accepts a hit if any texel of its
// bilinear footprint is covered, so neighbouring billboards overlap by up to a texel instead of leaving
// cracks between them.
// Counts (cost_count.glsl): march() is one search; a step is one of its samples (THESIS: up to the first
// past the box exit; IMPROVED: each of the n, and each bisection).
#include "cost_count.glsl"
uniform sampler2DArray u_maps;
uniform sampler2DArray u_alpha;
uniform float u_hit_range;   // THESIS: e (0.01 in Vichitvejpaisal2005 §4.1, 0.02 to fill holes, §3.4)

const int MIN_STEPS = 4;
const int REFINE = 5;        // bisection steps before the secant step

// u_maps has a one-texel border around the R x R map (extrapolated on upload).
vec4 map(vec2 st, int layer) {
    float R = float(textureSize(u_alpha, 0).x);
    return FETCH(texture(u_maps, vec3((st * R + 1.0) / (R + 2.0), float(layer))));
}

float map_depth(vec2 st, int layer) {
    return map(st, layer).w;
}

#if defined(THESIS)
bool covered(vec2 st, int layer) {   // the texel's own coverage
    ivec2 size = textureSize(u_alpha, 0).xy;
    ivec2 texel = clamp(ivec2(floor(st * vec2(size))), ivec2(0), size - 1);
    return FETCH(texelFetch(u_alpha, ivec3(texel, layer), 0)).r > 0.5;
}
#else
bool covered(vec2 st, int layer) {   // any texel of the bilinear footprint covered
    return any(greaterThan(FETCH(textureGather(u_alpha, vec3(st, float(layer)), 0)), vec4(0.5)));
}
#endif

// The ray s(t) = o + d t (texture space) inside the box for t in [t0, t1]: the hit's t, or -1.
#if defined(THESIS)
float march(vec3 o, vec3 d, float t0, float t1, int layer) {
    SEARCH();
    float len = length(d);
    vec3 dir = d / len;
    float reach = (t1 - t0) * len;           // the ray's length inside the box, texture units
    const float STRIDE = sqrt(2.0) / 100.0;
    vec3 s0 = o + d * t0;
    for (int k = 0; k < 100; k++) {
        float x = float(k) * STRIDE;
        STEP();
        if (x > reach) break;                // past the box: transparent (Vichitvejpaisal2005 §3.3 step 2.2)
        vec3 s = s0 + dir * x;
        if (abs(s.z - map_depth(s.xy, layer)) < u_hit_range && covered(s.xy, layer)) return t0 + x / len;
    }
    return -1.0;
}
#else
float march(vec3 o, vec3 d, float t0, float t1, int layer) {
    SEARCH();
    float R = float(textureSize(u_alpha, 0).x);
    vec2 across = d.xy * (t1 - t0) * R;      // texels crossed by the ray's projection onto the map
    int n = int(clamp(ceil(length(across)), float(MIN_STEPS), 2.0 * R));
    float dt = (t1 - t0) / float(n);
    float tp = t0;
    vec3 s = o + d * t0;
    float fp = s.z - map_depth(s.xy, layer);  // < 0: the ray is in front of the map
    for (int k = 1; k <= n; k++) {
        float tc = t0 + dt * float(k);
        STEP();
        s = o + d * tc;
        float fc = s.z - map_depth(s.xy, layer);
        if (fp < 0.0 && fc >= 0.0) {
            float lo = tp, hi = tc, flo = fp, fhi = fc;
            for (int i = 0; i < REFINE; i++) {
                STEP();
                float mid = 0.5 * (lo + hi);
                vec3 m = o + d * mid;
                float fm = m.z - map_depth(m.xy, layer);
                if (fm < 0.0) { lo = mid; flo = fm; } else { hi = mid; fhi = fm; }
            }
            float th = lo + (hi - lo) * flo / (flo - fhi);   // flo < 0 <= fhi: th in [lo, hi]
            if (covered((o + d * th).xy, layer)) return th;
        }
        tp = tc;
        fp = fc;
    }
    return -1.0;
}
#endif
