"""The timed part of bench.vdm.paper_bake, runnable against either tree."""
import json, os, sys, time
import numpy as np
from vdmbake.assets import heightfields
from vdmbake.kernels import vdm
tag = sys.argv[1]
load0 = os.getloadavg()[0]
h = heightfields.pattern("bricks", 128); depth = 0.06
s = vdm.Sampling(128, 32, 8, vdm.curvature_samples(-2.0, 3.0, 16))
c0 = time.process_time()
t0 = time.perf_counter(); flat, rays, scene = vdm.vdm_flat(h, depth, s); t1 = time.perf_counter()
c1 = time.process_time()
o, d = vdm.flat_rays(s, 1e-4 * depth); o, d = np.ascontiguousarray(o), np.ascontiguousarray(d)
c1b = time.process_time()
t2 = time.perf_counter(); scene.distances(o, d); t3 = time.perf_counter()
c2 = time.process_time()
del o, d
c3 = time.process_time()
t4 = time.perf_counter(); table, theta_mvm, _ = vdm.bake_tables(h, depth, s); t5 = time.perf_counter()
c4 = time.process_time()
vdm.compress(table, theta_mvm, 8); t6 = time.perf_counter()
c5 = time.process_time()
print(json.dumps({"tag": tag, "flat_s": round(t1 - t0, 3), "raw_s": round(t3 - t2, 3), "ratio": round((t3 - t2) / (t1 - t0), 3),
                  "tables_s": round(t5 - t4, 3), "svd_s": round(t6 - t5, 3), "bake_s": round(t6 - t4, 3),
                  "cpu_flat_s": round(c1 - c0, 3), "cpu_raw_s": round(c2 - c1b, 3), "cpu_tables_s": round(c4 - c3, 3), "cpu_svd_s": round(c5 - c4, 3), "cpu_bake_s": round(c5 - c3, 3), "load_before": round(load0, 2), "load_after": round(os.getloadavg()[0], 2)}), flush=True)
