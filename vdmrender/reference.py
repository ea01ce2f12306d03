"""The reference: Embree primary rays through every pixel centre plus one shadow ray per hit,
shaded in float64 with the numpy twin of the shared model. Independent of the GL path."""
from __future__ import annotations

import numpy as np

from vdmbake.embree import RayScene

from .shading import safe_normalize, shade

SHADOW_EPSILON = 1e-5  # shadow-ray origin offset along the geometric normal, in bounding radii
VERSION = 1            # bump when the reference's output for the same inputs changes (cache key)


class MeshReference:
    """Traces one triangle mesh; the Embree scene is built once and reused for every camera."""

    def __init__(self, mesh, light, material):
        self.mesh, self.light, self.material = mesh, light, material
        self.scene = RayScene(mesh.vertices, mesh.faces)
        self.eps = SHADOW_EPSILON * mesh.bounding_sphere()[1]

    def render(self, camera) -> np.ndarray:
        """(H, W, 4) float32: linear RGB and coverage, row 0 at the top."""
        eye, d = camera.pixel_rays()
        # Start on the near plane and stop at the far plane, as the rasteriser clips (d has view depth 1).
        hits = self.scene.intersect(eye + d * camera.near, d, camera.far - camera.near)
        hit = hits.prim >= 0
        tri = self.mesh.faces[hits.prim[hit]]
        w = np.stack([1 - hits.u[hit] - hits.v[hit], hits.u[hit], hits.v[hit]], 1)[:, :, None]
        p = (w * self.mesh.vertices[tri]).sum(1)
        n = safe_normalize((w * self.mesh.normals[tri]).sum(1))
        dh = d[hit]
        ng = hits.ng[hit]
        back = np.einsum("ij,ij->i", ng, dh) > 0          # seen from behind: flip to face the viewer
        n[back], ng[back] = -n[back], -ng[back]
        to_eye = safe_normalize(camera.eye - p)
        L = np.broadcast_to(np.asarray(self.light.direction), p.shape)
        lit = ~self.scene.occluded(p + ng * self.eps, L)
        out = np.zeros((camera.height * camera.width, 4), np.float64)
        out[hit, :3] = shade(self.material.albedo, n, to_eye, lit, self.light, self.material)
        out[hit, 3] = 1.0
        return out.reshape(camera.height, camera.width, 4).astype(np.float32)
