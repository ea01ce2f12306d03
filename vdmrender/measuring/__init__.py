"""Measuring one variant: `measure` is the harness every row goes through (time, counters, frames read back),
`timing` the timer queries after a warm-up and the time budget, `interleaved` the one loop that times alternatives
side by side (the sweep's pricing, the benchmarks), `antialias` the frames as shipped (MSAA and supersampled targets
and their resolve), `counters` the device-independent cost counters."""
