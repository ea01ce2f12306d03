#version 430
// Octahedral impostors, per pixel (Brucks 2018): the pixel's ray clipped to the bounding sphere, the three
// atlas views nearest its direction each intersected with it in their own frame (octahedral.glsl: MARCH,
// a ray / depth-map search, or VIRTUAL, Amplify's single parallax step), blended; the blended hit's exact
// depth, and its blended normal shaded with the shared model and the shadow map. SHADOW: the light's pass
// (the light's direction picks its own views); only the depth is written. ALBEDO_ATLAS: the colour is the
// blended albedo of the views (octahedral.glsl), else the material's. INSTANCED: the copy's matrix takes
// the ray into the impostor's own frame.
#include "cost_count.glsl"
#include "quadric.glsl"
#include "octahedral.glsl"
#include "copy.glsl"
#if !defined(SHADOW)
#include "shading.glsl"
#include "shadow.glsl"
uniform vec3 u_eye;            // anchor-relative
#if !defined(ALBEDO_ATLAS)
uniform vec3 u_albedo;
#endif
uniform float u_atlas_texels;  // extra shadow offset along the normal, in atlas texels
out vec4 frag;
#endif
uniform float u_radius;
#ifdef INSTANCED
flat in mat4 v_model;
#endif

void main() {
    COUNT_FRAGMENT();
    vec3 p0, seg;
    pixel_ray(u_inv_view_proj, u_viewport, gl_FragCoord.xy, p0, seg);
    float t;
    vec3 n, albedo;
#ifdef INSTANCED
    vec3 q0 = p0, qseg = seg;   // the ray in the copy's own frame (copy.glsl)
    into_copy(v_model, q0, qseg);
    if (!impostor_hit(q0, qseg, u_radius, t, n, albedo)) discard;
    n = normalize(mat3(v_model) * n);
#else
    if (!impostor_hit(p0, seg, u_radius, t, n, albedo)) discard;
#endif
    vec3 p = p0 + seg * t;
    gl_FragDepth = window_depth(u_view_proj, p);
#if !defined(SHADOW)
    vec3 V = normalize(u_eye - p);
    // The surface is known to about an atlas texel, and the light's views differ from the eye's:
    // the shadow lookup moves that far along the normal, on top of the shadow map's own offset.
    float texel = 2.0 * u_capture / (float(textureSize(u_atlas, 0).x) / float(u_views));
#ifdef INSTANCED
    texel *= length(v_model[0].xyz);   // a copy's texels are as large as its scale makes them
#endif
    float lit = shadow_lit(p + n * (u_atlas_texels * texel), n);
#if !defined(ALBEDO_ATLAS)
    albedo = u_albedo;
#endif
    frag = vec4(shade(albedo, n, V, lit), 1.0);
#endif
}
