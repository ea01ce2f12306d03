"""make bench: the slow measurements (out/bench), never asserted and not shipped: they drive the baker and
the renderer from outside, one module per benchmark (python -m bench.NAME) plus interleaved A/B timing."""
