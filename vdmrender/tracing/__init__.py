"""The reference: an independent ray tracer, no GL. `reference` traces every pixel (Embree for meshes and the
truly displaced mesostructure, float64 quadrics from `quadric_math` and `quadric_groups`) and shades it with the
numpy twin of the GLSL model (`shading`); `refcache` keys its frames on what they depend on and reuses them;
`borders` finds the pixels that see an open border."""
