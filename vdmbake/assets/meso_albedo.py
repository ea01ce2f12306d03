"""A mesostructure's colour tile (`[objects.mesostructure] albedo`): the albedo map that repeats with the
height field, as every textured figure of the VDM paper (Wang2003 Fig. 9) has one.

The tile is an albedo map as vdmbake.common.texture defines it ((H, W, 3) uint8 sRGB, row 0 at v = 0, the
picture's bottom, as height fields) spanning one tile of texture space: the mesostructure techniques and
the reference read it at a point's tile coordinate T = uv * tiling, wrapping, bilinear without mipmaps
(vdmbake.common.texture.sample). It keeps its own resolution; it need not be square (it is stretched over the
tile). Three sources, as for the height (vdmbake.assets.heightfields.from_spec):
- a built-in colouring of a height pattern: `bricks` colours the `bricks` pattern's bricks and mortar
  from its heights (the mortar floor light grey, brick tops red-brown, varying with the tops' relief);
- `skimage:NAME`: a photo inside the scikit-image wheel, the grey surface photos the heights use or
  a colour one (SKIMAGE_COLOUR);
- an image file any 8-bit format Pillow reads (PNG, JPEG, ...; 16-bit grey PNG scaled to 8 bits), as
  sRGB, alpha dropped: a path relative to the scene or pkg:PACKAGE/PATH.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import heightfields
from ..common import texture
from ..common.colour import srgb8_to_linear, to_srgb8
from ..errors import InputError

# Colour photographs inside the scikit-image wheel (skimage/data/, never downloaded): name -> (file, provenance).
SKIMAGE_COLOUR = {
    "coffee": ("coffee.png", "Rachel Michetti, CC0"),
    "chelsea": ("chelsea.png", "Stefan van der Walt, CC0"),
    "astronaut": ("astronaut.png", "NASA, public domain"),
    "rocket": ("rocket.jpg", "SpaceX, public domain"),
}
SKIMAGE_NAMES = {**heightfields.SKIMAGE_PHOTOS, **SKIMAGE_COLOUR}

# `bricks`: sRGB8 colours of the mortar and of the brick tops at their lowest and highest, per course.
MORTAR = (186, 180, 168)
BRICKS = (((118, 46, 34), (172, 76, 52)),     # course 0 (v in [0, 1/2)): dark, light
          ((134, 58, 38), (186, 96, 60)))     # course 1


def _bricks(size: int) -> np.ndarray:
    """The `bricks` height pattern at `size` coloured from its heights: the mortar floor (0) to the brick
    top (1 - BRICK_TOP_VARIATION and above) blends mortar to brick over the bevel, and on the tops the
    brick's colour follows their relief (lighter where higher); the two courses differ in hue."""
    h = heightfields.pattern("bricks", size)
    top = 1.0 - heightfields.BRICK_TOP_VARIATION
    brick = np.clip(h / top, 0.0, 1.0)[..., None]                                       # 0 mortar .. 1 brick
    relief = np.clip((h - top) / heightfields.BRICK_TOP_VARIATION, 0.0, 1.0)[..., None]  # on the tops
    course = (np.floor((np.arange(size) + 0.5) / size * 2.0).astype(int) % 2)[:, None]  # rows are v
    dark, light = (srgb8_to_linear(np.asarray(BRICKS)[course, i]) for i in (0, 1))        # (size, 1, 3)
    lin = (1 - brick) * srgb8_to_linear(MORTAR) + brick * ((1 - relief) * dark + relief * light)
    return to_srgb8(lin)


_MAKERS = {"bricks": _bricks}
PATTERNS = tuple(_MAKERS)


def load_image(path: Path) -> np.ndarray:
    """An image file as an albedo map (vdmbake.common.texture.from_image), refused with a clear message where
    Pillow cannot read it or it is larger than texture.MAX_PIXELS."""
    from PIL import Image

    try:
        Image.MAX_IMAGE_PIXELS = None   # our own limit applies, with a message that says what to do
        with Image.open(path) as im:
            if im.size[0] * im.size[1] > texture.MAX_PIXELS:
                raise InputError(f"{path}: an albedo picture of {im.size[0]} x {im.size[1]} pixels, more than the "
                                 f"{texture.MAX_PIXELS} (8192 x 8192) accepted; scale it down.")
            im.load()
            if im.mode in ("I", "I;16", "I;16B", "I;16L", "I;16N"):    # 16-bit grey: full scale 65535
                im = Image.fromarray(np.round(np.asarray(im, np.float64) / 257.0).clip(0, 255).astype(np.uint8))
            elif im.mode == "F":
                raise InputError(f"{path}: a floating-point picture; allowed: an 8-bit sRGB picture (PNG, JPEG)")
            return texture.from_image(im)
    except InputError:
        raise
    except Exception as e:  # PIL raises OSError, SyntaxError, ValueError, ... for what it cannot read
        raise InputError(f"{path}: unreadable picture ({type(e).__name__}: {e}); allowed: an 8-bit sRGB "
                         "picture Pillow reads (PNG, JPEG, ...)") from None


def from_spec(spec: str, size: int, base: Path) -> np.ndarray:
    """A scene's mesostructure `albedo` as an albedo map: a pattern coloured at the height's `size`,
    skimage:NAME, or a picture (relative to `base`, or pkg:PACKAGE/PATH) at its own resolution."""
    if spec in _MAKERS:
        return _MAKERS[spec](size)
    if spec.startswith("skimage:"):
        name = spec.partition(":")[2]
        return load_image(heightfields.skimage_file(name, SKIMAGE_NAMES, f"albedo: scikit-image photo {name!r}"))
    from .meshes import resolve_path

    return load_image(resolve_path(spec, base))
