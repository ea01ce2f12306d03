"""Every bundle part kind (vdmbake.bundle.parts) round-trips: unpack(pack(value)) gives the value back,
to float32 where the format stores float32, and the reader refuses a part of another kind."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.bundle import parts
from vdmbake.assets import primitives
from vdmbake.kernels import quadrics
from vdmbake.errors import InputError
from vdmbake.common.mesh import TriMesh

RNG = np.random.default_rng(3)


def f32(a):
    return np.asarray(a, np.float32)


def test_mesh_with_uvs_and_frame():
    m = primitives.torus(1.0, 0.35, 12, 6)
    m = TriMesh(m.vertices + 1e5, m.faces, m.normals, m.uvs, m.frame)     # positions keep float64
    back = parts.stored(parts.MESH, m)
    assert np.array_equal(back.vertices, m.vertices) and np.array_equal(back.faces, m.faces)
    assert np.array_equal(back.normals, f32(m.normals)) and np.array_equal(back.uvs, f32(m.uvs))
    for f in ("dpdu", "dpdv", "k1", "k2", "d1"):
        assert np.array_equal(getattr(back.frame, f), f32(getattr(m.frame, f)))
    plain = parts.stored(parts.MESH, TriMesh(m.vertices, m.faces, m.normals))
    assert plain.uvs is None and plain.frame is None
    data, meta = parts.MESH.pack(m)
    assert meta == {"vertices": len(m.vertices), "faces": len(m.faces)}


def test_quadrics():
    s, c = RNG.normal(size=(5, 4)), RNG.normal(size=(3, 7))
    s[:, 3], c[:, 6] = np.abs(s[:, 3]) + 0.1, np.abs(c[:, 6]) + 0.1    # radii > 0: what a bake stores (a reader refuses others)
    q = quadrics.QuadricSet(s, f32(RNG.uniform(size=(5, 3))), c, f32(RNG.uniform(size=(3, 3))))
    back = parts.stored(parts.QUADRICS, q)
    for f in ("spheres", "sphere_rgb", "cylinders", "cylinder_rgb"):
        assert np.array_equal(getattr(back, f), getattr(q, f))


def test_mesostructure_maps():
    n = RNG.normal(size=(8, 8, 3))
    m = parts.MesostructureMaps(f32(RNG.uniform(size=(8, 8))), f32(n / np.linalg.norm(n, axis=-1, keepdims=True)))
    back = parts.stored(parts.MESOSTRUCTURE, m)
    assert np.array_equal(back.heights, m.heights) and np.array_equal(back.normals, m.normals)


@pytest.mark.parametrize("storage", [np.float32, np.float16, np.uint8])
def test_vdm_tables(storage):
    W = RNG.uniform(0, 255, size=(4, 8, 8, 5)).astype(storage)
    scale, offset = (f32(RNG.uniform(size=5)), f32(RNG.normal(size=5))) if storage == np.uint8 else \
        (np.ones(5, np.float32), np.zeros(5, np.float32))
    t = parts.VDMTables(W, f32(RNG.normal(size=(5, 3, 2))), f32(RNG.normal(size=(5, 3))), scale, offset)
    data, meta = parts.VDM.pack(t)
    assert meta == {"k": 5, "n_phi": 4, "storage": np.dtype(storage).name}
    back = parts.VDM.unpack(data, meta, "t")
    assert back.W.dtype == storage
    for f in ("W", "E_vdm", "E_mvm", "scale", "offset"):
        assert np.array_equal(getattr(back, f), getattr(t, f)), f


def test_billboards():
    boards = [parts.Billboard(RNG.normal(size=3), np.linalg.qr(RNG.normal(size=(3, 3)))[0], RNG.uniform(size=3),
                              f32(RNG.uniform(size=(6, 6)) > 0.5), f32(RNG.uniform(size=(6, 6))),
                              f32(RNG.normal(size=(6, 6, 3)))) for _ in range(3)]
    back = parts.stored(parts.BILLBOARDS, boards)
    assert len(back) == 3
    for a, b in zip(boards, back):
        for f in ("origin", "axes", "size", "alpha", "depth", "normal"):
            assert np.array_equal(getattr(a, f), getattr(b, f)), f


def test_octahedral_atlas():
    n, res = 3, 16
    basis = np.linalg.qr(RNG.normal(size=(3, 3)))[0]
    basis *= np.sign(np.linalg.det(basis))          # right-handed
    a = parts.OctahedralAtlas(n, True, basis, RNG.normal(size=3), 1.5, 1.9, f32(RNG.uniform(-1, 1, (n * res, n * res, 2))),
                              f32(RNG.uniform(size=(n * res, n * res))), f32(RNG.uniform(size=(n * res, n * res)) > 0.5), 777)
    back = parts.stored(parts.OCTAHEDRAL, a)
    assert back.resolution == res
    for f in ("views", "hemi", "basis", "centre", "radius", "capture", "normal", "depth", "coverage", "rays"):
        assert np.array_equal(getattr(a, f), getattr(back, f)), f
    data, meta = parts.OCTAHEDRAL.pack(a)
    with pytest.raises(InputError, match="the manifest says 3 views of 8"):
        parts.OCTAHEDRAL.unpack(data, {**meta, "resolution": 8}, "x.exr")
    with pytest.raises(InputError, match="basis not a right-handed"):
        parts.OCTAHEDRAL.unpack(data, {**meta, "basis": (-basis).tolist()}, "x.exr")
    a.depth[0, 0] = np.nan
    with pytest.raises(InputError, match="NaN or Inf"):
        parts.OCTAHEDRAL.unpack(*parts.OCTAHEDRAL.pack(a), "x.exr")


def test_missing_channels_and_wrong_kind_are_input_errors(tmp_path):
    data, meta = parts.MESOSTRUCTURE.pack(parts.MesostructureMaps(f32(np.ones((4, 4))), f32(np.ones((4, 4, 3)))))
    with pytest.raises(InputError, match="'height' with channels h is missing"):
        one = np.ones(1, np.float32)
        parts.MESOSTRUCTURE.unpack(parts.VDM.pack(parts.VDMTables(f32(np.ones((1, 4, 4, 1))), f32(np.ones((1, 1, 1))),
                                                                  f32(np.ones((1, 1))), one, 0 * one))[0], meta, "x.exr")
    with pytest.raises(InputError, match="unreadable EXR"):
        parts.MESOSTRUCTURE.unpack(data[:100], meta, "x.exr")
