"""How the VDM's eigenfunction weights W are stored (Wang2003 §3.3, where 8 eigenfunctions
of 128^2 x 32 weights make the paper's 4 MB: one byte per weight). Formats: float32; float16; uint8
codes with a per-eigenfunction scale and offset (weight = code * scale + offset). The bake keeps the
smallest format whose rounding leaves the reconstruction's RMS error within TOLERANCE of the SVD
truncation's own. The error a format adds is measured exactly without rebuilding the tables: for
the rounding error dW, ||dW E^T||_F^2 = trace((E^T E) (dW^T dW)), two k x k matrices.

Shapes as vdm.Compressed: W (..., k), E_vdm (k, n_theta, n_c), E_mvm (k, n_c).
"""
from __future__ import annotations

import numpy as np

FORMATS = ("uint8", "float16", "float32")       # smallest first
BYTES = {"uint8": 1, "float16": 2, "float32": 4}
TOLERANCE = 0.05    # a format may raise the RMS of d and of theta_MVM by this fraction (errors add in quadrature)


def quantise(W: np.ndarray, fmt: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(stored, scale, offset), scale and offset per eigenfunction (the last axis); the weights are
    stored * scale + offset. uint8 spans each eigenfunction's range with 256 codes."""
    k = W.shape[-1]
    if fmt == "float32":
        return W.astype(np.float32), np.ones(k, np.float32), np.zeros(k, np.float32)
    if fmt == "float16":
        return W.astype(np.float16), np.ones(k, np.float32), np.zeros(k, np.float32)
    if fmt != "uint8":
        raise ValueError(f"unknown W storage {fmt!r}; one of {FORMATS}")
    flat = W.reshape(-1, k)
    lo, hi = flat.min(0).astype(np.float32), flat.max(0).astype(np.float32)
    scale = ((hi - lo) / np.float32(255)).astype(np.float32)
    safe = np.where(scale > 0, scale, np.float32(1))
    codes = np.clip(np.rint((W - lo) / safe), 0, 255).astype(np.uint8)
    return codes, scale, lo


def dequantise(stored: np.ndarray, scale: np.ndarray, offset: np.ndarray) -> np.ndarray:
    return (stored.astype(np.float32) * scale + offset).astype(np.float32)


def added_rms(dW: np.ndarray, E_vdm: np.ndarray, E_mvm: np.ndarray) -> tuple[float, float]:
    """RMS over every entry of A_VDM and of A_MVM (the -1 entries of A_VDM hold the MVM angle, as in
    the SVD) of the change dW E^T that a change dW of the weights makes."""
    k = dW.shape[-1]
    d = dW.reshape(-1, k).astype(np.float64)
    G = d.T @ d
    out = []
    for E in (E_vdm.reshape(k, -1), E_mvm.reshape(k, -1)):
        E = E.astype(np.float64)
        out.append(float(np.sqrt(max(np.sum(G * (E @ E.T)), 0.0) / (len(d) * E.shape[1]))))
    return out[0], out[1]


def storage_errors(W: np.ndarray, E_vdm: np.ndarray, E_mvm: np.ndarray) -> dict[str, dict]:
    """The RMS error each format adds to d (texture units) and to theta_MVM (radians)."""
    out = {}
    for fmt in FORMATS:
        stored, scale, offset = quantise(W, fmt)
        rms_vdm, rms_mvm = added_rms(dequantise(stored, scale, offset) - W, E_vdm, E_mvm)
        out[fmt] = {"rms_vdm": rms_vdm, "rms_mvm": rms_mvm}
    return out


def choose(errors: dict[str, dict], rms_vdm: float, rms_mvm: float) -> str:
    """The smallest format whose added error, in quadrature with the truncation's (rms_vdm, rms_mvm),
    raises neither by more than TOLERANCE."""
    def within(added, own):
        return np.hypot(own, added) <= (1 + TOLERANCE) * own
    for fmt in FORMATS:
        e = errors[fmt]
        if within(e["rms_vdm"], rms_vdm) and within(e["rms_mvm"], rms_mvm):
            return fmt
    return "float32"
