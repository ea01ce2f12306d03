#version 430
// Ray/sphere per fragment in parameter space (the unit sphere), stable quadratic.
#include "cost_count.glsl"
#include "quadric.glsl"
#include "impostor_out.glsl"
flat in vec4 v_sphere;
flat in vec3 v_rgb;

void main() {
    COUNT_FRAGMENT();
    vec3 p0, seg;
    pixel_ray(u_inv_view_proj, u_viewport, gl_FragCoord.xy, p0, seg);
    float len = length(seg);
    vec3 d = seg / len;
    float r = v_sphere.w;
    float t = ray_unit_sphere((p0 - v_sphere.xyz) / r, d);   // in radii
    if (t < 0.0 || t * r > len) discard;                     // behind the near plane or past the far one
    vec3 p = p0 + d * (t * r);
    vec3 n = (p - v_sphere.xyz) / r;                          // on the unit sphere, point = normal
    if (dot(n, d) > 0.0) n = -n;                              // inside or cut by the near plane: face the viewer
    write_hit(p, n, t * r / len, v_rgb);
}
