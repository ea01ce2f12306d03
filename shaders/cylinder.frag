#version 430
// Ray/capped cylinder per fragment in parameter space; side normal (x, y, 0), caps (0, 0, +-1). Under MSAA the
// coverage is which samples' rays hit (impostor_out.glsl: COVER_SAMPLES).
#include "cost_count.glsl"
#include "quadric.glsl"
#include "impostor_out.glsl"
flat in mat4 v_to_param;
flat in mat3 v_frame;
flat in vec3 v_rgb;
noperspective in vec2 v_ndc;

// The ray p0 + mu seg (mu in [0, 1]: near to far plane) against the capped cylinder: its hit p, normal n facing the
// viewer and mu, or false.
bool hit_cylinder(vec3 p0, vec3 seg, out vec3 p, out vec3 n, out float mu) {
    vec3 o = (v_to_param * vec4(p0, 1.0)).xyz;
    vec3 d = mat3(v_to_param) * seg;      // the ray parameter is mu directly: s in [0, 1]
    vec3 np;
    mu = ray_unit_cylinder(o, d, np);
    if (mu < 0.0 || mu > 1.0) return false;
    p = p0 + mu * seg;
    n = normalize(v_frame * np);          // inverse transpose of (rotation * scale) = rotation / scale
    if (dot(n, seg) > 0.0) n = -n;
    return true;
}

void main() {
    COUNT_FRAGMENT();
    vec3 p0, seg, p, n;
    float mu;
    pixel_ray(u_inv_view_proj, u_viewport, gl_FragCoord.xy, p0, seg);
    bool hit = hit_cylinder(p0, seg, p, n, mu);
    COVER_SAMPLES(hit_cylinder, hit, p, n, mu)
    if (!hit) discard;
    write_hit(p, n, mu, v_rgb);
}
