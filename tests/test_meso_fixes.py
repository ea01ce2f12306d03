"""Issue 10's fixes to how height maps meet meshes: the image's orientation against standard UVs,
one normalisation rule for every file format, and no cracks at UV seams in displaced meshes.

Height data: a real elevation model (matplotlib's sample `jacksboro_fault_dem.npz`, 344 x 403 int16
metres) written as a 16-bit PNG and as EXR, and small synthetic images whose orientation is unambiguous."""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from vdmbake.kernels import curvature, vdm
from vdmbake.formats import exr
from vdmbake.common import geometry
from vdmbake.assets import heightfields as hf, primitives
from vdmbake.assets.meshes import load_mesh_file

from meso_scenes import dem, torus_obj, write_obj, write_png16

DEPTH = 0.1


# ----------------------------------------------------------------------------- orientation


def test_image_top_is_v_one(tmp_path):
    """Image row 0 is the top of the picture; in OBJ / glTF UVs (as trimesh gives them) v = 0 is the
    picture's bottom. The loaded field is indexed [v, u], so its last row is the image's first."""
    img = np.zeros((8, 8), np.uint8)
    img[:2] = 255                        # a bright band along the top of the picture
    img[:, :1] = 128                     # and a grey column on its left
    p = tmp_path / "top.png"
    Image.fromarray(img).save(p)
    h = hf.load_image(p, None)
    assert np.array_equal(h, img[::-1] / 255.0)
    assert geometry.sample(h, np.array([0.5, 0.85])) == 1.0       # near v = 1: the picture's top
    assert geometry.sample(h, np.array([0.5, 0.3])) == 0.0
    e = tmp_path / "top.exr"                                 # EXR scanlines run top to bottom too
    exr.write(e, {"h": {"Y": img.astype(np.float32)}})
    assert np.array_equal(hf.load_image(e, None), h)


def test_height_map_upright_on_an_obj_quad(tmp_path):
    """A quad exported with standard UVs (v = 0 at its bottom edge, y = -1), displaced by a height map
    whose picture has its high half on top: the displaced quad must be high at y > 0."""
    write_obj(tmp_path / "quad.obj", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],
              [(0, 0), (1, 0), (1, 1), (0, 1)], [(0, 1, 2), (0, 2, 3)], [(0, 1, 2), (0, 2, 3)])
    img = np.zeros((16, 16), np.uint8)
    img[:8] = 255                                            # the top half of the picture is high
    Image.fromarray(img).save(tmp_path / "half.png")
    mesh = load_mesh_file(tmp_path / "quad.obj")
    mesh.frame = curvature.estimate_frame(mesh.vertices, mesh.faces, mesh.normals, mesh.uvs)
    h = hf.from_spec("half.png", 16, tmp_path)
    d = geometry.displaced(mesh, h, vdm.height_normals(h, DEPTH), DEPTH, (1, 1), 5)
    y, z = d.vertices[:, 1], d.vertices[:, 2]
    s = 2.0                                                   # s_n: one tile is 2 x 2 world units
    top, bottom = (y > 0.2) & (y < 0.8), (y < -0.2) & (y > -0.8)   # away from the (periodic) edges
    assert np.allclose(z[top], 0.0, atol=1e-12)              # the top half stays at the reference surface
    assert np.allclose(z[bottom], -DEPTH * s, atol=1e-12)    # the bottom half is depth below it


def test_primitive_uvs_not_mirrored():
    """Every primitive's texture map keeps the picture upright and unmirrored seen from outside, as
    standard UVs do: (dP/du x dP/dv) points along the outward normal (a right-handed frame)."""
    for name, params in [("plane", dict(size=2.0, segments=4)), ("sphere", dict(radius=1, segments=16, rings=8)),
                         ("torus", dict(major=1, minor=0.3, segments=16, rings=8)),
                         ("cylinder", dict(radius=0.5, height=1, segments=16, rings=2, caps=1)),
                         ("cone", dict(radius=0.5, height=1, segments=16, rings=2, caps=1)),
                         ("vase", dict(radius=0.5, height=1.5, segments=16, rings=8))]:
        m = primitives.build(name, params)
        f = m.frame
        handed = np.einsum("ij,ij->i", np.cross(f.dpdu, f.dpdv), m.normals)
        ok = np.linalg.norm(np.cross(f.dpdu, f.dpdv), axis=1) < 1e-9    # poles: a degenerate map
        assert np.all((handed > 0) | ok), (name, int((handed <= 0).sum()))
        # and the UVs move the way the frame says: across every face, uv differences match dP/du, dP/dv
        tri = m.faces
        dp = m.vertices[tri[:, 1]] - m.vertices[tri[:, 0]]
        duv = m.uvs[tri[:, 1]] - m.uvs[tri[:, 0]]
        pred = f.dpdu[tri[:, 0]] * duv[:, :1] + f.dpdv[tri[:, 0]] * duv[:, 1:]
        good = np.einsum("ij,ij->i", pred, dp) > 0
        small = np.abs(duv).max(1) < 0.5                     # not across the u seam
        assert good[small & (np.linalg.norm(dp, axis=1) > 0)].mean() > 0.99, name


# ----------------------------------------------------------------------------- normalisation


def test_same_elevation_model_as_png16_and_exr_gives_one_surface(tmp_path):
    """The DEM's metres (236 to 1076) stored as they are in a 16-bit PNG and as float EXR: one rule
    (min/max over the file, `depth` the only scale) makes both the same surface, spanning [0, 1]."""
    z = dem()
    write_png16(tmp_path / "dem.png", z)
    exr.write(tmp_path / "dem.exr", {"dem": {"Y": z.astype(np.float32)}})
    a = hf.load_image(tmp_path / "dem.png", 64)
    b = hf.load_image(tmp_path / "dem.exr", 64)
    assert np.abs(a - b).max() < 1e-12
    full = hf.load_image(tmp_path / "dem.exr", 256)
    assert full.max() > 0.95 and full.min() < 0.05           # the data's own range, not the file format's
    # the same data at another offset and scale: tenths of a foot above 200 m
    write_png16(tmp_path / "feet.png", np.round((z - 200) * 3.28084 * 10).astype(np.uint16))
    assert np.abs(hf.load_image(tmp_path / "feet.png", 64) - b).max() < 1e-4  # 16-bit rounding of 0.1 ft


def test_png_bit_depths_and_photos_share_the_rule(tmp_path):
    a = np.arange(64, dtype=np.uint8).reshape(8, 8) * 3 + 11  # 11 .. 200
    Image.fromarray(a).save(tmp_path / "h8.png")
    write_png16(tmp_path / "h16.png", a.astype(np.uint16) * 257)
    h8, h16 = hf.load_image(tmp_path / "h8.png", None), hf.load_image(tmp_path / "h16.png", None)
    assert h8.min() == 0.0 and h8.max() == 1.0
    assert np.allclose(h8, h16, atol=1e-12)


# ----------------------------------------------------------------------------- seams


def _open_edges(v: np.ndarray, f: np.ndarray) -> int:
    """Edges, keyed by their end positions, used by only one face: 0 on a closed surface."""
    _, pid = np.unique(v, axis=0, return_inverse=True)
    pid = pid.ravel()[f]
    e = np.sort(np.concatenate([pid[:, [0, 1]], pid[:, [1, 2]], pid[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int((counts == 1).sum())


@pytest.mark.parametrize("levels", [0, 2])
def test_displaced_mesh_has_no_cracks_at_uv_seams(tmp_path, levels):
    mesh = load_mesh_file(torus_obj(tmp_path))
    assert len(mesh.vertices) > 24 * 12                        # the loader kept the seams split (UVs differ)
    assert _open_edges(mesh.vertices, mesh.faces) == 0         # and the positions there are the same
    mesh.frame = curvature.estimate_frame(mesh.vertices, mesh.faces, mesh.normals, mesh.uvs)
    bricks = hf.pattern("bricks", 32)
    d = geometry.displaced(mesh, bricks, vdm.height_normals(bricks, 0.06), 0.06, (8, 2), levels)
    assert _open_edges(d.vertices, d.faces) == 0


def test_primitive_seams_displace_together():
    """The primitives duplicate their seam column (phi = 0 and 2 pi, equal up to rounding): displaced,
    the copies land on the same point, so the displaced torus is closed."""
    t = primitives.torus(1.0, 0.35, 32, 16)
    weave = hf.pattern("weave", 32)
    d = geometry.displaced(t, weave, vdm.height_normals(weave, 0.06), 0.06, (3, 1), 1)   # tiling 3: u = 0 and 1 agree
    assert _open_edges(d.vertices, d.faces) == 0
