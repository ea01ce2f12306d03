// Ray casting of quadrics per pixel (Sigg2006, as re-implemented by
// dePoel2009 §3). Twin of vdmrender/tracing/quadric_math.py. Coordinates are anchor-relative world space.
#include "camera.glsl"
uniform mat4 u_view_proj;       // clip space from anchor-relative world
uniform mat4 u_inv_view_proj;
uniform vec2 u_viewport;        // pixels

const mat4 D = mat4(1.0, 0.0, 0.0, 0.0,  0.0, 1.0, 0.0, 0.0,  0.0, 0.0, 1.0, 0.0,  0.0, 0.0, 0.0, -1.0);

// Sigg's projected bounding box of the quadric with variance matrix T (parameter space -> world):
// R = P M T; the clip plane x - X w = 0 is tangent iff (R_x - X R_w) D (R_x - X R_w)^T = 0.
// Returns (xmin, ymin, xmax, ymax) in NDC; the whole screen where the quadric reaches the eye
// plane (R_w D R_w^T >= 0: the projection is unbounded, the denominator goes to 0).
vec4 quadric_bounds(mat4 T) {
    mat4 R = transpose(u_view_proj * T);   // rows of P M T as columns
    vec4 rw = R[3];
    float a = dot(rw, D * rw);
    if (a >= -1e-12 * dot(rw, rw)) return vec4(-1.0, -1.0, 1.0, 1.0);
    vec2 b = vec2(dot(R[0], D * rw), dot(R[1], D * rw));
    vec2 c = vec2(dot(R[0], D * R[0]), dot(R[1], D * R[1]));
    vec2 root = sqrt(max(b * b - a * c, 0.0));
    vec2 lo = (b + root) / a, hi = (b - root) / a;   // a < 0: (b + root) / a is the smaller
    return vec4(min(lo, hi), max(lo, hi));
}

// The side of the eye plane the quadric T lies on: 1 in front, -1 behind, 0 reaching it (where
// quadric_bounds gives the whole screen). The clip w row of P M T applied to T's centre is its depth.
float eye_side(mat4 T) {
    vec4 rw = transpose(u_view_proj * T)[3];
    if (dot(rw, D * rw) >= -1e-12 * dot(rw, rw)) return 0.0;
    return rw.w > 0.0 ? 1.0 : -1.0;
}

// A screen-aligned quad over the bounds, clamped to the screen, at depth 0 (never clipped);
// the fragment stage writes the true depth.
vec4 quad_corner(vec4 box, vec2 corner) {
    box = clamp(box, -1.0, 1.0);
    return vec4(mix(box.xy, box.zw, corner * 0.5 + 0.5), 0.0, 1.0);
}

// Smallest root >= 0 of t^2 - 2 b t + c = 0 with disc = b^2 - c computed by the caller in a
// stable form; q = b + sign(b) sqrt(disc), roots {c / q, q} (no cancellation). -1 if none.
float first_root(float b, float c, float disc) {
    if (disc < 0.0) return -1.0;
    float q = b + (b >= 0.0 ? 1.0 : -1.0) * sqrt(disc);
    float t0 = q != 0.0 ? c / q : 0.0;
    float lo = min(t0, q), hi = max(t0, q);
    return lo >= 0.0 ? lo : hi;   // hi < 0 too: no hit ahead
}

// Unit sphere at the origin, unit direction d: Ray Tracing Gems ch. 7, disc = 1 - |f + b d|^2.
float ray_unit_sphere(vec3 f, vec3 d) {
    float b = -dot(f, d);
    vec3 l = f + b * d;
    return first_root(b, dot(f, f) - 1.0, 1.0 - dot(l, l));
}

// Unit capped cylinder x^2 + y^2 <= 1, |z| <= 1 in parameter space; d need not be unit.
// Returns the ray parameter (units of |d|), -1 if missed; n: parameter-space normal.
float ray_unit_cylinder(vec3 o, vec3 d, out vec3 n) {
    float best = 1e30;
    float s = length(d.xy);
    if (s > 0.0) {
        vec2 dir = d.xy / s;
        float b = -dot(o.xy, dir);
        vec2 l = o.xy + b * dir;
        float disc = 1.0 - dot(l, l);
        if (disc >= 0.0) {
            float q = b + (b >= 0.0 ? 1.0 : -1.0) * sqrt(disc);
            float c = dot(o.xy, o.xy) - 1.0;
            vec2 roots = vec2(q != 0.0 ? c / q : 0.0, q) / s;
            for (int k = 0; k < 2; k++) {
                float t = roots[k];
                if (t >= 0.0 && t < best && abs(o.z + t * d.z) <= 1.0) {
                    best = t;
                    n = vec3(o.xy + t * d.xy, 0.0);
                }
            }
        }
    }
    if (d.z != 0.0) {
        for (int k = 0; k < 2; k++) {
            float zc = k == 0 ? -1.0 : 1.0;
            float t = (zc - o.z) / d.z;
            vec2 xy = o.xy + t * d.xy;
            if (t >= 0.0 && t < best && dot(xy, xy) <= 1.0) {
                best = t;
                n = vec3(0.0, 0.0, zc);
            }
        }
    }
    return best < 1e30 ? best : -1.0;
}
