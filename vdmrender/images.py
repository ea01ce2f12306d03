"""Pictures for people: frames, error heat maps and a per-object overview sheet (PNG)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from vdmbake.common.colour import to_srgb8


def encode(linear_rgba: np.ndarray, background) -> np.ndarray:
    """(H, W, 4) linear float + coverage -> (H, W, 4) uint8 sRGB over the background, alpha = coverage (any
    coverage > 0 at least 1). The colour is premultiplied by coverage, as a box-filtered frame holds it (a GL
    frame's covered pixels have coverage 1): rgb + (1 - coverage) background."""
    alpha = np.clip(np.nan_to_num(linear_rgba[..., 3], nan=0.0), 0.0, 1.0)
    cov = alpha > 0
    rgb = np.where(cov[..., None], np.nan_to_num(linear_rgba[..., :3], nan=0.0, posinf=1.0, neginf=0.0)
                   + (1 - alpha[..., None]) * np.asarray(background, np.float32), np.asarray(background, np.float32))
    return np.concatenate([to_srgb8(rgb), np.ceil(alpha * 255).astype(np.uint8)[..., None]], -1)


def save_rgb(path: Path, rgba8: np.ndarray) -> None:
    Image.fromarray(np.ascontiguousarray(rgba8[..., :3])).save(path, optimize=False)


def heatmap(dist: np.ndarray, vmax: float) -> np.ndarray:
    """Per-pixel delta-Luv on the inferno colour map, 0 (black) to vmax (pale yellow), clipped."""
    from matplotlib import colormaps

    rgba = colormaps["inferno"](np.clip(dist / vmax, 0.0, 1.0))
    return (rgba * 255 + 0.5).astype(np.uint8)


def overview(rows: list[tuple[str, list[np.ndarray]]], path: Path, tile: int = 192) -> None:
    """A labelled sheet: one row per (label, images), one column per frame, images scaled so their shorter
    side is `tile` (cells keep the frames' aspect); the label column as wide as the longest label."""
    cols = max(len(imgs) for _, imgs in rows)
    h, w = next(imgs[0].shape[:2] for _, imgs in rows if imgs)
    tw, th = (round(tile * w / h), tile) if w >= h else (tile, round(tile * h / w))
    measure = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    margin = max(150, 12 + int(np.ceil(max(measure.textlength(label) for label, _ in rows))))
    sheet = Image.new("RGB", (margin + cols * tw, len(rows) * th), (24, 24, 28))
    draw = ImageDraw.Draw(sheet)
    for r, (label, imgs) in enumerate(rows):
        draw.text((6, r * th + th // 2 - 6), label, fill=(235, 235, 235))
        for c, img in enumerate(imgs):
            im = Image.fromarray(np.ascontiguousarray(img[..., :3]))
            im.thumbnail((tw, th))
            sheet.paste(im, (margin + c * tw, r * th))
    sheet.save(path)
