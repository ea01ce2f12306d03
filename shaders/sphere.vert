#version 430
// One screen-aligned quad per sphere (instanced), covering Sigg's projected bounding box. INSTANCED: one quad
// per copy of each sphere (quadric_copies.glsl), the copy's sphere M c, s r: a similarity keeps it a sphere, so
// the box is Sigg's (Sigg et al. 2006; dePoel2009 §3) of the placed quadric, not of the baked one.
#include "quadric.glsl"
in vec2 in_corner;          // per vertex: (+-1, +-1)
#ifdef INSTANCED
#include "quadric_copies.glsl"
#else
in vec4 in_sphere;          // per instance: centre (anchor-relative), radius
in vec3 in_rgb;
#endif
flat out vec4 v_sphere;
flat out vec3 v_rgb;
noperspective out vec2 v_ndc;   // the quad's window position (NDC), read per sample under MSAA

void main() {
#ifdef INSTANCED
    vec4 sphere;
    sphere_row(quadric_index(), sphere, v_rgb);
    mat4 M = copy_model();
    sphere = vec4((M * vec4(sphere.xyz, 1.0)).xyz, copy_scale(M) * sphere.w);
#else
    vec4 sphere = in_sphere;
    v_rgb = in_rgb;
#endif
    float r = sphere.w;
    mat4 T = mat4(r, 0.0, 0.0, 0.0,  0.0, r, 0.0, 0.0,  0.0, 0.0, r, 0.0,  sphere.xyz, 1.0);
    gl_Position = quad_corner(quadric_bounds(T), in_corner);
    v_ndc = gl_Position.xy / gl_Position.w;
    v_sphere = sphere;
}
