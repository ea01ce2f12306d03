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

// Under MSAA the quad covers the whole box, so the pixel centre's ray alone would cover the pixel wholly or not at
// all: each sample's ray (through the quad's NDC v_ndc, interpolated at the sample) decides its sample instead
// (gl_SampleMask), and where the centre's ray (HIT_FN's hit, p, n, mu) missed, the first sample that hits is
// shaded. HIT_FN(p0, seg, p, n, mu): the ray's hit with the fragment's quadric, or false.
#define COVER_SAMPLES(HIT_FN, hit, p, n, mu)                                                 \
    if (gl_NumSamples > 1) {                                                                \
        int mask = 0;                                                                       \
        for (int s = 0; s < gl_NumSamples; ++s) {                                           \
            vec3 q0, qseg, qp, qn;                                                          \
            float qmu;                                                                      \
            ndc_ray(u_inv_view_proj, interpolateAtSample(v_ndc, s), q0, qseg);              \
            if (HIT_FN(q0, qseg, qp, qn, qmu)) {                                            \
                mask |= 1 << s;                                                             \
                if (!hit) { p = qp; n = qn; mu = qmu; hit = true; }                         \
            }                                                                               \
        }                                                                                   \
        gl_SampleMask[0] = mask;                                                            \
    }
