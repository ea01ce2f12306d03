#!/bin/bash
# The four scenes at 512^2, one vdmrender run each (from the worktree root; bundles and runs in out/m).
# Then: interleaved timing, instrumented counts, error split, ablations, figures.
set -e
mkdir -p out/m
cp docs/relief-scripts/scenes/*.toml out/m/
for s in torus-bricks vase-bricks torus-gravel vase-gravel; do
  .venv/bin/vdmbake out/m/$s.toml -o out/m/$s.bundle
  .venv/bin/vdmrender out/m/$s.bundle -o out/m/r-$s
  .venv/bin/python docs/relief-scripts/bench_interleaved.py out/m/$s.bundle --rounds 6 --extra pomcull:16 32::FLAT \
    > out/m/timing2-$s.log
  .venv/bin/python docs/relief-scripts/error_split.py out/m/r-$s $s
done
.venv/bin/python docs/relief-scripts/ablations.py torus-bricks vase-bricks torus-gravel vase-gravel
.venv/bin/python docs/relief-scripts/bench_formats.py bricks
.venv/bin/python docs/relief-scripts/make_figures.py
