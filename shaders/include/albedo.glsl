// The asset's albedo map (vdmbake/common/texture.py, whose `sample` is this lookup's numpy twin): texels
// decoded to linear (gl.albedo_texture), filtered bilinearly, wrapping, without mipmaps (as the reference); under
// the scene's render.mipmaps the texture has its chain and the implicit derivatives of uv pick the level.
#include "cost_count.glsl"
uniform sampler2D u_albedo_map;

vec3 albedo_map(vec2 uv) {
    return FETCH(texture(u_albedo_map, uv)).rgb;
}
