#version 430
// Depth-only pass (shadow maps): positions relative to the object's anchor.
in vec3 in_pos;
uniform mat4 u_mvp;

void main() {
    gl_Position = u_mvp * vec4(in_pos, 1.0);
}
