"""The papers' bake kernels, pure numpy (+ Embree), grouped by paper:

* Wang2003 (view-dependent displacement mapping): `vdm` (the tables by ray casting, the MVM, the SVD),
  `vdm_storage` (how the weights are stored), `curvature` (the per-vertex curvatures the tables are
  indexed by on curved surfaces).
* Sigg2006 (ray casting of quadrics): `quadrics` (sphere and cylinder lists), `quadric_mesh` (their
  triangle mesh for viewers and the raster peer).
* Vichitvejpaisal2005 (enhanced billboards): `billboards` (greedy projection, the maps),
  `billboard_maps` (the renderers' bordered maps and pyramids).
* Beyond the papers: `octahedral` (octahedral impostors, Brucks 2018), `coarse` (simplified meshes for
  hole filling and as a peer).

A technique's bake step (vdmbake/techniques/NAME.py) calls these; the renderer never imports them."""
