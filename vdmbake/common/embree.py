"""A thin wrapper over embreex: closest hits and occlusion for batches of rays.

Embree works in float32. Geometry is therefore stored relative to an anchor point
(the mesh's bounding-box centre) and ray origins are shifted by the same anchor
in float64 first, so objects far from the origin keep their precision; callers that
have points relative to the anchor already pass them so (relative=True). Coordinates are
also divided by a power of two near the mesh's size (exact in floating point), so that
Embree sees a mesh about one unit across whatever its scale (1e-9 or 1e9).
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

CHUNK = 1 << 20  # rays per embree call: bounds the temporary arrays


@dataclass
class Hits:
    t: np.ndarray       # (N,) float64 ray parameter, inf where missed
    prim: np.ndarray    # (N,) int64 triangle index, -1 where missed
    u: np.ndarray       # (N,) barycentrics: P = (1-u-v) v0 + u v1 + v v2
    v: np.ndarray
    ng: np.ndarray      # (N, 3) unit geometric normal, cross(v1-v0, v2-v0) direction


class RayScene:
    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        self.anchor = 0.5 * (vertices.min(0) + vertices.max(0))
        extent = float(np.abs(vertices - self.anchor).max()) if len(vertices) else 0.0
        self.scale = 2.0 ** round(np.log2(extent)) if extent > 0 and np.isfinite(extent) else 1.0
        self._scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self._scene, np.ascontiguousarray(((vertices - self.anchor) / self.scale)[faces], dtype=np.float32))
        self.rays_cast = 0
        self._count = threading.Lock()   # scenes are traced from several threads (reference.filtered, the bakes)

    def _batches(self, origins, dirs, tfar, relative=False):
        n = len(origins)
        tfar = np.full(n, np.inf) if tfar is None else np.broadcast_to(tfar, (n,))
        shift = 0.0 if relative else self.anchor
        for s in range(0, n, CHUNK):
            e = min(n, s + CHUNK)
            with self._count:
                self.rays_cast += e - s
            yield s, e, (np.ascontiguousarray((origins[s:e] - shift) / self.scale, dtype=np.float32),
                         np.ascontiguousarray(dirs[s:e], dtype=np.float32),
                         np.ascontiguousarray(np.minimum(tfar[s:e] / self.scale, 3.0e38), dtype=np.float32))

    def intersect(self, origins: np.ndarray, dirs: np.ndarray, tfar=None) -> Hits:
        n = len(origins)
        h = Hits(np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros(n), np.zeros(n), np.zeros((n, 3)))
        for s, e, (o, d, tf) in self._batches(origins, dirs, tfar):
            r = self._scene.run(o, d, dists=tf, output=1)
            hit = r["primID"] >= 0
            h.prim[s:e] = r["primID"]
            h.u[s:e], h.v[s:e] = r["u"], r["v"]
            # the hits' distances and unit normals only: a frame's misses cost no arithmetic
            h.t[s:e][hit] = r["tfar"][hit].astype(np.float64) * self.scale
            ng = r["Ng"][hit].astype(np.float64)
            length = np.sqrt(np.einsum("ij,ij->i", ng, ng))[:, None]
            h.ng[s:e][hit] = ng / np.where(length > 0, length, 1.0)   # a zero normal stays zero
        return h

    def distances(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Only the hit distance (float32, -1 where missed): the lean path for bulk table bakes."""
        out = np.empty(len(origins), np.float32)
        for s, e, (o, d, tf) in self._batches(origins, dirs, None):
            r = self._scene.run(o, d, dists=tf, output=1)
            out[s:e] = np.where(r["primID"] >= 0, r["tfar"] * np.float32(self.scale), -1.0)
        return out

    def occluded(self, origins: np.ndarray, dirs: np.ndarray, tfar=None, relative: bool = False) -> np.ndarray:
        """relative: the origins are given relative to `anchor`."""
        out = np.zeros(len(origins), bool)
        for s, e, (o, d, tf) in self._batches(origins, dirs, tfar, relative):
            out[s:e] = self._scene.run(o, d, dists=tf, query="OCCLUDED") >= 0
        return out
