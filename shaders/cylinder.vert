#version 430
// One quad per capped cylinder (instanced): the union of its two caps' projected bounding
// boxes (Sigg et al.), each cap a flat disk: a unit sphere squashed by the variance matrix;
// the whole screen where the cylinder crosses the eye plane. INSTANCED: one quad per copy of each cylinder
// (quadric_copies.glsl), the copy's cylinder M p0, M p1, s r, whose caps give the box (dePoel2009 §4).
#include "quadric.glsl"
#include "frame.glsl"
in vec2 in_corner;
#ifdef INSTANCED
#include "quadric_copies.glsl"
#else
in vec3 in_p0;              // per instance: axis end points (anchor-relative) and radius
in vec3 in_p1;
in float in_radius;
in vec3 in_rgb;
#endif
flat out mat4 v_to_param;   // world -> parameter space (unit cylinder, |z| <= 1)
flat out mat3 v_frame;      // columns u, v, w: parameter-space normals -> world
flat out vec3 v_rgb;
noperspective out vec2 v_ndc;   // the quad's window position (NDC), read per sample under MSAA

void main() {
#ifdef INSTANCED
    vec3 p0, p1;
    float r;
    cylinder_row(quadric_index(), p0, p1, r, v_rgb);
    mat4 M = copy_model();
    p0 = (M * vec4(p0, 1.0)).xyz;
    p1 = (M * vec4(p1, 1.0)).xyz;
    r *= copy_scale(M);
#else
    vec3 p0 = in_p0, p1 = in_p1;
    float r = in_radius;
    v_rgb = in_rgb;
#endif
    vec3 axis = p1 - p0;
    float h = 0.5 * length(axis);
    vec3 w = axis / (2.0 * h);
    vec3 u, v;
    onb(w, u, v);
    mat4 T0 = mat4(vec4(u * r, 0.0), vec4(v * r, 0.0), vec4(0.0), vec4(p0, 1.0));
    mat4 T1 = mat4(vec4(u * r, 0.0), vec4(v * r, 0.0), vec4(0.0), vec4(p1, 1.0));
    vec4 box0 = quadric_bounds(T0), box1 = quadric_bounds(T1);
    // The caps' boxes bound the cylinder (the hull of its caps) only with both caps in front of the
    // eye plane. Caps on opposite sides: the side crosses the plane (the eye inside or beside the
    // cylinder), so the whole screen; both behind: nothing (a cap reaching the plane is the screen).
    float s0 = eye_side(T0), s1 = eye_side(T1);
    vec4 box = s0 * s1 < 0.0 ? vec4(-1.0, -1.0, 1.0, 1.0)
             : s0 < 0.0 && s1 < 0.0 ? vec4(2.0)
             : vec4(min(box0.xy, box1.xy), max(box0.zw, box1.zw));
    gl_Position = quad_corner(box, in_corner);
    v_ndc = gl_Position.xy / gl_Position.w;
    vec3 m = 0.5 * (p0 + p1);
    mat3 scale_inv = mat3(1.0 / r, 0.0, 0.0,  0.0, 1.0 / r, 0.0,  0.0, 0.0, 1.0 / h);
    mat3 rot_t = transpose(mat3(u, v, w));
    v_to_param = mat4(scale_inv * rot_t);
    v_to_param[3] = vec4(-(scale_inv * rot_t * m), 1.0);
    v_frame = mat3(u, v, w);
}
