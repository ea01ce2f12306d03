// An orthonormal frame around a unit vector w: u, v with (u, v, w) right-handed, branch-free and
// stable for every direction (Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
// Numpy twin: vdmbake/common/geometry.py onb.
void onb(vec3 w, out vec3 u, out vec3 v) {
    float s = w.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + w.z);
    float b = w.x * w.y * a;
    u = vec3(1.0 + s * w.x * w.x * a, s * b, -s * w.x);
    v = vec3(b, s + w.y * w.y * a, -w.y);
}
