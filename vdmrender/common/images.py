"""Pictures for people: frames, error heat maps and a per-object overview sheet (PNG)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

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


GUTTER = 8   # px between the cells of a sheet and around them: an object that reaches its frame's edge stays apart


def overview(rows: list[tuple[str, list[np.ndarray]]], path: Path, tile: int = 192, heat_max: float | None = None
             ) -> None:
    """A labelled sheet: one row per (label, images), one column per frame, images scaled so their shorter
    side is `tile` (cells keep the frames' aspect), GUTTER apart; the label column as wide as the longest label.
    With heat_max, the heat maps' colour scale under the rows, numbered from 0 to heat_max ΔLuv."""
    cols = max(len(imgs) for _, imgs in rows)
    h, w = next(imgs[0].shape[:2] for _, imgs in rows if imgs)
    tw, th = (round(tile * w / h), tile) if w >= h else (tile, round(tile * h / w))
    measure = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    margin = max(150, 12 + int(np.ceil(max(measure.textlength(label) for label, _ in rows))))
    scale = 40 if heat_max else 0   # the colour scale's strip
    sheet = Image.new("RGB", (margin + GUTTER + cols * (tw + GUTTER), GUTTER + len(rows) * (th + GUTTER) + scale),
                      BACKDROP)
    draw = ImageDraw.Draw(sheet)
    for r, (label, imgs) in enumerate(rows):
        y = GUTTER + r * (th + GUTTER)
        draw.text((6, y + th // 2 - 6), label, fill=INK)
        for c, img in enumerate(imgs):
            im = Image.fromarray(np.ascontiguousarray(img[..., :3]))
            im.thumbnail((tw, th))
            sheet.paste(im, (margin + GUTTER + c * (tw + GUTTER), y))
    if heat_max:
        colour_scale(sheet, margin + GUTTER, sheet.height - scale, min(256, cols * tw + (cols - 1) * GUTTER), heat_max)
    sheet.save(path)


BACKDROP, INK = (24, 24, 28), (235, 235, 235)


def colour_scale(sheet: Image.Image, x: int, y: int, width: int, heat_max: float) -> None:
    """The heat maps' inferno scale, `width` px long at (x, y), with 0, a quarter, ... heat_max ΔLuv under it and its
    name left of it."""
    bar = heatmap(np.linspace(0.0, heat_max, width)[None, :].repeat(10, 0), heat_max)
    sheet.paste(Image.fromarray(np.ascontiguousarray(bar[..., :3])), (x, y))
    draw = ImageDraw.Draw(sheet)
    draw.font = scale_font()
    draw.text((6, y - 2), "heat maps: ΔLuv", fill=INK)
    for k in range(5):
        v, px = heat_max * k / 4, x + round((width - 1) * k / 4)
        draw.line([(px, y + 10), (px, y + 14)], fill=INK)
        s = f"{v:g}" + ("+" if k == 4 else "")
        tw = draw.textlength(s)
        draw.text((min(max(px - tw / 2, x), x + width - tw), y + 16), s, fill=INK)


def scale_font() -> ImageFont.FreeTypeFont:
    """matplotlib's own DejaVu Sans (PIL's default font has no Δ), so the scale reads the same on every machine."""
    from matplotlib import font_manager

    return ImageFont.truetype(font_manager.findfont("DejaVu Sans", fallback_to_default=False), 11)
