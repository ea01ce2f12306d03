"""Deciding from measured rows, without drawing (no GL is imported here): `pricing` (which of two timings is
cheaper: paired log-ratios and their confidence interval), `lod` (LOD chains per band of screen sizes, pops,
hysteresis, the price on a field of copies) and `baseline` (this run against an earlier report; the exit code)."""
