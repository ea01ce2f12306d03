"""Multi-part EXR files through the OpenEXR 3.x `OpenEXR.File` API.

Each part is a name and a dict of 2-D channels; data channels get dotted names
(`depth.Z`, `normal.X`) so no tool mistakes them for colour. Works around the
binding's known pitfalls: every part gets the same explicit displayWindow (the
union of the part sizes), arrays are made contiguous, float64 is narrowed to
float32 explicitly, and 3-channel arrays are never passed whole (they would
become R/G/B); reading keeps channels separate (the binding would merge R, G, B, A).
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

_DTYPES = (np.float32, np.float16, np.uint32)


def _channel(name: str, a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != 2:
        raise ValueError(f"EXR channel {name!r} must be 2-D, got shape {a.shape}")
    if a.dtype == np.float64:
        a = a.astype(np.float32)
    if a.dtype.type not in _DTYPES:
        raise ValueError(f"EXR channel {name!r}: dtype {a.dtype} not storable (float32, float16 or uint32)")
    return np.ascontiguousarray(a)


def write(path: Path, parts: dict[str, dict[str, np.ndarray]], compression: str = "zip") -> None:
    """Write {part name: {channel name: 2-D array}} as one (multi-part if more than one) EXR file."""
    Path(path).write_bytes(to_bytes(parts, compression))


def to_bytes(parts: dict[str, dict[str, np.ndarray]], compression: str = "zip") -> bytes:
    """The EXR file `write` makes, as bytes."""
    import OpenEXR

    comp = {"zip": OpenEXR.ZIP_COMPRESSION, "none": OpenEXR.NO_COMPRESSION}[compression]
    parts = {p: {c: _channel(f"{p}/{c}", a) for c, a in chans.items()} for p, chans in parts.items()}
    for p, chans in parts.items():
        shapes = {a.shape for a in chans.values()}
        if len(shapes) != 1:
            raise ValueError(f"EXR part {p!r}: channels differ in size {sorted(shapes)}")
    sizes = [next(iter(c.values())).shape for c in parts.values()]
    hmax, wmax = max(s[0] for s in sizes), max(s[1] for s in sizes)
    display = (np.array([0, 0], np.int32), np.array([wmax - 1, hmax - 1], np.int32))
    out = []
    for (name, chans), (h, w) in zip(parts.items(), sizes):
        header = {"compression": comp, "type": OpenEXR.scanlineimage, "displayWindow": display,
                  "dataWindow": (np.array([0, 0], np.int32), np.array([w - 1, h - 1], np.int32))}
        out.append(OpenEXR.Part(header, chans, name=name))
    buf = io.BytesIO()
    with OpenEXR.File(out) as f:
        f.write(buf)
    return buf.getvalue()


# Zip (deflate) and every other EXR compression expand data at most about 1032-fold; a channel holds at
# least 2 bytes a pixel (half). A header claiming more pixels than that is not a file this package wrote.
MAX_EXPANSION = 2100


def check_size(data: bytes) -> None:
    """Refuse, from the headers alone, an EXR whose parts claim more pixels than its bytes can hold
    (e.g. a damaged header saying 2^30 x 2^30), before any pixel is decoded."""
    import OpenEXR

    with OpenEXR.File(io.BytesIO(data), header_only=True) as f:
        pixels = 0
        for p in f.parts:
            lo, hi = p.header["dataWindow"]
            w, h = int(hi[0]) - int(lo[0]) + 1, int(hi[1]) - int(lo[1]) + 1
            if w <= 0 or h <= 0:
                raise ValueError(f"part {p.name()!r}: empty data window {w} x {h}")
            pixels += w * h
    if 2 * pixels > MAX_EXPANSION * len(data) + (1 << 20):
        raise ValueError(f"its headers claim {pixels} pixels, more than {len(data)} bytes can hold")


def read(source: Path | bytes) -> dict[str, dict[str, np.ndarray]]:
    """{part name: {channel name: 2-D array}} for every part of an EXR file, or of its bytes."""
    import OpenEXR

    src = io.BytesIO(source) if isinstance(source, bytes) else str(source)
    with OpenEXR.File(src, separate_channels=True) as f:
        return {p.name(): {c: np.array(ch.pixels) for c, ch in p.channels.items()} for p in f.parts}
