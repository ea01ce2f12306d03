#version 430
// Enhanced billboards (Vichitvejpaisal2005 §3.3 step 1): each billboard is drawn as its
// bounding box, so that every pixel its geometry can cover runs the fragment stage's ray march; every
// box of the object is in the vertex buffer (its 36 corners carry the box), and each instance draws them
// all for one copy of the object (issue 23; an object drawn once is one copy at the identity). Only the
// BACK faces are rasterised (front faces culled): they cover the box's screen footprint whether the eye is
// outside or inside the box, and they are never in front of the ray's box segment, so near-plane clipping
// removes nothing visible. u_raster is the camera's matrix with the far plane at infinity (the light's with
// a wider depth range), so no box face is lost behind the far plane; the fragment stage writes the true
// depth of the hit.
in vec3 in_corner;   // unit-cube corner (0 or 1 per axis) of its billboard's box; 12 triangles, CCW from outside
in vec3 in_origin;   // the box: corner at texel (0, 0), depth 0 (anchor-relative, the object's frame)
in vec3 in_u;        // the box's edges along u, v, w (unit axis times the box extent)
in vec3 in_v;
in vec3 in_w;
in int in_layer;     // the billboard's layer in the map arrays
in mat4 in_model;    // per instance: the copy's similarity A = s R (vdmbake.common.instances), anchor-relative
uniform mat4 u_raster;
flat out vec3 v_origin;
flat out vec3 v_iu;  // edge / |edge|^2: dot(p - origin, v_iu) is the texture coordinate along that edge
flat out vec3 v_iv;
flat out vec3 v_iw;
flat out int v_layer;
flat out mat3 v_turn;   // R: the maps' normals, in the object's frame, turned into the world

void main() {
    mat3 A = mat3(in_model);
    vec3 o = (in_model * vec4(in_origin, 1.0)).xyz;
    vec3 u = A * in_u, v = A * in_v, w = A * in_w;   // a similarity keeps the box a box
    gl_Position = u_raster * vec4(o + in_corner.x * u + in_corner.y * v + in_corner.z * w, 1.0);
    v_origin = o;
    v_iu = u / dot(u, u);
    v_iv = v / dot(v, v);
    v_iw = w / dot(w, w);
    v_layer = in_layer;
    v_turn = A / length(A[0]);
}
