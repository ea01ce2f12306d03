"""Reading what a scene names: mesh files and their textures, the built-in primitives and the Utah
teapot, height fields, a mesostructure tile's colour, molecules. Each reader returns the in-memory
form the kernels take (`common.mesh.TriMesh`, `kernels.quadrics.QuadricSet`, arrays) or raises InputError."""
