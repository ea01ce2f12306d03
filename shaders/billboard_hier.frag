#version 430
// Enhanced billboards by the hierarchical march (Vichitvejpaisal2005 §3.3 step 2, beyond the thesis):
// one fragment per pixel (a screen triangle, scissored to the billboards' screen box) traces the pixel's
// ray through every billboard it meets, each clipped to its box (slab test), to where it enters the
// billboard's occupied pyramid cells (OCCUPANCY pre-pass) and to the nearest hit so far, so a billboard
// behind a hit costs little and each pixel is shaded once. Per billboard,
// heightfield_trace.glsl descends the min/max pyramid of its depth map (vdmbake/kernels/billboard_maps.py: the
// bilinear surface of the bordered map, empty cells marked so that rays pass them) and returns the exact
// first crossing of the surface (hf_trace_two_sided: either way, so an open surface seen from behind or a
// closed model seen from inside is drawn too, shaded two-sided; the ray's side is unknown where it enters
// the box and beside empty cells, so it must come from one side of a surface to hit it: no walls).
//   COARSE_DEPTH  the coarse mesh's depth pre-pass (pushed back as the frame's coarse pass is) bounds every
//                 ray: what lies behind it would lose the depth test against the coarse mesh anyway;
//   SHADOW        the light's pass (orthographic), depth only;
//   ALBEDO_MAPS   the colour at the hit is the billboard's colour map (Vichitvejpaisal2005 §3.3 step 2.3), else the material's;
//   INSTANCED     one fragment per pixel of each copy's quad (bounding_quad.vert): the ray is taken into the
//                 copy's frame (copy.glsl), where the arrays below hold; depth and shading in the world.
// BOARDS (defined by the caller) is the number of billboards, MAX_ITER the tracer's cap per billboard.
// Counts (cost_count.glsl): each billboard traced is a search, each of its cell visits a step.
#include "cost_count.glsl"
#define HF_CLAMP
#define HF_MAX_ITER MAX_ITER
#define HF_FETCH(cell, level) texelFetch(u_pyramids, ivec3((cell) + u_level_origin[level], g_layer), 0)
uniform sampler2DArray u_pyramids;    // pyramid.texture_atlas of each billboard, one layer each
uniform ivec2 u_level_origin[16];     // where each level starts in the atlas
int g_layer = 0;
#include "heightfield_trace.glsl"
#include "camera.glsl"
#if defined(INSTANCED)
#include "copy.glsl"
flat in mat4 v_model;
#endif

uniform sampler2DArray u_maps;        // RGBA32F bordered maps: normal (xyz), depth (w); linear filtering
uniform mat4 u_to_box[BOARDS];        // anchor-relative world -> the billboard's unit box (u, v, depth)
uniform int u_layer[BOARDS];          // its layer in u_maps and u_pyramids
uniform float u_texel[BOARDS];        // world size of one map texel (the larger of u and v)
const float BACK_MARGIN = 2.0;        // map texels
uniform mat4 u_view_proj;             // clip space from anchor-relative world (the true near and far planes)
uniform mat4 u_inv_view_proj;
uniform vec2 u_viewport;
#if defined(COARSE_DEPTH)
uniform sampler2D u_coarse_depth;
#endif
#if defined(OCCUPANCY)
uniform sampler2D u_occupancy;        // the occupancy pre-pass: per billboard a tile of the viewport's size
uniform ivec2 u_tile[BOARDS];         // each billboard's tile
uniform int u_occ_off[BOARDS];        // 1: no tile (its rays start at its box)
#endif
#if !defined(SHADOW)
#include "shading.glsl"
#include "shadow.glsl"
uniform vec3 u_eye;                   // anchor-relative
#if defined(ALBEDO_MAPS)
#include "board_albedo.glsl"
#else
uniform vec3 u_albedo;
#endif
uniform float u_board_texels;         // extra shadow offset, in map texels (as billboard.frag)
out vec4 frag;
#endif

void main() {
    COUNT_FRAGMENT();
    // The pixel's ray from the near plane (t = 0) to the far plane (t = 1), anchor-relative world.
    vec3 p0, seg;
    pixel_ray(u_inv_view_proj, u_viewport, gl_FragCoord.xy, p0, seg);
    float best = 1.0;
#if defined(COARSE_DEPTH)
    float zc = FETCH(texelFetch(u_coarse_depth, ivec2(gl_FragCoord.xy), 0)).r;
    vec2 ndc = gl_FragCoord.xy / u_viewport * 2.0 - 1.0;
    vec4 q = u_inv_view_proj * vec4(ndc, zc * 2.0 - 1.0, 1.0);
    best = zc < 1.0 ? dot(q.xyz / q.w - p0, seg) / dot(seg, seg) : 1.0;
#endif
#if defined(INSTANCED)
    vec3 w0 = p0, wseg = seg;            // the world ray; p0, seg from here on in the copy's frame
    into_copy(v_model, p0, seg);
    float scale = length(v_model[0].xyz);
    mat3 turn = mat3(v_model) / scale;
#endif
    float R = float(u_hf_cells.x - 1);   // (R + 1)^2 cells over the bordered R x R map
    // Per billboard, the ray's segment in its box from where it enters the first occupied box of its
    // pyramid (the occupancy pre-pass; nothing of the billboard lies before) to the exit. The billboards
    // whose segment starts before the bound are traced cheapest first (the fewest map texels crossed: a
    // billboard seen edge-on costs the most), so that an early hit clips the costly ones. On llvmpipe a
    // loop's trip count, not a branch, is what skips work: the loop runs over the needed billboards only.
    float t0[BOARDS], t1[BOARDS], cost[BOARDS];
    int needed = 0;
    for (int k = 0; k < BOARDS; k++) {
        vec3 o = (u_to_box[k] * vec4(p0, 1.0)).xyz;
        vec3 d = mat3(u_to_box[k]) * seg;
        vec3 inv = 1.0 / mix(d, vec3(1e-30), lessThan(abs(d), vec3(1e-30)));   // parallel to a slab: +-huge
        vec3 ta = -o * inv, tb = (1.0 - o) * inv;
        vec3 lo = min(ta, tb), hi = max(ta, tb);
#if defined(OCCUPANCY)
        float occ = u_occ_off[k] != 0 ? 0.0 : FETCH(texelFetch(u_occupancy, ivec2(gl_FragCoord.xy) + u_tile[k], 0)).r;
#else
        float occ = 0.0;
#endif
        t0[k] = max(max(lo.x, lo.y), max(lo.z, occ));
        t1[k] = min(min(hi.x, hi.y), min(hi.z, best));
        bool need = t0[k] < t1[k];
        cost[k] = need ? length(d.xy) * R * (t1[k] - t0[k]) : 1e30;
        needed += need ? 1 : 0;
    }
    int order[BOARDS];
    for (int k = 0; k < BOARDS; k++) {       // rank by cost (ties by index), then place: a branch-free sort
        int r = 0;
        for (int j = 0; j < BOARDS; j++) r += (cost[j] < cost[k] || (cost[j] == cost[k] && j < k)) ? 1 : 0;
        order[r] = k;
    }
    if (needed == 0) discard;               // no billboard to trace: the whole pixel group may stop here
    // The nearest crossing from above (front) and from below (back). Near a billboard's silhouette its
    // surface is known to a texel, so a ray may slip under it and come out just before the true surface,
    // which another billboard holds: a back hit wins only when no front hit lies within BACK_MARGIN of its
    // map texels behind it (an open surface seen from behind, or a closed model from inside: none does).
    float front = best, back = 2.0, margin = 0.0;
    int hit = -1, hit_back = -1;
    float seg_len = length(seg);
    for (int i = 0; i < needed; i++) {
        int k = order[i];
        float bound = min(front, back + margin);
        if (t0[k] < bound) {
            vec3 o = (u_to_box[k] * vec4(p0, 1.0)).xyz;
            vec3 d = mat3(u_to_box[k]) * seg;
            g_layer = u_layer[k];
            // sample coordinates of the bordered map: x = u R + 0.5 (heightfield_trace.glsl)
            float t = hf_trace_two_sided(vec3(o.xy * R + 0.5, o.z), vec3(d.xy * R, d.z), t0[k], min(t1[k], bound));
            if (t >= 0.0 && !hf_from_below) {
                front = t;
                hit = k;
            } else if (t >= 0.0 && t < back) {
                back = t;
                hit_back = k;
                margin = BACK_MARGIN * u_texel[k] / seg_len;
            }
        }
    }
    bool from_below = hit_back >= 0 && !(hit >= 0 && front <= back + margin);
    if (from_below) hit = hit_back;
    best = from_below ? back : front;
    if (hit < 0) discard;
    vec3 p = p0 + seg * best;
#if defined(INSTANCED)
    vec3 world = w0 + wseg * best;
#else
    vec3 world = p;
    float scale = 1.0;
    mat3 turn = mat3(1.0);
#endif
    gl_FragDepth = window_depth(u_view_proj, world);
#if !defined(SHADOW)
    vec3 st = (u_to_box[hit] * vec4(p, 1.0)).xyz;
    vec3 N = safe_normalize(turn * FETCH(texture(u_maps, vec3((st.xy * R + 1.0) / (R + 2.0), float(u_layer[hit])))).xyz);
    if (from_below) N = -N;   // the surface seen from behind: shaded two-sided, as the mesh and the reference are
    // the shadow lookup moves along the normal by u_board_texels map texels on top of the shadow map's
    // own normal offset (the surface is known to about a texel)
    float lit = shadow_lit(world + N * (u_board_texels * u_texel[hit] * scale), N);
#if defined(ALBEDO_MAPS)
    vec3 albedo = board_albedo(st.xy, u_layer[hit]);
#else
    vec3 albedo = u_albedo;
#endif
    frag = vec4(shade(albedo, N, normalize(u_eye - world), lit), 1.0);
#endif
}
