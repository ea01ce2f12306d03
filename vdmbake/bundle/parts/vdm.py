"""The SVD-compressed VDM and MVM tables (Wang2003 §3.3), one EXR."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...formats import exr
from ...schema import REQUIRED, Choice, Integer, setting
from .kind import PartKind, bad, channels, finite, need


@dataclass
class VDMTables:
    """d_VDM(x, y, phi, theta, c) ~ sum_i W[phi, y, x, i] E_vdm[i, c, theta] and theta_MVM(x, y, phi, c)
    ~ sum_i W[phi, y, x, i] E_mvm[i, c] (Wang2003 §3.3). x, y: texel centres of the tile; phi, theta: bin
    centres of [0, 2 pi) and [0, pi / 2]; c: the curvature samples listed in the manifest. d in
    texture units (extended d = l / sin(theta) on curved surfaces, Wang2003 Appendix), theta_MVM in radians.
    W is stored as float32, float16 or uint8 codes (vdmbake/kernels/vdm_storage.py): the weight is
    W * scale[i] + offset[i] (scale 1, offset 0 for floats)."""
    W: np.ndarray       # (n_phi, N, N, k) float32, float16 or uint8
    E_vdm: np.ndarray   # (k, n_c, n_theta) float32
    E_mvm: np.ndarray   # (k, n_c) float32
    scale: np.ndarray   # (k,) float32
    offset: np.ndarray  # (k,) float32


def _pack_vdm(t: VDMTables):
    n_phi, n, _, k = t.W.shape
    W = t.W.reshape(n_phi * n, n, k)        # rows: phi-major blocks of y
    codes = t.W.dtype == np.uint8           # EXR has no 8-bit channels: codes go in UINT ones (zipped, near a byte)
    tables = {"W": {f"W.{i:03d}": W[..., i].astype(np.uint32) if codes else W[..., i] for i in range(k)},
              "E_vdm": {f"E.{i:03d}": t.E_vdm[i] for i in range(k)},
              "E_mvm": {f"E.{i:03d}": t.E_mvm[i][None] for i in range(k)}}
    if codes:
        tables["W_dequant"] = {"scale": t.scale[None].astype(np.float32), "offset": t.offset[None].astype(np.float32)}
    return exr.to_bytes(tables), {"k": k, "n_phi": n_phi, "storage": str(t.W.dtype)}


def _unpack_vdm(data, meta, origin) -> VDMTables:
    parts = channels(data, origin)
    k, n_phi = int(meta["k"]), int(meta["n_phi"])
    W = np.stack(need(parts, "W", [f"W.{i:03d}" for i in range(k)], origin), -1)
    n = W.shape[1]
    E = [f"E.{i:03d}" for i in range(k)]
    if meta.get("storage") == "uint8":
        scale, offset = (a[0] for a in need(parts, "W_dequant", ["scale", "offset"], origin))
        W = W.astype(np.uint8)
    else:
        scale, offset = np.ones(k, np.float32), np.zeros(k, np.float32)
    E_vdm, E_mvm = np.stack(need(parts, "E_vdm", E, origin)), np.stack(need(parts, "E_mvm", E, origin))
    if W.shape[0] != n_phi * n or E_mvm.shape[1] != 1 or E_mvm.shape[2] != E_vdm.shape[1]:
        bad(origin, f"tables of shapes W {W.shape}, E_vdm {E_vdm.shape}, E_mvm {E_mvm.shape} for n_phi = {n_phi}")
    finite(origin, W=W, E_vdm=E_vdm, E_mvm=E_mvm, scale=scale, offset=offset)
    return VDMTables(W.reshape(n_phi, n, n, k), E_vdm, E_mvm[:, 0], scale, offset)


@dataclass(frozen=True)
class VDMMeta:
    k: int = setting(REQUIRED, Integer(1, 4096), "eigenfunctions stored")
    n_phi: int = setting(REQUIRED, Integer(1, 256), "azimuth samples")
    storage: str = setting(REQUIRED, Choice("float32", "float16", "uint8"), "the weights' format")


VDM = PartKind("vdm", ".exr", _pack_vdm, _unpack_vdm, VDMMeta)
