#version 430
// The billboards' occupancy pre-pass (techniques/billboards_hier.py): the boxes of one billboard's occupied
// pyramid cells at OCCUPANCY_LEVEL (cell x depth interval, anchor-relative world), front faces only.
in vec3 in_pos;
uniform mat4 u_view_proj;   // clip space from anchor-relative world
uniform vec3 u_p0;          // the ray parameter t of a point q: dot(q - u_p0, u_axis) (see the fragment stage)
uniform vec3 u_axis;
out float v_t;

void main() {
    gl_Position = u_view_proj * vec4(in_pos, 1.0);
    v_t = dot(in_pos - u_p0, u_axis);
}
