#!/bin/bash
# old / new interleaved, fresh process each
for i in 1 2 3; do
  (cd /tmp && OPENBLAS_NUM_THREADS=1 PYTHONPATH=/tmp/meso/old /work/wt-meso/.venv/bin/python /work/wt-meso/docs/meso-scripts/bakebench.py old)
  (cd /work/wt-meso && OPENBLAS_NUM_THREADS=1 PYTHONPATH=/work/wt-meso .venv/bin/python /work/wt-meso/docs/meso-scripts/bakebench.py new)
done
