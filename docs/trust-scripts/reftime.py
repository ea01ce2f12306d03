# Run from the repository root: .venv/bin/python docs/trust-scripts/reftime.py configs/molecule-4jsv.toml
"""Reference trace time, old walk (start at tmin) vs fixed (start reach before), interleaved."""
import time, statistics, numpy as np
from vdmbake.scene import load_scene
from vdmbake.bake import object_quadrics
from pathlib import Path
from vdmrender import reference
from vdmrender.camera import cameras_for
import sys
scene = load_scene(sys.argv[1]); obj = scene.objects[0]
q, _ = object_quadrics(obj, Path(sys.argv[1]).parent)
c, r = q.bounding_sphere()
cams = cameras_for(scene.camera, c, r, 512, 384)
ref = reference.QuadricReference(q, scene.light, obj.material)
reach = ref.tracer.reach
res = {"old": [], "new": []}
imgs = {}
for rep in range(3):
    for mode in ("old", "new"):
        ref.tracer.reach = 0.0 if mode == "old" else reach
        t = time.perf_counter(); im = [ref.render(cam) for cam in cams]; res[mode].append(time.perf_counter() - t)
        imgs[mode] = im
print({k: round(statistics.median(v), 3) for k, v in res.items()}, "ratio", statistics.median(res["new"]) / statistics.median(res["old"]))
for a, b in zip(imgs["old"], imgs["new"]):
    print("pixels differing:", int((np.abs(a - b).max(-1) > 1e-6).sum()), "of", a.shape[0] * a.shape[1])
