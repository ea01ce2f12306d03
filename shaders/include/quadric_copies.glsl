// Copies of a quadrics object (issue 23), for sphere.vert, cylinder.vert and instanced.vert built with
// INSTANCED: every copy of every quadric in one instanced draw, gl_InstanceID = copy * u_quadrics + k. The
// bake's quadric rows (QuadricSet.instances: the float32 rows the single copy reads as attributes) are read by
// index k from a storage buffer, and each copy's matrix from another, so GPU memory holds the quadrics once
// plus 64 bytes a copy. The matrices are similarities (a uniform scale: a sphere stays a sphere, a cylinder a
// cylinder) from coordinates relative to the object's own centre to the frame's anchor
// (vdmrender/techniques/impostor.py: Copies). Bindings as Copies.BINDINGS; the cost counters hold binding 7.
layout(std430, binding = 0) readonly buffer CopyModels { mat4 copy_models[]; };
layout(std430, binding = 1) readonly buffer SphereRows { float sphere_rows[]; };       // x y z radius r g b
layout(std430, binding = 2) readonly buffer CylinderRows { float cylinder_rows[]; };   // x0 y0 z0 x1 y1 z1 radius r g b
uniform int u_quadrics;   // quadrics of one copy

mat4 copy_model() {
    return copy_models[gl_InstanceID / u_quadrics];
}

int quadric_index() {
    return gl_InstanceID % u_quadrics;
}

// Sphere k of the bake: centre (relative to the object's centre), radius; its colour.
void sphere_row(int k, out vec4 sphere, out vec3 rgb) {
    int b = 7 * k;
    sphere = vec4(sphere_rows[b], sphere_rows[b + 1], sphere_rows[b + 2], sphere_rows[b + 3]);
    rgb = vec3(sphere_rows[b + 4], sphere_rows[b + 5], sphere_rows[b + 6]);
}

// Cylinder k of the bake: axis end points, radius, colour.
void cylinder_row(int k, out vec3 p0, out vec3 p1, out float radius, out vec3 rgb) {
    int b = 10 * k;
    p0 = vec3(cylinder_rows[b], cylinder_rows[b + 1], cylinder_rows[b + 2]);
    p1 = vec3(cylinder_rows[b + 3], cylinder_rows[b + 4], cylinder_rows[b + 5]);
    radius = cylinder_rows[b + 6];
    rgb = vec3(cylinder_rows[b + 7], cylinder_rows[b + 8], cylinder_rows[b + 9]);
}

// A similarity's uniform scale.
float copy_scale(mat4 m) {
    return length(m[0].xyz);
}
