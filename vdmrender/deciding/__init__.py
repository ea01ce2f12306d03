"""Deciding from measured rows, without drawing (no GL is imported here, tests/test_layout.py): `pricing` (the one
statistic for timing noise: when one time is more than another, by the paired log-ratios of frames timed side by
side and their confidence interval, or by separately timed medians and their spreads), `lod` (LOD chains per band
of screen sizes, pops, hysteresis, the price on a field of copies) and `baseline` (this run against an earlier
report; the exit code)."""
