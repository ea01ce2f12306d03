// The pixel's ray, and the window depth of a point: shared by the shaders that cast rays per pixel
// (quadric impostors, billboards) and by those that write the depth of what they find
// (gl_FragDepth: impostors, billboards, mesostructure). Numpy twins: vdmrender/common/camera.py.

// The ray through normalised device position ndc (ndc_ray) or window position frag_xy in pixels (pixel_ray)
// between the near and the far plane: p = near_point + s * segment, s in [0, 1] (the interpolation factor mu of
// dePoel2009 eq. 3-4).
void ndc_ray(mat4 inv_view_proj, vec2 ndc, out vec3 near_point, out vec3 segment) {
    vec4 a = inv_view_proj * vec4(ndc, -1.0, 1.0);
    vec4 b = inv_view_proj * vec4(ndc, 1.0, 1.0);
    near_point = a.xyz / a.w;
    segment = b.xyz / b.w - near_point;
}

void pixel_ray(mat4 inv_view_proj, vec2 viewport, vec2 frag_xy, out vec3 near_point, out vec3 segment) {
    ndc_ray(inv_view_proj, frag_xy / viewport * 2.0 - 1.0, near_point, segment);
}

// Window-space depth in [0, 1] of point p under the clip transform view_proj (default depth range).
float window_depth(mat4 view_proj, vec3 p) {
    vec4 c = view_proj * vec4(p, 1.0);
    return clamp(0.5 + 0.5 * c.z / c.w, 0.0, 1.0);
}
