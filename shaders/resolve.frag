#version 430
// Supersampling's resolve (vdmrender/measuring/antialias.py): each pixel the box-filtered mean of its K x K texels of
// the frame rendered K times larger, in linear colour (a mean of sRGB-encoded values would darken edges).
// Colour is premultiplied by coverage (cleared to 0, covered texels have alpha 1), so the mean is what a
// viewer sees over the background: rgb + (1 - alpha) background (vdmrender.common.images.encode).
#include "cost_count.glsl"
uniform sampler2D u_frame;   // the supersampled frame, RGBA32F, nearest
uniform int u_k;             // K
out vec4 frag;

void main() {
    COUNT_FRAGMENT();
    ivec2 base = ivec2(gl_FragCoord.xy) * u_k;
    vec4 sum = vec4(0.0);
    for (int j = 0; j < u_k; ++j)
        for (int i = 0; i < u_k; ++i)
            sum += FETCH(texelFetch(u_frame, base + ivec2(i, j), 0));
    frag = sum / float(u_k * u_k);
}
