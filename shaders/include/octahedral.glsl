// Octahedral impostors (Brucks 2018; Unreal's impostor baker, Amplify Impostors): N x N orthographic
// views of the object on the lattice of an octahedral map of directions, in one atlas (the bake:
// vdmbake/kernels/octahedral.py, whose numpy functions these mirror). Anchor-relative world coordinates: the
// anchor is the bounding sphere's centre, every view's centre.
//   u_atlas  RGBA16 unorm, linear: the normal in its view's frame (octahedral code, rg = code / 2 + 0.5),
//            depth along the view (b: 0 at the front of the view's box, 1 at its back), coverage (a).
//            Tile (i, j) holds view (i, j); empty texels next to covered ones carry extrapolated normal
//            and depth (the bake: vdmbake/kernels/octahedral.py to_part), so filtering at a silhouette follows the surface.
// HEMI: the views cover the upper hemisphere of u_basis (hemi-octahedral map), else the full sphere.
// ALBEDO_ATLAS: u_albedo_atlas, laid out as u_atlas, holds the surface's linear albedo (an asset with its own
// colours; the covered neighbours' mean around silhouettes), read at each view's hit and blended as the normal.
// MIPMAPS (the scene's render.mipmaps): u_albedo_atlas holds colour x coverage and coverage with a short mip
// chain (passes/boards.py covered_colours; octahedral.py MAX_LEVEL), read at the level of the hit coordinate's
// derivatives, taken where every pixel of the quad runs them; rgb / a is the mean colour of what the footprint
// covers. u_atlas is searched (depth) and its normals are decoded per texel: it stays at level 0.
// Counts (cost_count.glsl): each view searched is a search; MARCH's steps are its samples and bisections,
// VIRTUAL's one parallax step is one.
#include "cost_count.glsl"
uniform sampler2D u_atlas;
#if defined(ALBEDO_ATLAS)
uniform sampler2D u_albedo_atlas;   // RGB16F, linear filtering (MIPMAPS: RGBA16F, premultiplied, mip-mapped)
#endif
uniform int u_views;          // N: views per side
uniform mat3 u_basis;         // world -> map frame (z up)
uniform float u_capture;      // half side of every view's square (world units)
uniform float u_steps_per_texel;

const int MIN_STEPS = 2;
const int REFINE = 5;         // bisection steps before the secant step (MARCH)
const float CLIFF_FACTOR = 2.0; // the map changing between two steps faster than CLIFF_FACTOR times the slope
const float CLIFF_SLOPE = 2.0;  // its normal gives, plus CLIFF_SLOPE (depth per unit of u, v), is a discontinuity

float sgn(float x) { return x >= 0.0 ? 1.0 : -1.0; }
vec2 sgn(vec2 v) { return vec2(sgn(v.x), sgn(v.y)); }

// The full octahedral map: unit square [-1, 1]^2 <-> sphere (vdmbake.kernels.octahedral.encode/decode).
vec2 oct_encode(vec3 d) {
    vec2 p = d.xy / max(abs(d.x) + abs(d.y) + abs(d.z), 1e-30);
    return d.z < 0.0 ? (1.0 - abs(p.yx)) * sgn(p) : p;
}

vec3 oct_decode(vec2 g) {
    float z = 1.0 - abs(g.x) - abs(g.y);
    vec2 xy = z < 0.0 ? (1.0 - abs(g.yx)) * sgn(g) : g;
    return normalize(vec3(xy, z));
}

// The map of view directions: full, or the hemi-octahedral map of z >= 0 (below the horizon: onto it).
vec2 map_encode(vec3 d) {
#if defined(HEMI)
    d.z = max(d.z, 0.0);
    vec2 p = d.xy / max(abs(d.x) + abs(d.y) + d.z, 1e-30);
    return vec2(p.x + p.y, p.x - p.y);
#else
    return oct_encode(d);
#endif
}

vec3 map_decode(vec2 g) {
#if defined(HEMI)
    g = vec2(g.x + g.y, g.x - g.y) * 0.5;
#endif
    return oct_decode(g);
}

// The lattice triangle that direction e (towards the viewer, world) falls in: its three views
// (i, j) and barycentric weights (vdmbake.kernels.octahedral.nearest_views). Cells are cut along the
// diagonal parallel to the map's creases in their quadrant.
void nearest_views(vec3 e, out ivec2 view[3], out vec3 w) {
    float m = float(u_views - 1);
    vec2 x = (map_encode(u_basis * e) + 1.0) * 0.5 * m;
    vec2 c = clamp(floor(x), 0.0, m - 1.0);
    vec2 f = clamp(x - c, 0.0, 1.0);
    vec2 mid = (c + 0.5) / m * 2.0 - 1.0;
#if defined(HEMI)
    bool main_diag = mid.x * mid.y >= 0.0;
#else
    bool main_diag = mid.x * mid.y < 0.0;
#endif
    ivec2 o = ivec2(c);
    if (main_diag) {
        if (f.x >= f.y) { view[0] = o; view[1] = o + ivec2(1, 0); view[2] = o + ivec2(1, 1); w = vec3(1.0 - f.x, f.x - f.y, f.y); }
        else            { view[0] = o; view[1] = o + ivec2(0, 1); view[2] = o + ivec2(1, 1); w = vec3(1.0 - f.y, f.y - f.x, f.x); }
    } else {
        if (f.x + f.y <= 1.0) { view[0] = o; view[1] = o + ivec2(1, 0); view[2] = o + ivec2(0, 1); w = vec3(1.0 - f.x - f.y, f.x, f.y); }
        else { view[0] = o + ivec2(1, 0); view[1] = o + ivec2(0, 1); view[2] = o + ivec2(1, 1); w = vec3(1.0 - f.y, 1.0 - f.x, f.x + f.y - 1.0); }
    }
}

// View (i, j)'s direction towards the viewer e and axes u, v (u x v = e): Duff et al. 2017's frame in
// the map's frame, its branch chosen on the lattice integers (vdmbake.kernels.octahedral.view_frames), then to world.
void view_frame(ivec2 view, out vec3 e, out vec3 u, out vec3 v) {
    e = map_decode(vec2(view) / float(u_views - 1) * 2.0 - 1.0);
#if defined(HEMI)
    float s = 1.0;
#else
    ivec2 k = abs(2 * view - (u_views - 1));
    float s = k.x + k.y <= u_views - 1 ? 1.0 : -1.0;
#endif
    float a = -1.0 / (s + e.z);
    float b = e.x * e.y * a;
    u = vec3(1.0 + s * e.x * e.x * a, s * b, -s * e.x) * u_basis;   // map frame -> world
    v = vec3(b, s + e.y * e.y * a, -e.y) * u_basis;
    e = e * u_basis;
}

// One texel lookup in view (i, j) at s.xy in [0, 1]^2 of its square.
vec4 atlas(vec2 st, ivec2 view) {
    return FETCH(texture(u_atlas, (vec2(view) + st) / float(u_views)));
}

// The world normal of a lookup: the view-frame code decoded, then taken to world.
vec3 atlas_normal(vec4 texel, vec3 e, vec3 u, vec3 v) {
    vec3 n = oct_decode(texel.rg * 2.0 - 1.0);
    return n.x * u + n.y * v + n.z * e;
}

// The segment [t0, t1] (ray parameter, clipped to [0, 1]) of p0 + seg t inside the sphere of radius r
// around the anchor; false if the ray misses it. Stable form (Ray Tracing Gems ch. 7).
bool sphere_chord(vec3 p0, vec3 seg, float r, out float t0, out float t1) {
    float len = length(seg);
    vec3 d = seg / len;
    vec3 f = p0 / r;
    float b = -dot(f, d);
    vec3 l = f + b * d;
    float disc = 1.0 - dot(l, l);
    if (disc < 0.0) return false;
    float q = b + sgn(b) * sqrt(disc);
    float c = dot(f, f) - 1.0;
    float ra = q != 0.0 ? c / q : 0.0;
    t0 = max(min(ra, q) * r / len, 0.0);
    t1 = min(max(ra, q) * r / len, 1.0);
    return t0 < t1;
}

// What one view says about the ray p0 + seg t, t in [t0, t1] (in the view's unit box s = (u, v, depth):
// s(t) = o + d t). A view's depth map bounds a solid: everything behind its surface where it is covered,
// which holds the object. So the first event along the ray is, in that view, one of:
//   HIT      the ray passes from in front of the surface to behind it where it is covered: a true
//            intersection (to the map's resolution), and the first one, since the ray was outside the solid;
//   UNKNOWN  the ray gets behind the surface where it is covered without passing through it (through the
//            solid's side wall, or it starts inside it): this view never saw that part of the ray;
//   MISS     neither: the ray never enters the solid, so it misses the object.
// Returns the HIT's t (else -1), the event's kind, and the lookup at the HIT.
const int MISS = 0, HIT = 1, UNKNOWN = 2;
#if defined(MARCH)
// A ray / height-field search: one step per texel that the ray's projection crosses (times
// u_steps_per_texel; the nearest views look almost along the ray, so the projection is short), then for
// a HIT bisection and a secant step.
float view_hit(vec3 o, vec3 d, float t0, float t1, ivec2 view, out int kind, out vec4 texel) {
    SEARCH();
    float R = float(textureSize(u_atlas, 0).x) / float(u_views);
    float across = length(d.xy) * (t1 - t0) * R;
    int n = int(clamp(ceil(across * u_steps_per_texel), float(MIN_STEPS), 4.0 * R));
    float dt = (t1 - t0) / float(n);
    vec3 s = o + d * t0;
    texel = atlas(s.xy, view);
    float fp = s.z - texel.b;            // >= 0: the ray is behind the map
    float ap = texel.a, bp = texel.b;
    kind = fp >= 0.0 && ap >= 0.5 ? UNKNOWN : MISS;
    float tp = t0, tc = t0, fc = fp;
    float step_xy = max(length(d.xy) * dt, 1e-6);
    for (int k = 1; k <= n && kind == MISS; k++) {
        STEP();
        tc = t0 + dt * float(k);
        s = o + d * tc;
        texel = atlas(s.xy, view);
        fc = s.z - texel.b;
        if (fc >= 0.0 && max(ap, texel.a) >= 0.5) {
            // Passing behind the map where it changes far faster than its normal's slope explains is
            // passing the filtered sheet over a depth discontinuity (an edge in front of a farther
            // surface): not a surface; the search goes on.
            vec3 nv = oct_decode(texel.rg * 2.0 - 1.0);
            bool cliff = abs(texel.b - bp) / step_xy > CLIFF_FACTOR * length(nv.xy) / max(nv.z, 1e-3) + CLIFF_SLOPE;
            kind = fp < 0.0 ? (cliff ? MISS : HIT) : (texel.a >= 0.5 ? UNKNOWN : MISS);
        }
        if (kind == MISS) { tp = tc; fp = fc; ap = texel.a; bp = texel.b; }
    }
    if (kind == MISS) return -1.0;
    if (kind == UNKNOWN) return tc;
    float lo = tp, hi = tc, flo = fp, fhi = fc;
    for (int i = 0; i < REFINE; i++) {
        STEP();
        float mid = 0.5 * (lo + hi);
        vec3 m = o + d * mid;
        float fm = m.z - atlas(m.xy, view).b;
        if (fm < 0.0) { lo = mid; flo = fm; } else { hi = mid; fhi = fm; }
    }
    float th = lo + (hi - lo) * flo / (flo - fhi);   // flo < 0 <= fhi: th in [lo, hi]
    texel = atlas((o + d * th).xy, view);
    if (texel.a < 0.5) kind = MISS;
    return th;
}
#else
// VIRTUAL (Amplify Impostors' single parallax step): the ray meets the view's middle plane (depth 0.5);
// the depth read there is taken for the surface's, the ray moves to that depth and is read again.
// A HIT where that lookup is covered (no UNKNOWN: one step cannot tell).
float view_hit(vec3 o, vec3 d, float t0, float t1, ivec2 view, out int kind, out vec4 texel) {
    SEARCH();
    STEP();
    float t = clamp((0.5 - o.z) / d.z, t0, t1);   // d.z > 0: the view looks along the ray, within a cell
    texel = atlas((o + d * t).xy, view);
    t = clamp((texel.b - o.z) / d.z, t0, t1);
    texel = atlas((o + d * t).xy, view);
    kind = texel.a >= 0.5 ? HIT : MISS;
    return kind == HIT ? t : -1.0;
}
#endif

// The pixel's ray p0 + seg t against the impostor: the three views nearest its direction, each asked in
// its own frame (view_hit). The views that saw the ray (HIT or MISS) vote by weight: covered if the HITs
// weigh at least half of them, the hit and normal then blended over the HITs. If no view saw it (all
// UNKNOWN: e.g. a ray into a hole whose rim hides its inside from all three), it counts as a miss.
// Returns false for no hit; t: the hit, n: the world normal (unit), albedo: the blended albedo of the
// HITs (ALBEDO_ATLAS; else 1).
bool impostor_hit(vec3 p0, vec3 seg, float radius, out float t, out vec3 n, out vec3 albedo) {
    float t0, t1;
    t = -1.0;
    n = vec3(0.0);
    albedo = vec3(1.0);
    if (!sphere_chord(p0, seg, radius, t0, t1)) return false;
    ivec2 view[3];
    vec3 w;
    nearest_views(-normalize(seg), view, w);
    float inv = 0.5 / u_capture;
    float seen = 0.0, hit = 0.0, tsum = 0.0;
    vec3 nhit = vec3(0.0), chit = vec3(0.0);
    for (int k = 0; k < 3; k++) {
        vec3 e, u, v;
        view_frame(view[k], e, u, v);
        vec3 o = vec3(dot(p0, u) * inv + 0.5, dot(p0, v) * inv + 0.5, (u_capture - dot(p0, e)) * inv);
        vec3 d = vec3(dot(seg, u), dot(seg, v), -dot(seg, e)) * inv;
        int kind;
        vec4 texel;
        float th = view_hit(o, d, t0, t1, view[k], kind, texel);
        vec3 nk = w[k] * atlas_normal(texel, e, u, v);
        if (kind != UNKNOWN) seen += w[k];
        if (kind == HIT) { hit += w[k]; tsum += w[k] * th; nhit += nk; }
#if defined(ALBEDO_ATLAS) && defined(MIPMAPS)
        vec2 at = (vec2(view[k]) + (o + d * th).xy) / float(u_views), gx = dFdx(at), gy = dFdy(at);
        if (kind == HIT) {
            vec4 c = FETCH(textureGrad(u_albedo_atlas, at, gx, gy));
            chit += w[k] * c.rgb / max(c.a, 1e-4);
        }
#elif defined(ALBEDO_ATLAS)
        if (kind == HIT) chit += w[k] * FETCH(texture(u_albedo_atlas, (vec2(view[k]) + (o + d * th).xy) / float(u_views))).rgb;
#endif
    }
    if (seen == 0.0 || hit < 0.5 * seen) return false;
    t = tsum / hit;
#if defined(ALBEDO_ATLAS)
    albedo = chit / hit;
#endif
    float len = length(nhit);
    n = len > 1e-20 ? nhit / len : -normalize(seg);
    return true;
}
