"""Old vs new per-curvature resampling and MVM, interleaved in one process (A, B, A, B, ...)."""
import time, types, statistics, numpy as np
from vdmbake.assets import heightfields
from vdmbake.kernels import vdm as new
src = open("/tmp/meso/old/vdmbake/vdm.py").read().replace("from .embree import", "from vdmbake.common.embree import")
import sys; old = types.ModuleType("old_vdm"); sys.modules["old_vdm"] = old; exec(compile(src, "old_vdm", "exec"), old.__dict__)
h = heightfields.pattern("bricks", 128); depth = 0.06
s = new.Sampling(128, 32, 8, new.curvature_samples(-2.0, 3.0, 16))
flat, _, _ = new.vdm_flat(h, depth, s)
g = new.hit_geometry(flat, s)
res = {"old": [], "new": []}
for rep in range(3):
    for c in (-1.0, 2.5):
        t0 = time.process_time(); a = old.vdm_curved(flat, s, c); res["old"].append(time.process_time() - t0)
        t0 = time.process_time(); b = new.vdm_curved(flat, s, c, g); res["new"].append(time.process_time() - t0)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
mo, mn = statistics.median(res["old"]), statistics.median(res["new"])
print(f"vdm_curved per curvature: old {mo:.3f} s, new {mn:.3f} s (medians of 6), ratio new/old {mn/mo:.2f}")
