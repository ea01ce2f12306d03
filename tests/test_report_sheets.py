"""The pictures for people stay readable (issue 12): error_vs_time.png puts one panel per object in a grid of
at most three columns, with every label inside the figure; the overview sheet's label column fits the
longest label."""
from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw

from vdmrender import images, report

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
    first_image = sheet.shape[1] - 32
    assert first_image >= width + 6
    band = sheet[32:64, :first_image]
    text_columns = np.flatnonzero((band > 128).any(axis=(0, 2)))
    assert text_columns.max() < first_image - 2 and text_columns.max() - text_columns.min() >= width - 8
