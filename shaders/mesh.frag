#version 430
#include "shading.glsl"
#include "shadow.glsl"
in vec3 v_pos;
in vec3 v_normal;
in vec3 v_albedo;
uniform vec3 u_eye;   // anchor-relative
out vec4 frag;

void main() {
    vec3 N = safe_normalize(v_normal);
    if (!gl_FrontFacing) N = -N;   // two-sided: the normal faces the viewer (reference: Ng . dir < 0)
    vec3 V = normalize(u_eye - v_pos);
    frag = vec4(shade(v_albedo, N, V, shadow_lit(v_pos, N)), 1.0);
}
