"""Height fields for view-dependent displacement mapping (VDM, Wang et al. 2003).

A height field is a (size, size) float64 array in [0, 1]: 1 is the top (the reference
surface the VDM is baked against), 0 the deepest point. Rows are v, columns u; texel
(i, j) sits at the texel centre ((j + 0.5) / size, (i + 0.5) / size) of the unit tile.
Row 0 is therefore v = 0, which in OBJ / glTF texture coordinates (as trimesh gives them) is the
bottom of the picture: image files, whose first row is the picture's top, are flipped on loading,
so every consumer (the bake, displacement, the GL upload, whose first row is t = 0) indexes [v, u].

Normalisation (one rule for every file, `depth` the only scale): the stored values are mapped
to [0, 1] by their own min / max, the lowest point to 0 and the highest to 1, whatever the format
(8- or 16-bit PNG, grey or colour, float EXR in any unit). The file's numeric range (bit depth,
metres or feet, an offset) is not a second scale: `depth` alone is the peak-to-valley height of
the mesostructure. A constant image is all ones (no relief).

Three sources:
- `pattern`: procedural, tileable test materials in the manner of the classic VDM / parallax
  occlusion mapping examples (bricks, a basket weave, bumps, a stiff "cliffs" case, flat).
  They are evaluated at texel centres from functions with period 1, so every tile repeats
  seamlessly; nothing is random (the brick-top variation is a fixed sum of sines).
- `load_image`: an 8/16-bit PNG or a float EXR from disk.
- `skimage_photo`: one of the CC0 surface photographs that ship inside the scikit-image wheel.
  These are photographs, not tiles: their opposite edges do not match.

Resampling (`size` given to the loaders) is a separable, periodic tent (bilinear) filter whose
footprint widens with the reduction factor when shrinking, so shrinking averages instead of
skipping texels, and the borders wrap around rather than clamp.
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np

from vdmbake.errors import InputError

PATTERNS = ("bricks", "weave", "bumps", "cliffs", "flat")

MIN_SIZE, MAX_SIZE = 2, 4096

# Rec. 709 luma weights, applied to the stored (non-linearised) values.
REC709 = (0.2126, 0.7152, 0.0722)

# Surface photographs shipped inside the scikit-image wheel (skimage/data/, no pooch download):
# name -> (file, provenance). All three are 512 x 512 8-bit grey, CC0.
SKIMAGE_PHOTOS = {
    "brick": ("brick.png", "CC0Textures Bricks25, CC0"),
    "gravel": ("gravel.png", "CC0Textures Gravel04, CC0"),
    "grass": ("grass.png", "DeviantArt linolafett 'Grass 01', CC0"),
}
# The optional-dependency group of the vdmbake package that brings scikit-image in.
SKIMAGE_EXTRA = "photos"

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
_EXR_MAGIC = b"\x76\x2f\x31\x01"


# --------------------------------------------------------------------------- sizes


def _check_size(size, where: str) -> int:
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)):
        raise InputError(f"{where}: size {size!r} is not an integer (allowed: {MIN_SIZE} to {MAX_SIZE})")
    if not MIN_SIZE <= int(size) <= MAX_SIZE:
        raise InputError(f"{where}: size {size} is out of range (allowed: {MIN_SIZE} to {MAX_SIZE})")
    return int(size)


def _centres(size: int) -> np.ndarray:
    """Texel-centre coordinates in [0, 1) of one axis."""
    return (np.arange(size) + 0.5) / size


def _pdist(x: np.ndarray, c) -> np.ndarray:
    """Distance from x to c on the unit circle (period 1)."""
    d = np.mod(x - c, 1.0)
    return np.minimum(d, 1.0 - d)


# --------------------------------------------------------------------------- patterns

BRICK_TOP_VARIATION = 0.06  # brick tops of `bricks` vary within [1 - this, 1] (vdmbake.assets.meso_albedo colours them)


def _bricks(size: int) -> np.ndarray:
    # Running bond, two courses per tile; each brick is one tile wide and half a tile high
    # (2:1), the upper course is offset by half a brick, so a tiled wall has the usual bond.
    mortar_half = 0.02  # flat mortar floor: 4 % of the tile across each joint
    bevel = 0.03  # linear ramp from the mortar floor to the brick top
    amp = BRICK_TOP_VARIATION
    u = _centres(size)[None, :]
    v = _centres(size)[:, None]
    course = np.floor(v * 2.0).astype(int) % 2  # 0: v in [0, .5), 1: v in [.5, 1)
    d_horiz = _pdist(v * 2.0, 0.0) / 2.0  # to the bed joints at v = 0 and v = 0.5
    d_vert = _pdist(u - 0.5 * course, 0.0)  # to the head joint of the course
    d = np.minimum(d_horiz, d_vert)
    ramp = np.clip((d - mortar_half) / bevel, 0.0, 1.0)
    # Surface variation: a fixed (seeded) handful of low-frequency sines with integer
    # frequencies, so it repeats with the tile; normalised to [0, 1].
    rng = np.random.default_rng(20030727)  # fixed seed: the pattern never changes
    var = np.zeros((size, size))
    total = 0.0
    for _ in range(5):
        fu, fv = rng.integers(1, 4, size=2)
        a = rng.uniform(0.5, 1.0)
        phase = rng.uniform(0.0, 2.0 * math.pi)
        var += a * (0.5 + 0.5 * np.sin(2.0 * math.pi * (fu * u + fv * v) + phase))
        total += a
    top = 1.0 - amp * (var / total)
    return ramp * top


def _weave(size: int) -> np.ndarray:
    # Basket weave: 4 groups of 2 parallel strands per tile in each direction; a horizontal
    # group goes over a vertical group where (row group + column group) is even and under it
    # otherwise. Each strand has a cosine cross-section (0 at its edges, 1 on its axis) and a
    # cosine undulation along its length (full height over a crossing, `low` under one).
    groups, per_group = 4, 2  # groups must be even for the over/under to repeat with the tile
    fill = 0.85  # fraction of a strand's lane it covers; the rest is a gap at 0
    low = 0.5
    lanes = groups * per_group
    u = _centres(size)
    v = _centres(size)

    def cross(x):  # cosine cross-section of the strands whose lanes tile the axis
        lane_pos = np.mod(x * lanes, 1.0) - 0.5  # -0.5..0.5 across a lane
        inside = np.abs(lane_pos) < 0.5 * fill
        return np.where(inside, np.cos(np.pi * lane_pos / fill), 0.0)  # exact 0 in the gaps

    def group(x):
        return np.floor(x * groups).astype(int) % groups

    # Along a horizontal strand of row group k: elevation 1 over column group j when j + k even.
    s = u * groups - 0.5  # crossing centres at integer s
    k = group(v)[:, None]
    elev_h = 0.5 + 0.5 * np.cos(np.pi * (s[None, :] + k))
    t = v * groups - 0.5
    j = group(u)[None, :]
    elev_v = 0.5 - 0.5 * np.cos(np.pi * (t[:, None] + j))
    h_horiz = cross(v)[:, None] * (low + (1.0 - low) * elev_h)
    h_vert = cross(u)[None, :] * (low + (1.0 - low) * elev_v)
    return np.clip(np.maximum(h_horiz, h_vert), 0.0, 1.0)


def _bumps(size: int) -> np.ndarray:
    # 4 x 4 hemispheres per tile on a flat base at 0; radius 0.45 of a cell, height 1.
    n, r = 4, 0.45
    u = _centres(size)
    cu = _pdist(u * n, 0.5)  # distance to the nearest cell centre, in cells
    d2 = cu[None, :] ** 2 + cu[:, None] ** 2
    return np.sqrt(np.clip(1.0 - d2 / (r * r), 0.0, 1.0))


def _cliffs(size: int) -> np.ndarray:
    # A square plateau at 1 on a floor at 0 with vertical walls (0 to 1 between adjacent
    # texels), kept off the seam, and a one-texel-wide slot down to 0 through its middle.
    h = np.zeros((size, size))
    a = max(1, size // 4)
    b = size - a
    h[a:b, a:b] = 1.0
    if b - a >= 3:  # room for a slot with plateau on both sides
        c = size // 2
        r0 = a + (b - a) // 4
        r1 = max(r0 + 1, b - (b - a) // 4)
        h[r0:r1, c] = 0.0
    return h


_MAKERS = {
    "bricks": _bricks,
    "weave": _weave,
    "bumps": _bumps,
    "cliffs": _cliffs,
    "flat": lambda size: np.ones((size, size)),
}


def pattern(name: str, size: int) -> np.ndarray:
    """(size, size) float64 heights in [0, 1], 1 = top (the reference surface), 0 = deepest.
    Periodic: the tile repeats seamlessly (the value at column 0 continues column size-1)."""
    if name not in _MAKERS:
        raise InputError(f"height pattern {name!r} is unknown (allowed: {', '.join(PATTERNS)})")
    size = _check_size(size, f"height pattern {name!r}")
    h = np.asarray(_MAKERS[name](size), dtype=np.float64)
    return np.clip(h, 0.0, 1.0)


# --------------------------------------------------------------------------- resampling


def _resample_axis(a: np.ndarray, n_out: int, axis: int) -> np.ndarray:
    """Periodic tent-filter resampling of one axis (bilinear when enlarging, a tent of the
    reduction factor's width when shrinking). Texel centres map to texel centres."""
    n_in = a.shape[axis]
    if n_in == n_out:
        return a.copy()
    ratio = n_in / n_out
    width = max(1.0, ratio)  # tent half-width in input texels
    x = (np.arange(n_out) + 0.5) * ratio - 0.5  # output centres in input texel coordinates
    lo = np.floor(x - width).astype(int) + 1
    taps = math.ceil(2.0 * width) + 1
    k = lo[:, None] + np.arange(taps)[None, :]
    w = np.clip(1.0 - np.abs(k - x[:, None]) / width, 0.0, None)
    w /= w.sum(axis=1, keepdims=True)
    k %= n_in
    a = np.moveaxis(a, axis, 0)
    out = np.zeros((n_out,) + a.shape[1:])
    for t in range(taps):
        out += w[:, t].reshape((-1,) + (1,) * (a.ndim - 1)) * a[k[:, t]]
    return np.moveaxis(out, 0, axis)


def resample(h: np.ndarray, size: int) -> np.ndarray:
    """(size, size) periodic tent-filtered resampling of a 2-D height field."""
    h = np.asarray(h, dtype=np.float64)
    return _resample_axis(_resample_axis(h, size, 0), size, 1)


# --------------------------------------------------------------------------- files

MAX_PIXELS = 16384 * 16384   # the largest height map file, PNG or EXR alike (checked from its header)


def _check_pixels(path: Path, width: int, height: int) -> None:
    if width * height > MAX_PIXELS:
        raise InputError(f"{path}: a height map of {width} x {height} pixels, more than the {MAX_PIXELS} "
                         "(16384 x 16384) accepted; scale it down (the bake resamples it to mesostructure.size).")


def _png_stored(path: Path) -> np.ndarray:
    """Luminance of a PNG in its stored units (grey value over its bit depth's full scale), rows top to bottom."""
    from PIL import Image

    try:
        Image.MAX_IMAGE_PIXELS = None   # PIL's own "decompression bomb" limit: ours applies to PNG and EXR alike
        with Image.open(path) as im:
            _check_pixels(path, *im.size)
            im.load()
            mode = im.mode
            if mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
                # 16-bit grey (Pillow may hand it over as 32-bit 'I'): full scale is 65535.
                return np.asarray(im).astype(np.float64) / 65535.0
            if mode in ("1", "L", "LA", "La"):
                return np.asarray(im.convert("L")).astype(np.float64) / 255.0
            # Colour (Pillow reads 16-bit colour PNGs at 8-bit precision), palette and the rest:
            # Rec. 709 weights on the stored 8-bit values; alpha ignored.
            rgb = np.asarray(im.convert("RGB")).astype(np.float64) / 255.0
    except InputError:
        raise
    except Exception as e:  # PIL raises OSError, SyntaxError, ValueError, DecompressionBombError...
        raise InputError(f"{path}: unreadable PNG ({e}); allowed: an 8- or 16-bit grey, RGB or RGBA PNG") from e
    return rgb @ np.array(REC709)


def _exr_height(path: Path) -> np.ndarray:
    from vdmbake.formats import exr

    try:
        import OpenEXR

        with OpenEXR.File(str(path), header_only=True) as f:
            for part in f.parts:
                lo, hi = part.header["dataWindow"]
                _check_pixels(path, int(hi[0] - lo[0]) + 1, int(hi[1] - lo[1]) + 1)
        parts = exr.read(path)
    except InputError:
        raise
    except Exception as e:
        raise InputError(f"{path}: unreadable EXR ({e}); allowed: a float EXR with a Y, R or single channel") from e
    found = None
    for chans in parts.values():
        for want in ("Y", "R"):
            if want in chans:
                found = chans[want]
                break
        if found is None and len(chans) == 1:
            found = next(iter(chans.values()))
        if found is not None:
            break
    if found is None:
        names = sorted(f"{p}/{c}" for p, chans in parts.items() for c in chans)
        raise InputError(f"{path}: no height channel among {names} (allowed: one named Y or R, or a part with a single channel)")
    h = np.asarray(found, dtype=np.float64)
    if h.ndim != 2 or h.size == 0:
        raise InputError(f"{path}: height channel has shape {h.shape}, not a 2-D image")
    bad = ~np.isfinite(h)
    if bad.any():
        raise InputError(f"{path}: {int(bad.sum())} texels are NaN or infinite (allowed: finite heights only)")
    return h


def _normalised(h: np.ndarray) -> np.ndarray:
    """The one normalisation rule (module docstring): min / max to [0, 1], constant -> all ones."""
    lo, hi = float(h.min()), float(h.max())
    return np.ones_like(h) if hi <= lo else (h - lo) / (hi - lo)


def _finish(h: np.ndarray, size: int | None, where: str) -> np.ndarray:
    """Normalise, turn picture rows (top first) into v rows (v = 0 first), check or resample the size."""
    h = _normalised(h)[::-1]
    if size is None:
        if h.shape[0] != h.shape[1]:
            raise InputError(f"{where}: image is {h.shape[1]} x {h.shape[0]}, not square "
                             f"(allowed: a square image, or give a size to resample to)")
        _check_size(h.shape[0], where)
        out = h.astype(np.float64, copy=True)
    else:
        size = _check_size(size, where)
        out = resample(h, size)
    return np.clip(out, 0.0, 1.0)


def load_image(path: Path, size: int | None) -> np.ndarray:
    """A height field from an image: 8-bit or 16-bit PNG (grey, or RGB/RGBA converted to luminance
    with Rec. 709 weights on the stored values), or a float EXR (first channel named Y, R or the only one;
    use vdmbake.formats.exr.read which returns {part: {channel: 2-D array}}). Normalised to [0, 1] by the data's
    min / max, whatever the format (constant -> all ones), and flipped so row 0 is v = 0 (the picture's
    bottom), as the module docstring says.
    `size`: resample to size x size with a periodic (wrap-around) bilinear filter, or keep the native
    size if None (non-square images are refused unless size is given)."""
    path = Path(path)
    if size is not None:
        _check_size(size, str(path))
    if not path.exists():
        raise InputError(f"{path}: no such file (allowed: a PNG or EXR height map)")
    if not path.is_file():
        raise InputError(f"{path}: not a file (allowed: a PNG or EXR height map)")
    try:
        with open(path, "rb") as f:
            magic = f.read(8)
    except OSError as e:
        raise InputError(f"{path}: cannot be read ({e})") from e
    if magic.startswith(_PNG_MAGIC):
        h = _png_stored(path)
    elif magic.startswith(_EXR_MAGIC):
        h = _exr_height(path)
    else:
        raise InputError(f"{path}: unreadable image: neither PNG nor OpenEXR (allowed: an 8- or 16-bit PNG, or a float EXR)")
    return _finish(h, size, str(path))


def skimage_file(name: str, catalogue: dict, where: str) -> Path:
    """The file of photo `name` of `catalogue` ({name: (file, provenance)}) inside the installed
    scikit-image wheel's skimage/data folder (nothing is ever downloaded). Raise InputError naming the
    allowed names if the name is unknown, and the extra to install if scikit-image is missing."""
    if name not in catalogue:
        raise InputError(f"{where} is unknown (allowed: {', '.join(catalogue)})")
    try:
        spec = importlib.util.find_spec("skimage")
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.submodule_search_locations:
        raise InputError(f"{where}: scikit-image is not installed (install the '{SKIMAGE_EXTRA}' extra: "
                         f"pip install 'vdmbake[{SKIMAGE_EXTRA}]', or pip install scikit-image)")
    file = catalogue[name][0]
    for loc in spec.submodule_search_locations:
        path = Path(loc) / "data" / file
        if path.is_file():
            return path
    raise InputError(f"{where}: {file} is not in this scikit-image installation's skimage/data "
                     f"(allowed: {', '.join(catalogue)}, from a scikit-image wheel)")


def skimage_photo(name: str, size: int | None) -> np.ndarray:
    """Real photographs bundled with scikit-image (e.g. 'brick', 'gravel', 'grass'): luminance as height,
    normalised and oriented as every image file (load_image). Raise InputError naming the extra to install if
    scikit-image is missing, and naming the allowed photo names if the name is unknown (skimage_file)."""
    where = f"scikit-image photo {name!r}"
    path = skimage_file(name, SKIMAGE_PHOTOS, where)
    return _finish(_png_stored(path), size, f"{where} ({path})")


def from_spec(spec: str, size: int, base: Path) -> np.ndarray:
    """A scene's `height`: a pattern name, skimage:NAME, or an image path (relative to `base`, or
    pkg:PACKAGE/PATH), as a (size, size) height field."""
    if spec in PATTERNS:
        return pattern(spec, size)
    if spec.startswith("skimage:"):
        return skimage_photo(spec.partition(":")[2], size)
    from .meshes import resolve_path

    return load_image(resolve_path(spec, base), size)

