// Mesostructure texture space per pixel (Wang2003 §3.2), the GLSL twin of vdmbake/common/texspace.py.
#include "camera.glsl"
// A tile spans 1 x 1 texture units; the mesostructure lies u_depth (texture units) below the
// reference surface. Near the pixel, texture space maps to world space by M = [J | s_n N].
#include "cost_count.glsl"
uniform vec2 u_tiling;          // tiles over the UV square
uniform float u_depth;          // mesostructure depth, texture units
uniform sampler2D u_height;     // heights in [0, 1] (1 = reference surface), repeat, mip-mapped
uniform sampler2D u_normals;    // texture-space unit normals of the mesostructure, repeat (MIPMAPS: mip-mapped)
uniform mat4 u_mvp;

in vec3 v_pos;
in vec3 v_normal;
in vec2 v_uv;
in vec3 v_dpdu;
in vec3 v_dpdv;
in vec2 v_curv;
in vec3 v_d1;

struct Frame {
    vec3 N;        // unit normal
    vec3 Ju, Jv;   // world length per tile along u and v, in the tangent plane
    vec3 Iu, Iv;   // rows of J+ = (J^T J)^-1 J^T: world tangent vector -> texture units
    float sn;      // world length of one texture unit of depth
    vec3 d1, d2;   // principal directions, re-orthonormalised against N
};

// The interpolated frame, re-orthonormalised (interpolation shortens and tilts the vectors).
// J^T J and its determinant (~|J|^4) are formed from J scaled to unit size, so tiles of any world size
// stay inside float32's range; the determinant's clamp is relative (a degenerate map, e.g. at a pole,
// keeps finite values), as texspace.world_normals's.
Frame surface_frame(vec3 N) {
    Frame F;
    F.N = N;
    F.Ju = (v_dpdu - dot(v_dpdu, N) * N) / u_tiling.x;
    F.Jv = (v_dpdv - dot(v_dpdv, N) * N) / u_tiling.y;
    vec3 m3 = max(abs(F.Ju), abs(F.Jv));
    float m = max(max(max(m3.x, m3.y), m3.z), 1e-30);
    vec3 ju = F.Ju / m, jv = F.Jv / m;
    float a = dot(ju, ju), b = dot(ju, jv), c = dot(jv, jv);
    float det = max(a * c - b * b, 1e-12 * (a + c) * (a + c) + 1e-30);   // of J / m: the true one is det m^4
    F.Iu = (c * ju - b * jv) / (det * m);
    F.Iv = (a * jv - b * ju) / (det * m);
    F.sn = sqrt(sqrt(det)) * m;
    vec3 d1 = v_d1 - dot(v_d1, N) * N;
    F.d1 = dot(d1, d1) > 1e-12 ? normalize(d1) : normalize(F.Ju + 1e-30);
    F.d2 = cross(N, F.d1);
    return F;
}

// A world direction in texture space, unit length (z along the normal).
vec3 to_texture(Frame F, vec3 w) {
    return normalize(vec3(dot(F.Iu, w), dot(F.Iv, w), dot(F.N, w) / F.sn));
}

// World length of a texture-space vector t (the affine map M applied to it).
float world_length(Frame F, vec3 t) {
    return length(F.Ju * t.x + F.Jv * t.y + F.N * (F.sn * t.z));
}

// Curvature in texture units along the texture direction of t (c(e) = II(J e, J e) / s_n, Euler's
// formula): the paper's c_V without its 0/0 at V = N, where any direction will do.
float texture_curvature(Frame F, vec3 t) {
    float l = length(t.xy);
    vec2 e = l > 1e-6 ? t.xy / l : vec2(1.0, 0.0);
    vec3 x = F.Ju * e.x + F.Jv * e.y;
    float a = dot(x, F.d1), b = dot(x, F.d2);
    return (v_curv.x * a * a + v_curv.y * b * b) / F.sn;
}

// A texture-space normal (from u_normals) in world space: M^-T n.
vec3 world_normal(Frame F, vec3 n) {
    return normalize(F.Iu * n.x + F.Iv * n.y + F.N * (n.z / F.sn));
}

#ifdef MIPMAPS
// The pixel's footprint in tile coordinates (MIPMAPS, the scene's render.mipmaps): the screen derivatives of the
// base surface's T = uv * tiling, where the pixel's ray enters the mesostructure. VDM is "anti-aliased by
// mip-mapping" (Wang2003 §4) at this footprint; the hit's own T' jumps at every occlusion edge, and its
// derivatives would blur the whole quad there. Derivatives of an interpolated input hold in any control flow.
void footprint(out vec2 dx, out vec2 dy) {
    vec2 T = v_uv * u_tiling;
    dx = dFdx(T);
    dy = dFdy(T);
}

// The mesostructure's shading normal at T, the mean over the pixel's footprint renormalised (as engines filter
// normal maps). Kept at its mean's length, the Lambert term would be the footprint's mean n . L (linear in n),
// but level 0's bilinear filter shortens the normals between texels too, which would darken every magnified
// brick edge against the reference's unit normals; the renormalised mean overshoots the mean diffuse term
// where the footprint's normals spread (Toksvig's filtering would fix that; not done).
vec3 mesostructure_normal(Frame F, vec2 T) {
    vec2 dx, dy;
    footprint(dx, dy);
    return world_normal(F, FETCH(textureGrad(u_normals, T, dx, dy)).xyz);
}
#else
// The mesostructure's shading normal at T in world space, read at the finest level: the reference
// shades the displaced mesh with these normals at its vertices, unfiltered (mip-mapped normals blur
// the shading against it; docs/tuning.md has the figures).
vec3 mesostructure_normal(Frame F, vec2 T) {
    return world_normal(F, FETCH(textureLod(u_normals, T, 0.0)).xyz);
}
#endif

// The albedo at tile coordinate T: the mesostructure's colour tile, which repeats with the height field
// (TILE_ALBEDO: an albedo map, albedo.glsl; the reference reads it at the traced hit's T), or the
// material's constant.
#ifdef TILE_ALBEDO
#include "albedo.glsl"
#ifdef MIPMAPS
// The colour tile's mean over the pixel's footprint (gl.albedo_texture's mip chain): a filtered reference
// averages the reflectance its samples hit there.
vec3 tile_albedo(vec2 T) {
    vec2 dx, dy;
    footprint(dx, dy);
    return FETCH(textureGrad(u_albedo_map, T, dx, dy)).rgb;
}
#else
vec3 tile_albedo(vec2 T) {
    return albedo_map(T);
}
#endif
#else
uniform vec3 u_albedo;
vec3 tile_albedo(vec2 T) {
    return u_albedo;
}
#endif

// Depth below the reference surface at tile coordinate T, texture units.
float depth_at(vec2 T, vec2 dx, vec2 dy) {
    return u_depth * (1.0 - FETCH(textureGrad(u_height, T, dx, dy)).r);
}

// The same at the height field's finest level: the surface the reference traces.
float depth_at_lod0(vec2 T) {
    return u_depth * (1.0 - FETCH(textureLod(u_height, T, 0.0)).r);
}
