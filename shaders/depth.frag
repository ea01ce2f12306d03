#version 430
// Depth-only pass (shadow maps): the depth attachment is all that is written.
#include "cost_count.glsl"

void main() {
    COUNT_FRAGMENT();
}
