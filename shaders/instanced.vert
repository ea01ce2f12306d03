#version 430
// Tessellated peers of the impostors: one unit mesh drawn once per quadric (instancing).
// SPHERE: a unit icosphere placed at centre c with radius r. Otherwise a unit capped prism
// (radius 1, z in [-1, 1]) stretched between the cylinder's end points; its normals need no
// inverse transpose (side normals have z = 0, cap normals only z). INSTANCED: once per copy of each
// quadric (quadric_copies.glsl), the placed mesh moved by the copy's similarity M, its normals turned by it
// (a uniform scale: mesh.frag normalises).
#include "frame.glsl"
in vec3 in_pos;
in vec3 in_normal;
#ifdef INSTANCED
#include "quadric_copies.glsl"
#elif defined(SPHERE)
in vec4 in_sphere;          // per instance: centre (anchor-relative), radius
in vec3 in_rgb;
#else
in vec3 in_p0;
in vec3 in_p1;
in float in_radius;
in vec3 in_rgb;
#endif
uniform mat4 u_mvp;
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_albedo;

void main() {
#ifdef SPHERE
#ifdef INSTANCED
    vec4 sphere;
    sphere_row(quadric_index(), sphere, v_albedo);
#else
    vec4 sphere = in_sphere;
    v_albedo = in_rgb;
#endif
    v_pos = sphere.xyz + sphere.w * in_pos;
    v_normal = in_normal;
#else
#ifdef INSTANCED
    vec3 p0, p1;
    float radius;
    cylinder_row(quadric_index(), p0, p1, radius, v_albedo);
#else
    vec3 p0 = in_p0, p1 = in_p1;
    float radius = in_radius;
    v_albedo = in_rgb;
#endif
    vec3 axis = p1 - p0;
    vec3 w = normalize(axis);
    vec3 u, v;
    onb(w, u, v);
    v_pos = 0.5 * (p0 + p1) + mat3(u * radius, v * radius, 0.5 * axis) * in_pos;
    v_normal = mat3(u, v, w) * in_normal;
#endif
#ifdef INSTANCED
    mat4 M = copy_model();
    v_pos = (M * vec4(v_pos, 1.0)).xyz;
    v_normal = mat3(M) * v_normal;
#endif
    gl_Position = u_mvp * vec4(v_pos, 1.0);
}
