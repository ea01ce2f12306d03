// What an impostor fragment writes, by pass: the shaded colour (DIRECT), the G-buffer of the
// deferred path (GBUFFER: normal and mu, albedo and coverage), or only its depth (shadow map).
#if defined(DIRECT)
#include "shading.glsl"
#include "shadow.glsl"
uniform vec3 u_eye;
out vec4 frag;
#elif defined(GBUFFER)
layout(location = 0) out vec4 g_normal_mu;
layout(location = 1) out vec4 g_albedo;
#endif

void write_hit(vec3 p, vec3 n, float mu, vec3 albedo) {
    gl_FragDepth = window_depth(u_view_proj, p);
#if defined(DIRECT)
    frag = vec4(shade(albedo, n, normalize(u_eye - p), shadow_lit(p, n)), 1.0);
#elif defined(GBUFFER)
    g_normal_mu = vec4(n, mu);
    g_albedo = vec4(albedo, 1.0);
#endif
}
