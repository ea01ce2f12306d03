#version 430
// Rasterised triangle meshes (techniques `mesh` and `coarse`). Positions are relative to
// the object's anchor (its bounding-box centre) so far-off objects keep float32 precision.
in vec3 in_pos;
in vec3 in_normal;
uniform mat4 u_mvp;   // clip space from anchor-relative coordinates
uniform vec3 u_albedo;
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_albedo;

void main() {
    v_pos = in_pos;
    v_normal = in_normal;
    v_albedo = u_albedo;
    gl_Position = u_mvp * vec4(in_pos, 1.0);
}
