#version 430
// One screen-aligned quad per sphere (instanced), covering Sigg's projected bounding box.
#include "quadric.glsl"
in vec2 in_corner;          // per vertex: (+-1, +-1)
in vec4 in_sphere;          // per instance: centre (anchor-relative), radius
in vec3 in_rgb;
flat out vec4 v_sphere;
flat out vec3 v_rgb;

void main() {
    float r = in_sphere.w;
    mat4 T = mat4(r, 0.0, 0.0, 0.0,  0.0, r, 0.0, 0.0,  0.0, 0.0, r, 0.0,  in_sphere.xyz, 1.0);
    gl_Position = quad_corner(quadric_bounds(T), in_corner);
    v_sphere = in_sphere;
    v_rgb = in_rgb;
}
