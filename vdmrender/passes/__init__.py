"""Passes that several renderers share: rasterised meshes (`raster`: also `Passes`, the per-pass
interface the harness times), the shadow map, the mesostructure pass of bump/pom/relief/vdm, the
billboards' boxes and maps, and the height-field tracer's pyramid upload."""
