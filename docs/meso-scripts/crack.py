"""Rays through cracks of the displaced reference: an OBJ torus whose UV seams split its vertices
(as exporters write it), bricks, levels as the reference picks; rays from 8 orbit cameras at 512^2.
A closed surface seen from outside: a first hit on a back face went through a crack."""
import sys
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from test_meso_fixes import _torus_obj
from vdmbake import curvature, displace, heightfields as hf
from vdmbake.meshes import load_mesh_file
from vdmbake.embree import RayScene
tmp = Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp"); obj = _torus_obj(tmp, 48, 24)
mesh = load_mesh_file(obj)
mesh.frame = curvature.estimate_frame(mesh.vertices, mesh.faces, mesh.normals, mesh.uvs)
h = hf.pattern("bricks", 64); tiling = (8, 2)
levels = displace.reference_levels(mesh, 64, tiling)
d = displace.displaced(mesh, h, 0.06, tiling, levels)
sc = RayScene(d.vertices, d.faces)
res, through, covered = 512, 0, 0
for k in range(8):
    a = 2 * np.pi * k / 8 + 0.3
    eye = np.array([3.2 * np.cos(a), 3.2 * np.sin(a), 1.4])
    fwd = -eye / np.linalg.norm(eye); right = np.cross(fwd, [0, 0, 1]); right /= np.linalg.norm(right); up = np.cross(right, fwd)
    t = np.tan(np.radians(20)); x = ((np.arange(res) + 0.5) / res * 2 - 1) * t
    X, Y = np.meshgrid(x, -x)
    dirs = (fwd + X[..., None] * right + Y[..., None] * up).reshape(-1, 3)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hits = sc.intersect(np.broadcast_to(eye, dirs.shape).copy(), dirs)
    hit = hits.prim >= 0
    back = hit & (np.einsum("ij,ij->i", hits.ng, dirs) > 0)
    through += int(back.sum()); covered += int(hit.sum())
print(f"levels {levels}, faces {len(d.faces)}: {through} of {covered} covered pixels see through a crack (8 views, {res}^2)")
