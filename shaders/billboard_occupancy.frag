#version 430
// The billboards' occupancy pre-pass: the ray parameter t (billboard_hier.frag: 0 on the near plane, 1 on
// the far plane) where the pixel's ray enters the nearest occupied box, kept by MIN blending. t along a
// camera ray is linear in view depth, so the vertex stage computes it as an affine function of position.
#include "cost_count.glsl"
in float v_t;
out vec4 frag;

void main() {
    COUNT_FRAGMENT();
    frag = vec4(v_t, 0.0, 0.0, 1.0);
}
