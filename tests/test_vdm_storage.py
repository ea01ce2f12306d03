"""The VDM weights' storage (vdmbake/kernels/vdm_storage.py): 8-bit codes with a per-eigenfunction scale and
offset, half floats, float32; the error each adds, measured through the eigenfunctions' Gram matrices
without rebuilding the tables; the bake's choice and what it writes."""
from __future__ import annotations

import json

import numpy as np
import pytest

from vdmbake.formats import exr
from vdmbake.kernels import vdm_storage
from vdmbake.bundle.directory import Bundle

RNG = np.random.default_rng(3)


def tables(k=6, rows=(8, 8, 4), n_theta=5, n_c=3):
    W = RNG.normal(size=(*rows, k)) * np.linspace(10, 0.1, k)            # eigenfunctions of falling weight
    E, _ = np.linalg.qr(RNG.normal(size=(n_theta * n_c + n_c, k)))       # orthonormal columns, as the SVD's
    return W.astype(np.float32), E[:n_theta * n_c].T.reshape(k, n_theta, n_c), E[n_theta * n_c:].T


def test_uint8_codes_span_each_eigenfunction():
    W, _, _ = tables()
    W[..., 2] = 1.25                                                     # a constant eigenfunction stays exact
    codes, scale, offset = vdm_storage.quantise(W, "uint8")
    assert codes.dtype == np.uint8 and codes.shape == W.shape
    back = vdm_storage.dequantise(codes, scale, offset)
    flat = W.reshape(-1, W.shape[-1])
    assert np.allclose(offset, flat.min(0)) and np.allclose(offset + 255 * scale, flat.max(0), rtol=1e-6)
    assert np.all(np.abs(back - W) <= 0.5 * scale + 1e-6 * np.abs(W).max())
    assert np.all(back[..., 2] == 1.25)
    h, s, o = vdm_storage.quantise(W, "float16")
    assert h.dtype == np.float16 and np.all(s == 1) and np.all(o == 0)
    with pytest.raises(ValueError, match="unknown W storage"):
        vdm_storage.quantise(W, "int4")


def test_added_rms_is_the_tables_rms_change():
    """||dW E^T|| through the Gram matrices equals the RMS change of the rebuilt A_VDM and A_MVM."""
    W, E_vdm, E_mvm = tables()
    dW = RNG.normal(size=W.shape) * 0.01
    k = W.shape[-1]
    got = vdm_storage.added_rms(dW, E_vdm, E_mvm)
    d = dW.reshape(-1, k).astype(np.float64)
    want = [np.sqrt(np.mean((d @ E.reshape(k, -1)) ** 2)) for E in (E_vdm, E_mvm)]
    assert np.allclose(got, want, rtol=1e-10)


def test_choose_the_smallest_storage_the_truncation_hides():
    W, E_vdm, E_mvm = tables()
    errors = vdm_storage.storage_errors(W, E_vdm, E_mvm)
    assert errors["float32"] == {"rms_vdm": 0.0, "rms_mvm": 0.0}
    assert errors["uint8"]["rms_vdm"] > errors["float16"]["rms_vdm"] > 0
    u8 = errors["uint8"]["rms_vdm"]
    assert vdm_storage.choose(errors, 10 * u8, 10 * errors["uint8"]["rms_mvm"]) == "uint8"
    assert vdm_storage.choose(errors, 2 * u8, 2 * errors["uint8"]["rms_mvm"]) == "float16"
    assert vdm_storage.choose(errors, 0.0, 0.0) == "float32"


SCENE = """\
[render]
resolution = [32, 32]
[camera]
orbit = { count = 1 }
[[objects]]
name = "t"
primitive = "torus"
params = { segments = 32, rings = 16 }
techniques = { vdm = { k = [K] } }
[objects.mesostructure]
height = "bricks"
size = 16
phi = 8
curvatures = 3
"""


@pytest.mark.parametrize("k,storage", [(4, "uint8"), ('"all"', "float32")])
def test_bake_writes_the_chosen_storage(tmp_path, k, storage):
    """k = 4 keeps 8-bit weights (4 bytes of W per texel and view); "all" (every eigenfunction, the
    truncation's error ~1e-5) keeps float32. The manifest records the error every storage adds."""
    from vdmbake.bake import bake

    (tmp_path / "s.toml").write_text(SCENE.replace("K", str(k)))
    bake(tmp_path / "s.toml", tmp_path / "b.bundle")
    b = Bundle(tmp_path / "b.bundle")
    meso = b.manifest["objects"]["t"]["techniques"]["vdm"]
    assert meso["storage"] == storage
    assert set(meso["storage_errors"]) == set(vdm_storage.FORMATS)
    parts = exr.read(b.read_bytes(meso["tables"]))
    n, kk = 16 * 16 * 8, meso["k"]
    e_bytes = 4 * kk * (8 * 3 + 3)
    assert meso["compressed_bytes"] == n * kk * vdm_storage.BYTES[storage] + e_bytes
    w = parts["W"]["W.000"]
    if storage == "uint8":
        assert w.dtype == np.uint32 and w.max() <= 255 and w.max() > 200
        assert parts["W_dequant"]["scale"].shape == (1, kk)
    else:
        assert w.dtype == np.float32 and "W_dequant" not in parts
    json.dumps(meso)                                                      # plain JSON values
