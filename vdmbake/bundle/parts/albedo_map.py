"""Albedo maps (an asset's base-colour texture, a mesostructure tile's colour): 8-bit sRGB PNG."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...common import texture
from ...errors import InputError
from ...schema import REQUIRED, Integer, setting
from .kind import PartKind, bad


@dataclass(frozen=True)
class AlbedoMapMeta:
    width: int = setting(REQUIRED, Integer(1, 65536), "texels per row")
    height: int = setting(REQUIRED, Integer(1, 65536), "rows")


def _pack_albedo_map(a: np.ndarray):
    """8-bit sRGB PNG, as the asset's texture was (no precision lost), top row first as viewers expect."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(a[::-1]), "RGB").save(buf, "PNG", optimize=False, compress_level=6)
    return buf.getvalue(), {"width": a.shape[1], "height": a.shape[0]}


def _unpack_albedo_map(data, meta, origin) -> np.ndarray:
    import io

    from PIL import Image

    try:
        image = Image.open(io.BytesIO(data), formats=["PNG"])
        if image.mode != "RGB" or image.size != (meta["width"], meta["height"]):
            bad(origin, f"a {image.mode} PNG of {image.size[0]}x{image.size[1]} where an RGB one of "
                         f"{meta['width']}x{meta['height']} was written")
        return texture.from_image(image)
    except InputError:
        raise
    except Exception as e:  # PIL raises many types for damaged files
        raise InputError(f"{origin}: unreadable PNG ({type(e).__name__}: {e}).") from None


ALBEDO_MAP = PartKind("albedo-map", ".png", _pack_albedo_map, _unpack_albedo_map, AlbedoMapMeta)
