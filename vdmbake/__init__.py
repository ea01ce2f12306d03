"""vdmbake: bakes the tables, maps and meshes a scene's objects need into an EXR/PLY bundle."""

__version__ = "0.1.0"
