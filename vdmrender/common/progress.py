"""Progress on long work (reference traces, variant renders and their scoring, benchmark runs): a tqdm
bar on stderr when stderr is a terminal; nothing otherwise, so logs and CI output keep only the
one line per finished step that the tools print anyway."""
from __future__ import annotations

import sys


def bar(items, desc: str, unit: str = "frame"):
    """`items`, iterated with a bar that disappears when done (the step's log line stays)."""
    if not sys.stderr.isatty():
        return items
    from tqdm import tqdm

    return tqdm(items, desc=desc, unit=unit, leave=False, file=sys.stderr, dynamic_ncols=True)
