"""What every plot of a run shares: the error axis in words and readable ticks on a log axis."""
from __future__ import annotations

import math

# The plots' error axis in words (the mean over covered pixels of the per-pixel CIE L*u*v* colour difference).
ERROR_LABEL = "mean colour difference per pixel\nagainst the reference (CIE ΔE*uv)"


def log_ticks(ax, which: str) -> None:
    """Readable ticks on a log axis, as plain numbers (20, not 2×10¹): decades where the data span more than two
    and a half, 1, 2 and 5 per decade where they span one or more, and a few round steps within a narrower span
    (matplotlib's default labels every minor tick there, and they run together: "2.1×10²2.2×10²…")."""
    from matplotlib import ticker

    lo, hi = ax.get_xlim() if which == "x" else ax.get_ylim()
    span = math.log10(hi / lo)
    axis = ax.xaxis if which == "x" else ax.yaxis
    if span < 1:
        axis.set_major_locator(ticker.MaxNLocator(nbins=4, steps=[1, 2, 5, 10]))
    else:
        axis.set_major_locator(ticker.LogLocator(10, subs=(1.0, 2.0, 5.0) if span <= 2.5 else (1.0,), numticks=8))
    axis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(ticker.NullFormatter())
