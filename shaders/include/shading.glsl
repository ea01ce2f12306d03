// The shared shading model: Lambert diffuse plus Blinn-Phong specular from one directional light,
// a constant ambient term, ambient only where shadowed (as in Wang2003 §3.2, pixel shading). Passes
// write linear radiance; vdmbake/common/colour.py (to_srgb8) encodes it to sRGB.
// Its numpy twin is vdmrender/tracing/shading.py; the constants come from the scene.
uniform vec3 u_light_dir;    // unit vector towards the light, world space
uniform vec3 u_light_color;
uniform vec3 u_ambient;
uniform float u_kd;
uniform float u_ks;
uniform float u_shininess;

// A zero vector (e.g. opposite normals interpolated across a triangle) stays zero, not NaN.
vec3 safe_normalize(vec3 v) {
    float m = max(max(abs(v.x), abs(v.y)), abs(v.z));
    vec3 s = v / max(m, 1e-37);   // largest component +-1: its square neither underflows nor overflows
    return m > 0.0 ? s / length(s) : vec3(0.0);
}

// N: unit normal facing the viewer; V: unit vector to the eye; lit: 0 in shadow, 1 lit.
vec3 shade(vec3 albedo, vec3 N, vec3 V, float lit) {
    vec3 c = u_ambient * albedo;
    float ndl = dot(N, u_light_dir);
    if (lit > 0.0 && ndl > 0.0) {
        vec3 h = u_light_dir + V;
        vec3 H = h / max(length(h), 1e-8);
        c += u_light_color * (u_kd * ndl * albedo + u_ks * pow(max(dot(N, H), 0.0), u_shininess));
    }
    return c;
}
