#version 430
// Ray/capped cylinder per fragment in parameter space; side normal (x, y, 0), caps (0, 0, +-1).
#include "cost_count.glsl"
#include "quadric.glsl"
#include "impostor_out.glsl"
flat in mat4 v_to_param;
flat in mat3 v_frame;
flat in vec3 v_rgb;

void main() {
    COUNT_FRAGMENT();
    vec3 p0, seg;
    pixel_ray(u_inv_view_proj, u_viewport, gl_FragCoord.xy, p0, seg);
    vec3 o = (v_to_param * vec4(p0, 1.0)).xyz;
    vec3 d = mat3(v_to_param) * seg;      // the ray parameter is mu directly: s in [0, 1]
    vec3 np;
    float mu = ray_unit_cylinder(o, d, np);
    if (mu < 0.0 || mu > 1.0) discard;
    vec3 p = p0 + mu * seg;
    vec3 n = normalize(v_frame * np);     // inverse transpose of (rotation * scale) = rotation / scale
    if (dot(n, seg) > 0.0) n = -n;
    write_hit(p, n, mu, v_rgb);
}
