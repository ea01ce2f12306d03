#version 430
// One screen-aligned quad per object over the projection of its bounding sphere (Sigg's bounds,
// quadric.glsl; the whole screen when the eye is inside the sphere), at depth 0 so that it is never
// clipped; the fragment stage intersects the pixel's ray with what the object holds and writes the hit's
// depth (octahedral impostors; instanced hierarchical billboards). Anchor-relative world: the anchor is the
// bounding sphere's centre. INSTANCED: one quad per copy, over the copy's sphere.
#include "quadric.glsl"
in vec2 in_corner;        // (+-1, +-1)
uniform float u_radius;   // the bounding sphere's radius, grown by a little (the renderer's)

#ifdef INSTANCED
in mat4 in_model;         // this copy's similarity, anchor-relative (vdmbake.common.instances)
flat out mat4 v_model;
#endif

void main() {
    mat4 T = mat4(u_radius, 0.0, 0.0, 0.0,  0.0, u_radius, 0.0, 0.0,  0.0, 0.0, u_radius, 0.0,  0.0, 0.0, 0.0, 1.0);
#ifdef INSTANCED
    T = in_model * T;     // a similarity keeps the sphere a sphere
    v_model = in_model;
#endif
    gl_Position = quad_corner(quadric_bounds(T), in_corner);
}
