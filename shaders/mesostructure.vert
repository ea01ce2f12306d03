#version 430
// Base meshes of mesostructure techniques (vdm, pom, bump): the per-vertex surface frame of
// Wang2003 §3.2 (texture tangents, principal curvatures and direction) is interpolated per pixel.
in vec3 in_pos;       // anchor-relative
in vec3 in_normal;
in vec2 in_uv;
in vec3 in_dpdu;      // world dP/du, dP/dv over the whole UV square
in vec3 in_dpdv;
in vec2 in_curv;      // k1 along d1, k2 along normal x d1
in vec3 in_d1;
uniform mat4 u_mvp;
out vec3 v_pos;
out vec3 v_normal;
out vec2 v_uv;
out vec3 v_dpdu;
out vec3 v_dpdv;
out vec2 v_curv;
out vec3 v_d1;

void main() {
    v_pos = in_pos;
    v_normal = in_normal;
    v_uv = in_uv;
    v_dpdu = in_dpdu;
    v_dpdv = in_dpdv;
    v_curv = in_curv;
    v_d1 = in_d1;
    gl_Position = u_mvp * vec4(in_pos, 1.0);
}
