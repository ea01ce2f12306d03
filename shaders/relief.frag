#version 430
// Relief mapping by exact hierarchical tracing, the peer of POM and VDM: per pixel, the view ray in the
// mesostructure's texture space (Wang2003 §3.2: the base mesh's interpolated frame) traced through the
// min/max pyramid of the depth field to its exact first hit with the bilinear surface
// (heightfield_trace.glsl), then the hit's texture coordinate for the normal map, a shadow ray from the
// hit toward the light by the same tracer, the true depth of the hit, and the shared shading. The normal
// map is read at its finest level at the exact hit, as the traced reference's interpolated vertex normals
// are (a mip-mapped lookup blurs the normals at a texel or more per pixel: docs/mesostructure.md).
// Curvature (beyond POM; Wang2003 §3.1 and Appendix, curved relief mapping of Oliveira & Policarpo 2005):
// the base surface near the pixel is the quadric of its interpolated principal curvatures, so a ray's depth
// below it, at tangential distance s along texture direction e, is its depth below the tangent plane minus
// c(e) s^2 / 2 (texture_curvature). Both rays are traced bent by that term: on a convex surface a view
// ray can leave the surface again without a hit (a silhouette: the pixel is discarded). The hit's shading
// normal is turned from the pixel's frame to the frame where the hit lies (turned()).
// FLAT: straight rays and the pixel's frame (the surface taken as locally flat, as POM does).
// u_iterations caps the cell visits of each ray; a view ray stopped by the cap takes the point it had
// reached (above the surface), a stopped shadow ray counts as lit. Counts (cost_count.glsl): the view and the
// shadow ray are a search each, their cell visits the steps (heightfield_trace.glsl).
#include "cost_count.glsl"
#include "shading.glsl"
#include "shadow.glsl"
#include "mesostructure.glsl"
uniform int u_iterations;
#define HF_MAX_ITER u_iterations
#define HF_START_LEVEL 0
#include "heightfield_trace.glsl"
uniform vec3 u_eye;
out vec4 frag;

// A world vector v of the frame at the pixel, carried to the frame at tile offset dT along the base surface:
// the surface's normal there is N + k1 (x.d1) d1 + k2 (x.d2) d2 to first order (the shape operator applied to
// the tangential displacement x = J dT), and v turns with it (Rodrigues' rotation taking N to it).
vec3 turned(vec3 v, vec3 N, Frame F, vec2 dT) {
    vec3 x = F.Ju * dT.x + F.Jv * dT.y;
    vec3 Nh = normalize(N + v_curv.x * dot(x, F.d1) * F.d1 + v_curv.y * dot(x, F.d2) * F.d2);
    vec3 a = cross(N, Nh);
    float s = length(a), c = dot(N, Nh);
    if (s < 1e-12) return v;
    a /= s;
    return v * c + cross(a, v) * s + a * dot(a, v) * (1.0 - c);
}

void main() {
    COUNT_FRAGMENT();
    vec3 N = safe_normalize(v_normal);
    Frame F = surface_frame(N);
    vec2 T = v_uv * u_tiling;
    vec3 Vw = normalize(u_eye - v_pos);
    vec3 V = to_texture(F, Vw);
    vec3 L = to_texture(F, u_light_dir);
    if (V.z <= 0.0) discard;
#if defined(FLAT)
    float kV = 0.0, kL = 0.0;
#else
    float kV = -0.5 * texture_curvature(F, V) * dot(V.xy, V.xy);
    float kL = -0.5 * texture_curvature(F, L) * dot(L.xy, L.xy);
#endif
    // The view ray in sample coordinates (x = T N - 0.5, from the tile the pixel is in) and depth in texture
    // units; t is its length in texture units. Its depth is V.z t + kV t^2; it is traced until it reaches
    // the deepest point (u_depth) or, on a convex surface, comes back out (depth 0).
    float n = float(u_hf_cells.x);
    vec2 T0 = floor(T);
    vec3 o = vec3((T - T0) * n - 0.5, 0.0);
    vec3 d = vec3(-V.xy * n, V.z);
    float t_floor = hf_first_root(kV, V.z, -u_depth), t_out = kV < 0.0 ? -V.z / kV : HF_HUGE;
    float t = hf_trace_general(o, d, kV, 0.0, min(t_floor, t_out), false);
    if (t < 0.0 && !hf_exhausted) {
        if (t_out < t_floor) discard;           // the ray left the surface: a silhouette
        t = t_floor;                            // (or missed the deepest point by rounding)
    }
    if (t < 0.0) t = hf_t_reached;
    vec3 h = vec3(o.xy + d.xy * t, t * (V.z + kV * t));
    // Self-shadow: from the hit toward the light, its depth h.z - L.z t + kL t^2, until it reaches the
    // reference surface (depth 0) or, bending back on a concave surface, the deepest point. The ray starts
    // on the surface: it must leave it before a hit counts (reentry).
    float tl = hf_first_root(kL, -L.z, h.z);
    if (tl >= HF_HUGE) tl = hf_first_root(kL, -L.z, h.z - u_depth);
    float ts = hf_trace_general(h, vec3(L.xy * n, -L.z), kL, 0.0, L.z > 0.0 ? tl : 0.0, true);
    float lit = (L.z > 0.0 && ts < 0.0) ? 1.0 : 0.0;
    vec2 T1 = T0 + (h.xy + 0.5) / n;
    vec3 P = v_pos - Vw * (t * world_length(F, V));
    vec3 nw = mesostructure_normal(F, T1);
#if !defined(FLAT)
    nw = turned(nw, N, F, T1 - T);          // the normal map's frame is the one at the hit
#endif
    lit *= shadow_lit(v_pos, N);
    gl_FragDepth = window_depth(u_mvp, P);
    frag = vec4(shade(tile_albedo(T1), nw, Vw, lit), 1.0);
}
