"""The pictures for people stay readable (issue 12): error_vs_time.png puts one panel per object in a grid of
at most three columns, with every label inside the figure; the overview sheet's label column fits the
longest label."""
from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw

from vdmrender.common import images
from vdmrender.reporting import report

LABELS = ["mesh", "coarse@0.1", "billboards@greedy-hier+coarse", "billboards@greedy-improved+coarse"]


def rows(objects: int) -> list[dict]:
    """Each object: its variants spread over time and error, the longest label at the slowest point (where
    a label written to the right of its point runs off a panel at the figure's right edge)."""
    out = []
    for k in range(objects):
        for i, label in enumerate(LABELS):
            tech, _, value = label.partition("@")
            out.append({"object": f"object-{k}", "technique": tech, "label": label, "value": value or None,
                        "median_ms": 10.0 * 3 ** i, "mean_dluv": [0.02, 0.9, 0.7, 0.3][i]})
    return out


def test_error_plot_is_a_grid_with_every_label_inside():
    for n, shape in ((1, (1, 1)), (3, (1, 3)), (8, (3, 3))):
        fig = report.figure({"rows": rows(n), "resolution": [512, 512], "device": "llvmpipe"})
        fig.canvas.draw()
        axes = fig.get_axes()
        assert len(axes) == n
        grid = axes[0].get_subplotspec().get_gridspec().get_geometry()
        assert grid == shape
        width, height = fig.get_size_inches()
        assert width <= 3 * 5.6 + 1e-9 and height <= shape[0] * 4.4 + 1e-9
        box = fig.bbox
        renderer = fig.canvas.get_renderer()
        texts = [t for ax in axes for t in ax.texts]
        assert len(texts) == n * len(LABELS)
        for t in texts:
            e = t.get_window_extent(renderer)
            assert box.x0 <= e.x0 and e.x1 <= box.x1 and box.y0 <= e.y0 and e.y1 <= box.y1, t.get_text()
        import matplotlib.pyplot as plt
        plt.close(fig)


def test_overview_label_column_fits_the_longest_label(tmp_path):
    """A label longer than the old fixed 150-pixel column ends left of the first image."""
    label = "billboards@greedy-improved+coarse error"
    tile = np.full((32, 32, 4), 255, np.uint8)     # white images: any text pixel over them would not show
    images.overview([("reference", [tile]), (label, [tile])], tmp_path / "o.png", tile=32)
    sheet = np.asarray(Image.open(tmp_path / "o.png"))
    width = ImageDraw.Draw(Image.new("RGB", (1, 1))).textlength(label)
    assert width > 150
    first_image = sheet.shape[1] - 32 - images.GUTTER
    assert first_image >= width + 6 and (sheet[images.GUTTER, first_image:first_image + 32] == 255).all()
    top = 2 * images.GUTTER + 32   # the second row
    band = sheet[top:top + 32, :first_image]
    text_columns = np.flatnonzero((band > 128).any(axis=(0, 2)))
    assert text_columns.max() < first_image - 2 and text_columns.max() - text_columns.min() >= width - 8


def test_overview_cells_apart_and_its_colour_scale_numbered(tmp_path):
    """Frames that fill their cell to the edge stay GUTTER apart from each other and from the sheet's edges; with
    heat_max, an inferno bar from 0 to heat_max under the rows with numbers under it."""
    tile = np.full((32, 32, 4), 255, np.uint8)
    images.overview([("reference", [tile, tile]), ("mesh error", [tile, tile])], tmp_path / "o.png", tile=32,
                    heat_max=8.0)
    sheet = np.asarray(Image.open(tmp_path / "o.png").convert("RGB")).astype(int)
    g, width = images.GUTTER, sheet.shape[1]
    x0 = width - 2 * (32 + g)   # the first column of images
    white = (sheet == 255).all(-1)
    rows_white = np.flatnonzero(white[:, x0 + 5])
    assert rows_white.min() == g and rows_white.max() < 2 * 32 + 2 * g + 1
    assert not white[g + 32:2 * g + 32, x0:].any()            # between the rows
    assert not white[:, x0 + 32:x0 + 32 + g].any()            # between the columns
    assert not white[:, width - g:].any() and not white[:g].any()   # around the sheet
    y = 2 * (32 + g) + g   # the scale's bar: inferno from black to pale yellow, left to right
    bar = sheet[y + 5, x0:x0 + 2 * 32 + g]
    ends = images.heatmap(np.array([0.0, 8.0]), 8.0)[:, :3]
    assert np.abs(bar[0] - ends[0]).max() <= 2 and np.abs(bar[-1] - ends[1]).max() <= 2
    assert (np.diff(bar.sum(-1)) >= -3).all()   # brightening along the bar
    numbers = sheet[y + 16:y + 30, x0 - 4:]
    lit = np.flatnonzero((numbers > 150).all(-1).any(0))
    assert len(lit) and lit.max() - lit.min() > 2 * 32   # "0" at the start of the bar to "8+" at its end
