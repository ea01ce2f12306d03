#version 430
// Parallax occlusion mapping (Tatarchuk 2006), the VDM peer: per pixel, a linear search of
// u_steps equal depth layers along the view ray through the height field, refined by one secant
// step, then the same search from the hit toward the light for self-shadows. The surface is
// taken as locally flat: no curvature, no silhouettes. Counts (cost_count.glsl): the view and the shadow
// search are a search each, their layers the steps (the secant step is closed-form, not one).
#include "cost_count.glsl"
#include "shading.glsl"
#include "shadow.glsl"
#include "mesostructure.glsl"
uniform vec3 u_eye;
uniform int u_steps;
out vec4 frag;

void main() {
    COUNT_FRAGMENT();
    vec3 N = safe_normalize(v_normal);
    Frame F = surface_frame(N);
    vec2 T = v_uv * u_tiling;
    vec2 dx = dFdx(T), dy = dFdy(T);
    vec3 Vw = normalize(u_eye - v_pos);
    vec3 V = to_texture(F, Vw);
    if (V.z <= 0.0) discard;
    // Linear search: layer i is at depth i * step; the ray reaches it after i * step / V.z.
    float step = u_depth / float(u_steps);
    vec2 dT = -V.xy / max(V.z, 1e-3) * step;
    float ray = 0.0, prev_gap = -depth_at(T, dx, dy);          // gap = ray depth - surface depth
    vec2 Ti = T;
    float gap = prev_gap;
    SEARCH();
    for (int i = 1; i <= u_steps && gap < 0.0; ++i) {
        STEP();
        prev_gap = gap;
        Ti += dT;
        ray += step;
        gap = ray - depth_at(Ti, dx, dy);
    }
    // Secant step between the last two layers (the gap changes sign between them).
    float s = gap > 0.0 ? gap / max(gap - prev_gap, 1e-12) : 0.0;
    vec2 T1 = Ti - s * dT;
    float depth = ray - s * step;
    vec3 P = v_pos - Vw * (depth / max(V.z, 1e-3) * world_length(F, V));
    // Self-shadow: march from the hit up toward the light until the reference surface.
    vec3 L = to_texture(F, u_light_dir);
    float lit = L.z > 0.0 ? 1.0 : 0.0;
    if (L.z > 0.0) {
        vec2 dL = L.xy / max(L.z, 1e-3) * step;
        vec2 Tl = T1;
        SEARCH();
        for (float r = depth - step; r > 0.0 && lit > 0.0; r -= step) {
            STEP();
            Tl += dL;
            if (depth_at(Tl, dx, dy) < r - 0.5 * step) lit = 0.0;
        }
    }
    vec3 n = mesostructure_normal(F, T1);
    lit *= shadow_lit(v_pos, N);
    gl_FragDepth = window_depth(u_mvp, P);
    frag = vec4(shade(tile_albedo(T1), n, Vw, lit), 1.0);
}
