"""Pure numpy shared by the baker and the renderer, the one room of the baker (besides the bundle and
the formats) that vdmrender may import: frames and mesh geometry, the texture-space map, sRGB, the
albedo-map lookup, Embree ray scenes and the min/max pyramid with its exact trace."""
