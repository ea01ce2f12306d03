#version 430
// View-dependent displacement mapping, the per-pixel algorithm of Wang2003 §3.2:
// silhouette determination (MVM), real texture coordinate, shadow determination, shading.
// d_VDM and theta_MVM are reconstructed from the SVD (Wang2003 §3.3): W (x, y, phi) . E (theta, c).
// Compiled per variant: K eigenfunctions (the group loop unrolls); REFINE > 0 finishes the view ray's
// hit and decides the self-shadow on the height field itself (beyond the paper: refine_view,
// shadow_march); ORIGINAL_LOOKUP: the first implementation's lookup (float weights mip-mapped, phi
// always interpolated, a uniform loop bound), kept to measure against; MIPMAPS (the scene's render.mipmaps):
// the weights read at the mip level of the pixel's footprint (Wang2003 §4, vdm_lookup).
// Counts (cost_count.glsl): the view ray and the light ray are a search each (a lookup stands for its ray);
// the steps are REFINE's height-field samples (refine_view's REFINE + 1, shadow_march's REFINE).
#include "cost_count.glsl"
#include "shading.glsl"
#include "shadow.glsl"
#include "mesostructure.glsl"
#include "curved_ray.glsl"
const float PI = 3.14159265358979;
uniform vec3 u_eye;                 // anchor-relative
uniform sampler2DArray u_E_vdm;     // layer g: (theta, c) -> E_vdm of eigenfunctions 4g..4g+3, clamped
uniform sampler2D u_E_mvm;          // (c, g) -> E_mvm of eigenfunctions 4g..4g+3, clamped
uniform int u_groups;               // rows of u_E_mvm
uniform int u_n_phi;
uniform vec3 u_curv_axis;           // c -> texel: (first sample, samples per unit c, sample count)
uniform vec2 u_cos_range;           // cos theta of the last and the first theta sample (bin centres)
uniform float u_shadow_eps;         // texture units
uniform float u_window;             // half-width of the refinement window, texture units of depth
out vec4 frag;

float curvature_coord(float c) {    // clamped to the table's range by the texture's edge clamp
    return (0.5 + (c - u_curv_axis.x) * u_curv_axis.y) / u_curv_axis.z;
}

#ifdef ORIGINAL_LOOKUP
uniform sampler2DArray u_W;         // layer g * n_phi + phi: eigenfunction weights 4g..4g+3, repeat, mip-mapped
uniform int u_k;                    // eigenfunctions used

// (d_VDM, theta_MVM) at tile coordinate T for the view (theta, phi) at curvature c. phi is
// interpolated by hand between array layers (wrapping); x, y, theta and c by the samplers.
vec2 vdm_lookup(vec2 T, float theta, float phi, float c, vec2 dx, vec2 dy) {
    float p = phi * (float(u_n_phi) / (2.0 * PI)) - 0.5;
    float p0 = floor(p), f = p - p0;
    int i0 = int(mod(p0, float(u_n_phi)));
    int i1 = (i0 + 1) % u_n_phi;
    vec2 tc = vec2(theta / (0.5 * PI), curvature_coord(c));
    int groups = (u_k + 3) / 4;
    vec2 r = vec2(0.0);
    for (int g = 0; g < groups; ++g) {
        vec4 keep = vec4(lessThan(ivec4(4 * g) + ivec4(0, 1, 2, 3), ivec4(u_k)));
        vec4 w = mix(FETCH(textureGrad(u_W, vec3(T, g * u_n_phi + i0), dx, dy)),
                     FETCH(textureGrad(u_W, vec3(T, g * u_n_phi + i1), dx, dy)), f) * keep;
        r.x += dot(w, FETCH(texture(u_E_vdm, vec3(tc, g))));
        r.y += dot(w, FETCH(texture(u_E_mvm, vec2(tc.y, (g + 0.5) / float(u_groups)))));
    }
    return r;
}
#else
const int GROUPS = (K + 3) / 4;     // eigenfunctions 4g..4g+3 in one RGBA texel; unused ones have E = 0
uniform sampler2DArray u_W;         // layer g * n_phi + phi: weights of eigenfunctions 4g..4g+3, repeat (MIPMAPS:
                                    // mip-mapped per layer)
uniform vec4 u_W_scale[GROUPS];     // weight = stored * scale + offset (8-bit storage; 1 and 0 for floats)
uniform vec4 u_W_offset[GROUPS];

// (d_VDM, theta_MVM) at tile coordinate T for the view (theta, phi) at curvature c. The samplers
// interpolate x, y, theta and c; phi is interpolated by hand between array layers (wrapping), or the
// nearest phi is taken where REFINE finishes the hit anyway. x and y at the tables' finest level (against
// a reference of one ray per pixel centre, filtering a displacement blurs the hits) or, under MIPMAPS, at
// the level of the pixel's footprint (dx, dy: Wang2003 §4, "VDM as a texture map is easily anti-aliased by
// mip-mapping"). The mean of W over a footprint is the mean of the rows of A = W E^T it stands for (§3.3:
// the reconstruction is linear), so a level of W's mip chain is the SVD of the footprint's mean table,
// truncated at the same k; 8-bit codes average as the weights do (weight = code * scale + offset is
// affine). The eigenfunctions (theta, c) are not mip-mapped: a pixel's footprint spans texture space, while
// its rays' directions and curvature barely change across it.
#ifdef MIPMAPS
#define W_AT(T, layer, dx, dy) textureGrad(u_W, vec3(T, layer), dx, dy)
#else
#define W_AT(T, layer, dx, dy) texture(u_W, vec3(T, layer))
#endif
vec2 vdm_lookup(vec2 T, float theta, float phi, float c, vec2 dx, vec2 dy) {
    float p = phi * (float(u_n_phi) / (2.0 * PI)) - 0.5;
    float p0 = floor(p), f = p - p0;
    int i0 = int(mod(p0, float(u_n_phi)));
    int i1 = (i0 + 1) % u_n_phi;
    vec2 tc = vec2(theta / (0.5 * PI), curvature_coord(c));
    vec2 r = vec2(0.0);
    for (int g = 0; g < GROUPS; ++g) {
#if REFINE > 0
        vec4 w = FETCH(W_AT(T, g * u_n_phi + (f < 0.5 ? i0 : i1), dx, dy));
#else
        vec4 w = mix(FETCH(W_AT(T, g * u_n_phi + i0, dx, dy)), FETCH(W_AT(T, g * u_n_phi + i1, dx, dy)), f);
#endif
        w = w * u_W_scale[g] + u_W_offset[g];
        r.x += dot(w, FETCH(texture(u_E_vdm, vec3(tc, g))));
        r.y += dot(w, FETCH(texture(u_E_mvm, vec2(tc.y, (g + 0.5) / float(u_groups)))));
    }
    return r;
}
#endif

#if REFINE > 0
// How far below the height field the view ray is at distance t (> 0 inside the mesostructure).
float gap(vec2 T, vec3 V, float c, float t) {
    STEP();
    vec2 p = curved_ray(t, 0.0, length(V.xy), -V.z, c);
    return p.y - depth_at_lod0(T - p.x * V.xy);
}

// Beyond the paper, the view ray: the lookup's hit t0 (distance, texture units) is only as good as
// the tables' sampling; the height field itself decides. The window [t0 - w, t0 + w] (w = u_window
// of depth, along the ray) is sampled at REFINE + 1 points for the first sign change of the gap,
// which a secant step finishes (uniform samples find the first of several crossings, where a
// bracketing false-position search converges on any). Returns (t, found); found = 0: no sign
// change, the lookup's t0 stands.
vec2 refine_view(vec2 T, vec3 V, float c, float t0) {
    float w = u_window / max(V.z, 0.05);
    float ta = max(t0 - w, 0.0), step = (t0 + w - ta) / float(REFINE);
    float prev = gap(T, V, c, ta);
    vec2 r = prev >= 0.0 ? vec2(ta, 1.0) : vec2(t0, 0.0);
    for (int i = 1; i <= REFINE; ++i) {
        float ti = ta + float(i) * step, g = gap(T, V, c, ti);
        if (r.y == 0.0 && g >= 0.0) r = vec2(ti - step * g / max(g - prev, 1e-12), 1.0);
        prev = g;
    }
    return r;
}

// Beyond the paper, the light ray: from P' (depth h at T1) along L (unit, texture space) to where it
// leaves the surface after u, REFINE samples at the centres of equal steps, from u_shadow_eps on (so
// that P's own surface does not shadow it); P' is lit unless one lies inside the mesostructure. The
// second VDM lookup is not made: confirming its occluder on the height field would still miss the
// occluders it misses, and it costs as many fetches as the whole march.
float shadow_march(vec2 T1, float h, vec3 L, float c, float u) {
    float st = length(L.xy), step = (u - u_shadow_eps) / float(REFINE);
    float lit = 1.0;
    for (int i = 0; i < REFINE; ++i) {
        STEP();
        vec2 p = curved_ray(u_shadow_eps + (float(i) + 0.5) * step, h, st, L.z, c);
        if (p.y > depth_at_lod0(T1 + p.x * L.xy)) lit = 0.0;
    }
    return step > 0.0 ? lit : 1.0;
}
#endif

void main() {
    COUNT_FRAGMENT();
    vec3 N = safe_normalize(v_normal);
    Frame F = surface_frame(N);
    vec2 T = v_uv * u_tiling;
    vec2 dx = dFdx(T), dy = dFdy(T);
    vec3 Vw = normalize(u_eye - v_pos);
    vec3 V = to_texture(F, Vw);
    if (V.z <= 0.0) discard;                          // the base surface seen from behind
    float stV = length(V.xy);
    float cV = texture_curvature(F, V);
    SEARCH();
    vec2 dm = vdm_lookup(T, acos(min(V.z, 1.0)), atan(V.y, V.x), cV, dx, dy);
    // 1. Silhouette determination: beyond the maximal view angle the ray meets no mesostructure.
    bool miss = acos(min(V.z, 1.0)) > dm.y;
    // 2. Real texture coordinate T' = T - d V_xy (Wang2003 Appendix's extended d on curved surfaces), at
    //    distance t along the view ray, which cannot pass the mesostructure's floor.
    float t = clamp(ray_distance(max(dm.x, 0.0), V.z, cV), 0.0, depth_distance(u_depth, stV, V.z, cV));
#if REFINE > 0
    vec2 rv = refine_view(T, V, cV, t);
    if (miss && rv.y == 0.0) discard;                 // unless the height field shows a hit the MVM missed
    t = rv.x;
#else
    if (miss) discard;
#endif
    vec2 T1 = T - curved_ray(t, 0.0, stV, -V.z, cV).x * V.xy;
#ifdef MIPMAPS
    float h = depth_at(T1, dx, dy);                   // Wang2003 §3.2: h, at the footprint's level as the tables
#else
    float h = depth_at_lod0(T1);                      // Wang2003 §3.2: h as given by the height field
#endif
    vec3 P = v_pos - Vw * (t * world_length(F, V));
    // 3. Shadow determination, along the light ray bent with c_L as the tables are (the paper ignores
    //    curvature here).
    vec3 L = to_texture(F, u_light_dir);
    float lit = L.z > 0.0 ? 1.0 : 0.0;
    if (L.z > 0.0) {
        SEARCH();
        float cL = texture_curvature(F, L);
#if REFINE > 0
        lit = shadow_march(T1, h, L, cL, exit_distance(h, length(L.xy), L.z, cL));
#else
        // The paper's test (Wang2003 §3.2, Fig. 5): from T'' (T' + h tan(theta_L) L on a plane), where the
        // light ray leaves the surface, the VDM along L reaches P' (d_L = h / cos(theta_L)) unless
        // something is in the way. The light's polar angle is clamped to the sampled ones: beyond the
        // last, the lookup would hold a steeper ray's hit, short of P' (false shadows under a low
        // light). At T'' the normal has turned by c_L times the arc.
        float ctS = clamp(L.z, u_cos_range.x, u_cos_range.y), stS = sqrt(1.0 - ctS * ctS);
        vec3 Ls = vec3(L.xy * (stS / max(length(L.xy), 1e-12)), ctS);
        float u = exit_distance(h, stS, ctS, cL);
        float sigma = curved_ray(u, h, stS, ctS, cL).x;
        float thetaL = max(acos(ctS) - cL * sigma * stS, 0.0);
        vec2 dl = vdm_lookup(T1 + sigma * Ls.xy, thetaL, atan(L.y, L.x), cL, dx, dy);
        if (thetaL <= dl.y && ray_distance(max(dl.x, 0.0), cos(thetaL), cL) < u - u_shadow_eps) lit = 0.0;
#endif
    }
    // 4. Shading: the mesostructure normal at T' (the finest level, as the reference shades); macro
    //    shadows from the base mesh's shadow map.
    vec3 n = mesostructure_normal(F, T1);
    lit *= shadow_lit(v_pos, N);
    gl_FragDepth = window_depth(u_mvp, P);
    frag = vec4(shade(tile_albedo(T1), n, Vw, lit), 1.0);
}
