// The billboards' colour maps (Vichitvejpaisal2005 §3.1: "color and normal of projected polygon
// poly is stored in color map and normal map"; read at the hit, Vichitvejpaisal2005 §3.3 step 2.3): one RGB16F layer per
// billboard of the asset's linear albedo, with the one-texel border of the normal and depth maps (the
// bake, vdmbake/kernels/billboard_maps.py albedo_texels, fills it and the empty texels near covered ones with
// their covered neighbours' colour), read with linear filtering. Only for assets with colours (ALBEDO_MAPS).
// MIPMAPS (the scene's render.mipmaps): RGBA of colour x coverage and coverage with their mip chain
// (passes/boards.py covered_colours), read at the level the derivatives of the hit's map coordinate give; rgb / a
// is the mean colour of what the footprint covers. Those derivatives jump where neighbouring pixels hit other
// billboards or depths, which blurs those pixels' colour (the depth and normal maps are searched and stay at
// level 0: a mean depth is no surface the ray meets, and the min/max pyramids serve the searches).
#include "cost_count.glsl"
uniform sampler2DArray u_albedo_maps;

// The albedo at s.xy in [0, 1]^2 of billboard `layer`'s R x R map.
vec3 board_albedo(vec2 st, int layer) {
    float R = float(textureSize(u_albedo_maps, 0).x - 2);
#ifdef MIPMAPS
    vec4 c = FETCH(texture(u_albedo_maps, vec3((st * R + 1.0) / (R + 2.0), float(layer))));
    return c.rgb / max(c.a, 1e-4);
#else
    return FETCH(texture(u_albedo_maps, vec3((st * R + 1.0) / (R + 2.0), float(layer)))).rgb;
#endif
}
