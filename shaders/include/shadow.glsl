// Hard shadows from a shadow map of the object seen along the light direction
// (orthographic, fitted to the bounding sphere), one nearest-texel depth comparison, so the
// result matches the reference's single shadow ray. Depth bias: polygon offset when the map
// is drawn (slope-scaled) plus u_shadow_bias here.
uniform sampler2DShadow u_shadow_map;
uniform mat4 u_light_mvp;   // light clip space from anchor-relative coordinates
uniform float u_shadow_bias;

float shadow_lit(vec3 p) {
    vec3 s = (u_light_mvp * vec4(p, 1.0)).xyz * 0.5 + 0.5;
    return texture(u_shadow_map, vec3(s.xy, s.z - u_shadow_bias));
}
