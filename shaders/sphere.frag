#version 430
// Ray/sphere per fragment in parameter space (the unit sphere), stable quadratic; under MSAA covered per sample
// (impostor_out.glsl: COVER_SAMPLES), so a sphere smaller than a pixel covers the samples it covers.
#include "cost_count.glsl"
#include "quadric.glsl"
#include "impostor_out.glsl"
flat in vec4 v_sphere;
flat in vec3 v_rgb;
noperspective in vec2 v_ndc;

// The ray p0 + s seg (s in [0, 1]: near to far plane) against the sphere: its hit p, normal n facing the viewer and
// mu, or false.
bool hit_sphere(vec3 p0, vec3 seg, out vec3 p, out vec3 n, out float mu) {
    float len = length(seg);
    vec3 d = seg / len;
    float r = v_sphere.w;
    float t = ray_unit_sphere((p0 - v_sphere.xyz) / r, d);   // in radii
    if (t < 0.0 || t * r > len) return false;                // behind the near plane or past the far one
    p = p0 + d * (t * r);
    n = (p - v_sphere.xyz) / r;                               // on the unit sphere, point = normal
    if (dot(n, d) > 0.0) n = -n;                              // inside or cut by the near plane: face the viewer
    mu = t * r / len;
    return true;
}

void main() {
    COUNT_FRAGMENT();
    vec3 p0, seg, p, n;
    float mu;
    pixel_ray(u_inv_view_proj, u_viewport, gl_FragCoord.xy, p0, seg);
    bool hit = hit_sphere(p0, seg, p, n, mu);
    COVER_SAMPLES(hit_sphere, hit, p, n, mu)
    if (!hit) discard;
    write_hit(p, n, mu, v_rgb);
}
