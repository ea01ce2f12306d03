#version 430
#include "cost_count.glsl"
#include "shading.glsl"
#include "shadow.glsl"
#ifdef ALBEDO_MAP
#include "albedo.glsl"
in vec2 v_uv;
#endif
in vec3 v_pos;
in vec3 v_normal;
in vec3 v_albedo;
uniform vec3 u_eye;   // anchor-relative
out vec4 frag;

void main() {
    COUNT_FRAGMENT();
    vec3 N = safe_normalize(v_normal);
    if (!gl_FrontFacing) N = -N;   // two-sided: the normal faces the viewer (reference: Ng . dir < 0)
    vec3 V = normalize(u_eye - v_pos);
    vec3 albedo = v_albedo;
#ifdef ALBEDO_MAP
    albedo *= albedo_map(v_uv);
#endif
    frag = vec4(shade(albedo, N, V, shadow_lit(v_pos, N)), 1.0);
}
