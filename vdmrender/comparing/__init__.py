"""Comparing frames: `metrics` (CIE Luv difference, p95, coverage IoU, FLIP, and how rows are pooled),
`scoring` (each frame against the filtered and point references, heat maps, the reference's own noise) and
`change` (each row against its object's full asset drawn the same way, and the floor)."""
