"""What every part kind is (a name, a file suffix, pack and unpack, the metadata's schema) and the
checks the kinds share: unreadable or incomplete EXR tables, non-finite numbers, shapes that disagree
with the manifest, colour maps."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ...errors import InputError
from ...formats import exr
from ...schema import Integer, Invalid, Type, Vector


COUNT = Integer(0, 2**31 - 1)   # element counts: PLY and EXR index with 32-bit integers
EXTENT = 1e30   # scene units: a bounding sphere lies within this of the origin, its radius in [1 / EXTENT, EXTENT]


@dataclass(frozen=True)
class PartKind:
    name: str
    suffix: str
    pack: Callable[[Any], tuple[bytes, dict]]        # value -> (file bytes, manifest metadata)
    unpack: Callable[[bytes, dict, str], Any]        # (file bytes, manifest metadata, origin) -> value;
                                                     # checks the value against the metadata, finite numbers
                                                     # and index ranges, raising InputError
    meta: type | None = None                         # the metadata's schema (vdmbake.schema dataclass)


def channels(data: bytes, origin: str) -> dict[str, dict[str, np.ndarray]]:
    try:
        exr.check_size(data)
        return exr.read(data)
    except Exception as e:  # the binding raises RuntimeError and others for malformed files
        raise InputError(f"{origin}: unreadable EXR ({e}).") from None


def bad(origin: str, what: str):
    raise InputError(f"{origin}: {what}; the part does not match its manifest entry. Re-bake with vdmbake --force.")


def finite(origin: str, **arrays) -> None:
    for name, a in arrays.items():
        if a is not None and not np.isfinite(a).all():
            bad(origin, f"{name} holds NaN or Inf")


def check_extent(origin: str, centre, radius: float) -> None:
    """The one check of an object's size and place, wherever a bounding sphere is read: the geometry parts (mesh,
    quadrics, as the bake writes them and the renderer reads them) and the manifest's object entries. vdmrender
    places its cameras and clip planes around the sphere; beyond EXTENT (or under 1 / EXTENT) their distances
    and depth ranges overflow (or vanish in) the float32 the GL pipeline computes in."""
    centre = np.asarray(centre, np.float64)
    if not (np.isfinite(centre).all() and np.abs(centre).max() <= EXTENT and 1 / EXTENT <= radius <= EXTENT):
        with np.errstate(over="ignore", invalid="ignore"):   # rounding 1e308 overflows: shown as it is, no warning
            shown = np.where(np.abs(centre) < 1e300, np.round(centre, 6), centre).tolist()
        raise InputError(f"{origin}: the bounding sphere (centre {shown}, radius {radius:.6g}) "
                         f"is out of range: vdmrender draws objects within {EXTENT:g} of the origin, of radius "
                         f"{1 / EXTENT:g} to {EXTENT:g} scene units; scale or move the object (transform) or its "
                         "model.")


def is_rotation(m) -> bool:
    """Whether the 3x3 rows `m` are a right-handed orthonormal frame (to 1e-3: stored as JSON decimals)."""
    m = np.asarray(m, np.float64)
    with np.errstate(over="ignore", invalid="ignore"):   # entries near 1e308: not a rotation, no warning
        return bool(np.abs(m @ m.T - np.eye(3)).max() <= 1e-3 and np.linalg.det(m) > 0)


def check_shape(origin: str, name: str, a: np.ndarray, shape: tuple) -> None:
    if a.shape != shape:
        bad(origin, f"{name} has shape {a.shape}, expected {shape}")


def need(parts: dict, part: str, channels, origin: str) -> list[np.ndarray]:
    if part not in parts or any(c not in parts[part] for c in channels):
        raise InputError(f"{origin}: EXR part {part!r} with channels {', '.join(channels)} is missing.")
    return [parts[part][c] for c in channels]


class Matrix(Type):
    """rows x cols finite numbers, as nested lists."""

    def __init__(self, rows: int, cols: int):
        self.row, self.rows = Vector(cols), rows
        self.text = f"a list of {rows} rows of {cols} finite numbers"

    def parse(self, raw):
        if not isinstance(raw, list) or len(raw) != self.rows:
            raise Invalid
        return tuple(self.row.parse(r) for r in raw)


def albedo_channels(albedo: np.ndarray | None) -> dict:
    """A colour map as EXR channels: linear RGB in HALF, EXR's usual colour type (an 8-bit sRGB texture or
    vertex colour loses nothing visible there); none at all for an asset without colours."""
    return {} if albedo is None else {f"albedo.{c}": albedo[..., k].astype(np.float16) for k, c in enumerate("RGB")}


def albedo_meta(values) -> dict:
    """The manifest's `albedo: true` when the maps carry colour (left out otherwise: uncoloured parts unchanged)."""
    values = list(values)
    if any(a is not None for a in values) and any(a is None for a in values):
        raise ValueError("colour maps for some maps only")
    return {"albedo": True} if values and values[0] is not None else {}


def unpack_albedo(tables, name: str, meta, shape: tuple, origin: str) -> np.ndarray | None:
    if not meta.get("albedo"):
        return None
    a = np.stack(need(tables, name, [f"albedo.{c}" for c in "RGB"], origin), -1).astype(np.float32)
    check_shape(origin, f"{name} albedo", a, shape + (3,))
    finite(origin, **{f"{name} albedo": a})
    return a
