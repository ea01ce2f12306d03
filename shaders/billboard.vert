#version 430
// Enhanced billboards (Vichitvejpaisal2005 §3.3 step 1): each billboard is drawn as its
// bounding box, one instance per billboard, so that every pixel its geometry can cover runs the
// fragment stage's ray march. Only the BACK faces are rasterised (front faces culled): they cover the
// box's screen footprint whether the eye is outside or inside the box, and they are never in front of
// the ray's box segment, so near-plane clipping removes nothing visible. u_raster is the camera's
// matrix with the far plane at infinity (the light's with a wider depth range), so no box face is lost
// behind the far plane; the fragment stage writes the true depth of the hit.
in vec3 in_corner;   // per vertex: unit-cube corner (0 or 1 per axis); 12 triangles, CCW seen from outside
in vec3 in_origin;   // per instance: box corner at texel (0, 0), depth 0 (anchor-relative world)
in vec3 in_u;        // per instance: box edges along u, v, w (unit axis times the box extent)
in vec3 in_v;
in vec3 in_w;
uniform mat4 u_raster;
flat out vec3 v_origin;
flat out vec3 v_iu;  // edge / |edge|^2: dot(p - origin, v_iu) is the texture coordinate along that edge
flat out vec3 v_iv;
flat out vec3 v_iw;
flat out int v_layer;

void main() {
    vec3 p = in_origin + in_corner.x * in_u + in_corner.y * in_v + in_corner.z * in_w;
    gl_Position = u_raster * vec4(p, 1.0);
    v_origin = in_origin;
    v_iu = in_u / dot(in_u, in_u);
    v_iv = in_v / dot(in_v, in_v);
    v_iw = in_w / dot(in_w, in_w);
    v_layer = gl_InstanceID;
}
