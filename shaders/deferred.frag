#version 430
// Deferred shading of ray-cast quadrics (dePoel2009 §4): the G-buffer holds
// the normal and mu (the ray's interpolation factor between the near and far planes) instead
// of depth; the position is rebuilt from mu (dePoel2009 eq. 3-4). Optional Sobel outlines: silhouettes
// from the depth, creases from the normals, strengths u_silhouette and u_crease. Each hit writes its
// exact depth, so the pass is depth-tested against whatever else the target holds (composite frames).
#include "cost_count.glsl"
#include "shading.glsl"
#include "shadow.glsl"
#include "quadric.glsl"
uniform sampler2D u_normal_mu;   // xyz normal, w mu
uniform sampler2D u_albedo_cov;  // rgb albedo, a coverage
uniform vec3 u_eye;
uniform vec2 u_near_far;
uniform float u_silhouette;
uniform float u_crease;
out vec4 frag;

// View depth along the pixel's ray: linear in mu between the near and far planes; far for background.
float view_depth(ivec2 q) {
    vec4 g = FETCH(texelFetch(u_normal_mu, q, 0));
    return FETCH(texelFetch(u_albedo_cov, q, 0)).a > 0.0 ? mix(u_near_far.x, u_near_far.y, g.w) : u_near_far.y;
}

void main() {
    COUNT_FRAGMENT();
    ivec2 q = ivec2(gl_FragCoord.xy);
    vec4 alb = FETCH(texelFetch(u_albedo_cov, q, 0));
    if (alb.a == 0.0) discard;   // no quadric here: the target keeps what it holds
    vec4 g = FETCH(texelFetch(u_normal_mu, q, 0));
    vec3 p0, seg;
    pixel_ray(u_inv_view_proj, u_viewport, gl_FragCoord.xy, p0, seg);
    vec3 p = p0 + g.w * seg;
    gl_FragDepth = window_depth(u_view_proj, p);
    vec3 n = g.xyz;
    vec3 c = shade(alb.rgb, n, normalize(u_eye - p), shadow_lit(p, n));
    if (u_silhouette > 0.0 || u_crease > 0.0) {
        ivec2 hi = ivec2(u_viewport) - 1;
        float gx = 0.0, gy = 0.0;
        vec3 nx = vec3(0.0), ny = vec3(0.0);
        for (int j = -1; j <= 1; j++) {
            for (int i = -1; i <= 1; i++) {
                ivec2 k = clamp(q + ivec2(i, j), ivec2(0), hi);
                float wx = float(i) * (j == 0 ? 2.0 : 1.0);   // Sobel kernels
                float wy = float(j) * (i == 0 ? 2.0 : 1.0);
                float z = view_depth(k);
                vec3 nk = FETCH(texelFetch(u_albedo_cov, k, 0)).a > 0.0 ? FETCH(texelFetch(u_normal_mu, k, 0)).xyz : vec3(0.0);
                gx += wx * z;  gy += wy * z;
                nx += wx * nk; ny += wy * nk;
            }
        }
        // Thresholds keep smooth curvature unmarked: the depth Sobel is taken relative to the depth
        // (a jump of 5-15% of the depth is a silhouette at any distance); the normal Sobel is about
        // 8 x (normal turn per pixel in radians): 2-4 marks turns of 15-30 degrees per pixel.
        float depth_edge = smoothstep(0.05, 0.15, length(vec2(gx, gy)) / view_depth(q));
        float crease_edge = smoothstep(2.0, 4.0, sqrt(dot(nx, nx) + dot(ny, ny)));
        c *= 1.0 - clamp(u_silhouette * depth_edge + u_crease * crease_edge, 0.0, 1.0);
    }
    frag = vec4(c, 1.0);
}
