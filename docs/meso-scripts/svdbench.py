"""compress(k = 8) of the paper's table alone: python svdbench.py TAG [TABLE.npy MVM.npy] (bakes them if not given).
Run with OPENBLAS_NUM_THREADS=1 on a loaded machine: spinning BLAS threads otherwise swamp the figure."""
import json, sys, time
import numpy as np
from vdmbake.assets import heightfields
from vdmbake.kernels import vdm
if len(sys.argv) > 3:
    t, m = np.load(sys.argv[2]), np.load(sys.argv[3])
else:
    s = vdm.Sampling(128, 32, 8, vdm.curvature_samples(-2.0, 3.0, 16))
    t, m, _ = vdm.bake_tables(heightfields.pattern("bricks", 128), 0.06, s)
c0 = time.process_time(); w0 = time.perf_counter(); vdm.compress(t, m, 8)
print(json.dumps({"tag": sys.argv[1], "svd_wall": round(time.perf_counter() - w0, 3), "svd_cpu": round(time.process_time() - c0, 3)}), flush=True)
