#version 430
// Rasterised triangle meshes (techniques `mesh` and `coarse`). Positions are relative to
// the object's anchor (its bounding-box centre) so far-off objects keep float32 precision.
// VERTEX_COLOR: the asset's albedo per vertex (linear RGB), interpolated over each triangle as the
// reference interpolates it at the hit; ALBEDO_MAP: the asset's texture coordinates, its albedo map
// read per fragment (times the vertex colour, if any); otherwise the material's albedo. INSTANCED: one copy per
// instance, placed by its matrix.
in vec3 in_pos;
in vec3 in_normal;
#ifdef VERTEX_COLOR
in vec3 in_color;
#elif !defined(ALBEDO_MAP)
uniform vec3 u_albedo;
#endif
#ifdef ALBEDO_MAP
in vec2 in_uv;
out vec2 v_uv;
#endif
#ifdef INSTANCED
in mat4 in_model;     // this copy's similarity, anchor-relative (vdmbake.common.instances): normals only turn
#endif
uniform mat4 u_mvp;   // clip space from anchor-relative coordinates
#ifdef PUSHED
// Copies of a coarse mesh that fills holes (Vichitvejpaisal2005 §3.4; vdmrender/passes/boards.py pushed): each is
// depth-tested as if u_behind times its scale farther along its own ray than it is, from the eye (u_away.w = 1,
// xyz the eye) or along the light (u_away.w = 0, xyz the direction away from it); shaded where it is.
uniform vec4 u_away;
uniform float u_behind;
#endif
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_albedo;

void main() {
#ifdef INSTANCED
    v_pos = (in_model * vec4(in_pos, 1.0)).xyz;
    v_normal = mat3(in_model) * in_normal;   // a uniform scale: the fragment stage normalises
#else
    v_pos = in_pos;
    v_normal = in_normal;
#endif
#ifdef VERTEX_COLOR
    v_albedo = in_color;
#elif defined(ALBEDO_MAP)
    v_albedo = vec3(1.0);
#else
    v_albedo = u_albedo;
#endif
#ifdef ALBEDO_MAP
    v_uv = in_uv;
#endif
#ifdef PUSHED
    vec3 away = u_away.w > 0.5 ? normalize(v_pos - u_away.xyz) : u_away.xyz;
    gl_Position = u_mvp * vec4(v_pos + away * (u_behind * length(in_model[0].xyz)), 1.0);
#else
    gl_Position = u_mvp * vec4(v_pos, 1.0);
#endif
}
