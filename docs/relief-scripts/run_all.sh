#!/bin/bash
# The four scenes at 512^2, one vdmrender run each (from the worktree root; bundles and runs in out/m).
# Then: error split and texture layouts. bench_interleaved.py (interleaved timing), ablations.py and
# make_figures.py (which plotted bench_interleaved's logs) were removed when ReliefPass's constructor
# changed under them; git history holds them at docs/relief-scripts/.
set -e
mkdir -p out/m
cp docs/relief-scripts/scenes/*.toml out/m/
for s in torus-bricks vase-bricks torus-gravel vase-gravel; do
  .venv/bin/vdmbake out/m/$s.toml -o out/m/$s.bundle
  .venv/bin/vdmrender out/m/$s.bundle -o out/m/r-$s
  .venv/bin/python docs/relief-scripts/error_split.py out/m/r-$s $s
done
.venv/bin/python docs/relief-scripts/bench_formats.py bricks
