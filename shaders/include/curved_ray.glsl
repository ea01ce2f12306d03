// Straight rays through the mesostructure of a curved reference surface, in texture space. The
// surface is bent to curvature c (texture units; > 0 convex) along the ray's azimuth, as the VDM
// bake bends its tables (Wang2003 Appendix; vdmbake/kernels/vdm.py bend), taken to second order in
// c times the distance (the osculating parabola: |c t| is below 0.2 for the depths tables are
// baked for). Numpy twin: vdmrender/curved_ray.py. A ray starts h0 below the surface at arc
// position 0 and runs at polar angle theta from the surface normal (st = sin theta), down into the
// surface (cz = -cos theta: a view ray) or up out of it (cz = cos theta: a light ray).

// The ray's point at distance t: (sigma, depth). sigma is the arc length under the point over
// sin theta, the extended displacement of Wang2003 Appendix: the point lies over texture coordinate
// T -+ sigma * V.xy. depth is below the surface.
vec2 curved_ray(float t, float h0, float st, float cz, float c) {
    float x = t * st, y = t * cz - h0;                      // in the plane: along the surface, up
    return vec2(t * (1.0 - c * y), -y - 0.5 * c * x * x);
}

// The distance along a view ray (h0 = 0) whose point has the extended displacement d: the root of
// c cos(theta) t^2 + t - d = 0 in the stable form (Numerical Recipes 5.6); past a concave ray's
// largest sigma, the distance of the largest.
float ray_distance(float d, float ct, float c) {
    return 2.0 * d / (1.0 + sqrt(max(1.0 + 4.0 * c * ct * d, 0.0)));
}

// The distance along a view ray to depth h: the smaller root of (c st^2 / 2) t^2 - ct t + h = 0;
// where a convex surface's ray never gets that deep, the distance of its deepest point.
float depth_distance(float h, float st, float ct, float c) {
    float disc = ct * ct - 2.0 * c * st * st * h;
    return disc >= 0.0 ? 2.0 * h / max(ct + sqrt(disc), 1e-12) : ct / (c * st * st);
}

// The distance from a point h below the surface, along a light ray, to where it leaves the surface:
// the root of (c st^2 / 2) u^2 + ct u - h = 0. A concave surface rising over a grazing ray has none:
// the discriminant is clamped, the ray taken to leave where it comes closest.
float exit_distance(float h, float st, float ct, float c) {
    return 2.0 * h / max(ct + sqrt(max(ct * ct + 2.0 * c * st * st * h, 0.0)), 1e-12);
}
