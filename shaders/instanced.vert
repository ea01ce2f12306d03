#version 430
// Tessellated peers of the impostors: one unit mesh drawn once per quadric (instancing).
// SPHERE: a unit icosphere placed at centre c with radius r. Otherwise a unit capped prism
// (radius 1, z in [-1, 1]) stretched between the cylinder's end points; its normals need no
// inverse transpose (side normals have z = 0, cap normals only z).
#include "frame.glsl"
in vec3 in_pos;
in vec3 in_normal;
#ifdef SPHERE
in vec4 in_sphere;          // per instance: centre (anchor-relative), radius
#else
in vec3 in_p0;
in vec3 in_p1;
in float in_radius;
#endif
in vec3 in_rgb;
uniform mat4 u_mvp;
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_albedo;

void main() {
#ifdef SPHERE
    v_pos = in_sphere.xyz + in_sphere.w * in_pos;
    v_normal = in_normal;
#else
    vec3 axis = in_p1 - in_p0;
    vec3 w = normalize(axis);
    vec3 u, v;
    onb(w, u, v);
    v_pos = 0.5 * (in_p0 + in_p1) + mat3(u * in_radius, v * in_radius, 0.5 * axis) * in_pos;
    v_normal = mat3(u, v, w) * in_normal;
#endif
    v_albedo = in_rgb;
    gl_Position = u_mvp * vec4(v_pos, 1.0);
}
