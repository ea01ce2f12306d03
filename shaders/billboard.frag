#version 430
// Enhanced billboards, per pixel (Vichitvejpaisal2005 §3.3 step 2): the pixel's ray clipped to
// the billboard's box (slab test in its u, v, w frame) and to the near and far planes, the depth map
// marched from entry to exit (billboard.glsl: THESIS or IMPROVED), then at the hit the normal map, the
// shared shading model with the shadow map, and the hit's exact depth, so billboards and the coarse
// mesh depth-test together (Vichitvejpaisal2005 §3.4). SHADOW: the light's pass; only the depth is written.
// ALBEDO_MAPS: the colour at the hit is the billboard's colour map (Vichitvejpaisal2005 §3.3 step 2.3), else the material's.
// A camera inside the box needs nothing special: the ray starts on the near plane (as the reference's).
#include "cost_count.glsl"
#include "billboard.glsl"
#include "camera.glsl"
#if !defined(SHADOW)
#include "shading.glsl"
#include "shadow.glsl"
uniform vec3 u_eye;       // anchor-relative
#if defined(ALBEDO_MAPS)
#include "board_albedo.glsl"
#else
uniform vec3 u_albedo;
#endif
uniform float u_tolerance;     // extra shadow offset, in box depths
uniform float u_board_texels;  // extra shadow offset, in map texels
out vec4 frag;
#endif
uniform mat4 u_view_proj;       // clip space from anchor-relative world (the true near and far planes)
uniform mat4 u_inv_view_proj;
uniform vec2 u_viewport;        // pixels
flat in vec3 v_origin;
flat in vec3 v_iu;
flat in vec3 v_iv;
flat in vec3 v_iw;
flat in int v_layer;
flat in mat3 v_turn;

void main() {
    COUNT_FRAGMENT();
    // The pixel's ray from the near plane (t = 0) to the far plane (t = 1), anchor-relative world.
    vec3 p0, seg;
    pixel_ray(u_inv_view_proj, u_viewport, gl_FragCoord.xy, p0, seg);
    // The same ray in texture space, and its segment inside the unit box.
    vec3 q = p0 - v_origin;
    vec3 o = vec3(dot(q, v_iu), dot(q, v_iv), dot(q, v_iw));
    vec3 d = vec3(dot(seg, v_iu), dot(seg, v_iv), dot(seg, v_iw));
    vec3 inv = 1.0 / mix(d, vec3(1e-30), lessThan(abs(d), vec3(1e-30)));   // parallel to a slab: +-huge
    vec3 ta = -o * inv, tb = (1.0 - o) * inv;
    vec3 lo = min(ta, tb), hi = max(ta, tb);
    float t0 = max(max(lo.x, lo.y), max(lo.z, 0.0));
    float t1 = min(min(hi.x, hi.y), min(hi.z, 1.0));
    if (t0 >= t1) discard;
    float t = march(o, d, t0, t1, v_layer);
    if (t < 0.0) discard;
    vec3 p = p0 + seg * t;
    gl_FragDepth = window_depth(u_view_proj, p);
#if !defined(SHADOW)
    vec3 st = o + d * t;
    vec3 N = safe_normalize(v_turn * map(st.xy, v_layer).xyz);
#if defined(THESIS)
    // The thesis's hit test (|ray depth - map depth| < e) takes either side of the surface. A ray that
    // enters the box behind the surface and meets it from below (f = ray depth - map depth falling there,
    // the map's slope from central differences half a texel apart) sees its back: shade that side, as the
    // mesh and the reference do (an open surface seen from behind). A ray that entered in front and meets
    // it from below went through one of the march's holes (Vichitvejpaisal2005 §3.4): left as the thesis shades it.
    vec3 s0 = o + d * t0;
    float h = 0.5 / float(textureSize(u_alpha, 0).x);
    vec2 grad = vec2(map_depth(st.xy + vec2(h, 0.0), v_layer) - map_depth(st.xy - vec2(h, 0.0), v_layer),
                     map_depth(st.xy + vec2(0.0, h), v_layer) - map_depth(st.xy - vec2(0.0, h), v_layer)) / (2.0 * h);
    if (s0.z >= map_depth(s0.xy, v_layer) && d.z - dot(grad, d.xy) < 0.0) N = -N;
#endif
    // The shadow lookup moves along the normal by the billboard's own uncertainty, on top of the shadow
    // map's normal offset: u_board_texels of its map texels (the surface is known to about a texel, and
    // where two billboards overlap the light may see the other one), plus for THESIS the hit range
    // (its hits lie up to e box depths off the surface, in the frame and in the shadow map: u_tolerance = 2 e).
    float R = float(textureSize(u_alpha, 0).x);
    float texel = max(1.0 / length(v_iu), 1.0 / length(v_iv)) / R;
    float lit = shadow_lit(p + N * (u_board_texels * texel + u_tolerance / length(v_iw)), N);
#if defined(ALBEDO_MAPS)
    vec3 albedo = board_albedo(st.xy, v_layer);
#else
    vec3 albedo = u_albedo;
#endif
    frag = vec4(shade(albedo, N, normalize(u_eye - p), lit), 1.0);
#endif
}
