#version 430
// View-dependent displacement mapping, the per-pixel algorithm of Wang et al. 2003, sec. 3.2:
// silhouette determination (MVM), real texture coordinate, shadow determination, shading.
// d_VDM and theta_MVM are reconstructed from the SVD (sec. 3.3): W (x, y, phi) . E (theta, c).
#include "shading.glsl"
#include "shadow.glsl"
#include "mesostructure.glsl"
const float PI = 3.14159265358979;
uniform vec3 u_eye;                 // anchor-relative
uniform vec3 u_albedo;
uniform sampler2DArray u_W;         // layer g * n_phi + phi: eigenfunction weights 4g..4g+3, repeat, mip-mapped
uniform sampler2DArray u_E_vdm;     // layer g: (theta, c) -> E_vdm of eigenfunctions 4g..4g+3, clamped
uniform sampler2D u_E_mvm;          // (c, g) -> E_mvm of eigenfunctions 4g..4g+3, clamped
uniform int u_k;                    // eigenfunctions used
uniform int u_groups;               // groups of 4 stored (rows of u_E_mvm)
uniform int u_n_phi;
uniform vec3 u_curv_axis;           // c -> texel: (first sample, samples per unit c, sample count)
uniform float u_shadow_eps;         // texture units
out vec4 frag;

float curvature_coord(float c) {    // clamped to the table's range by the texture's edge clamp
    return (0.5 + (c - u_curv_axis.x) * u_curv_axis.y) / u_curv_axis.z;
}

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
        vec4 w = mix(textureGrad(u_W, vec3(T, g * u_n_phi + i0), dx, dy),
                     textureGrad(u_W, vec3(T, g * u_n_phi + i1), dx, dy), f) * keep;
        r.x += dot(w, texture(u_E_vdm, vec3(tc, g)));
        r.y += dot(w, texture(u_E_mvm, vec2(tc.y, (g + 0.5) / float(u_groups))));
    }
    return r;
}

void main() {
    vec3 N = safe_normalize(v_normal);
    Frame F = surface_frame(N);
    vec2 T = v_uv * u_tiling;
    vec2 dx = dFdx(T), dy = dFdy(T);
    vec3 Vw = normalize(u_eye - v_pos);
    vec3 V = to_texture(F, Vw);
    if (V.z <= 0.0) discard;                          // the base surface seen from behind
    float thetaV = acos(min(V.z, 1.0));
    float phiV = atan(V.y, V.x);
    vec2 dm = vdm_lookup(T, thetaV, phiV, texture_curvature(F, V), dx, dy);
    // 1. Silhouette determination: beyond the maximal view angle the ray meets no mesostructure.
    if (thetaV > dm.y) discard;
    // 2. Real texture coordinate, T' = T - d V_xy (extended d = l / sin(theta) on curved surfaces, Appendix).
    float d = max(dm.x, 0.0);
    vec2 T1 = T - d * V.xy;
    float h = depth_at(T1, dx, dy);
    vec3 P = v_pos - Vw * (d * world_length(F, V));
    // 3. Shadow determination: from P' toward L, the ray leaves the reference surface at
    //    T'' = T' + h tan(theta_L) L_xy; P' is lit if the VDM along L from T'' reaches it, h / cos(theta_L).
    vec3 L = to_texture(F, u_light_dir);
    float lit = L.z > 0.0 ? 1.0 : 0.0;
    if (L.z > 0.0) {
        float thetaL = acos(min(L.z, 1.0));
        vec2 T2 = T1 + h * L.xy / L.z;
        vec2 dl = vdm_lookup(T2, thetaL, atan(L.y, L.x), texture_curvature(F, L), dx, dy);
        if (thetaL <= dl.y && dl.x < h / L.z - u_shadow_eps) lit = 0.0;
    }
    // 4. Shading: the mesostructure normal at T'; macro shadows from the base mesh's shadow map.
    vec3 n = mesostructure_normal(F, T1);
    lit *= shadow_lit(v_pos, N);
    gl_FragDepth = window_depth(P);
    frag = vec4(shade(u_albedo, n, Vw, lit), 1.0);
}
