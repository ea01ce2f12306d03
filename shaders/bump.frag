#version 430
// Bump mapping (Blinn 1978), the simplest VDM peer: the base surface shaded with the
// mesostructure's normals; no parallax, occlusion, self-shadows or silhouettes.
#include "cost_count.glsl"
#include "shading.glsl"
#include "shadow.glsl"
#include "mesostructure.glsl"
uniform vec3 u_eye;
out vec4 frag;

void main() {
    COUNT_FRAGMENT();
    vec3 N = safe_normalize(v_normal);
    if (!gl_FrontFacing) N = -N;
    Frame F = surface_frame(N);
    vec2 T = v_uv * u_tiling;
    vec3 n = mesostructure_normal(F, T);
    vec3 Vw = normalize(u_eye - v_pos);
    frag = vec4(shade(tile_albedo(T), n, Vw, shadow_lit(v_pos, N)), 1.0);
}
