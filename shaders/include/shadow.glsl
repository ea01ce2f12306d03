// Hard shadows from a shadow map of the object seen along the light direction
// (orthographic, fitted to the bounding sphere), one nearest-texel depth comparison, so the
// result matches the reference's single shadow ray. Depth bias: the lookup point moves
// u_normal_offset along the normal (impostors write gl_FragDepth, which polygon offset does not
// reach); rasterised meshes add polygon offset when drawing the map.
#include "cost_count.glsl"
uniform sampler2DShadow u_shadow_map;
uniform mat4 u_light_mvp;   // light clip space from anchor-relative coordinates
uniform float u_normal_offset;

float shadow_lit(vec3 p, vec3 n) {
    vec3 s = (u_light_mvp * vec4(p + n * u_normal_offset, 1.0)).xyz * 0.5 + 0.5;
    return FETCH(texture(u_shadow_map, s));
}
