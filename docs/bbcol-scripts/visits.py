"""Per covered pixel of the colour scene's hier+coarse frames: the hierarchical march's cell visits (one
pyramid texelFetch each, COUNT build of billboard_hier.frag), against which the colour map adds one
bilinear RGB16F fetch at the hit.

    PYTHONPATH=. python docs/bbcol-scripts/visits.py OUT/colour.bundle
"""
import sys
from pathlib import Path

import numpy as np

from vdmbake import parts
from vdmbake.bundle import Bundle
from vdmrender import gl
from vdmrender.camera import cameras_for
from vdmrender.techniques.billboards_hier import HierBillboards

bundle = Bundle(Path(sys.argv[1]))
scene = bundle.scene
ctx = gl.create_context()
for obj in scene.objects:
    entry = bundle.manifest["objects"][obj.name]
    part = entry["techniques"]["billboards"]
    cams = cameras_for(scene.camera, entry["centre"], entry["radius"], *scene.render.resolution)
    coarse = bundle.surface(entry, part["coarse"])
    r = HierBillboards(ctx, bundle.read(part["greedy"]["maps"], parts.BILLBOARDS),
                       bundle.read(part["greedy"]["bordered"], parts.BORDERED), scene.light, obj.material,
                       scene.render.shadow_map, coarse, (entry["centre"], entry["radius"]), shadow_mesh=coarse, count=True)
    target = gl.Target(ctx, *scene.render.resolution)
    visits, hits = [], []
    for cam in cams:
        r.render(cam, target)
        f = target.read()
        visits.append(f[f[..., 2] > 0, 0])
        hits.append(f[f[..., 2] > 0, 3])
    v, h = np.concatenate(visits), np.concatenate(hits)
    print(f"{obj.name}: {len(v)} traced pixels, cell visits mean {v.mean():.1f}, median {np.median(v):.0f}; "
          f"{h.mean():.3f} of them hit a billboard (one colour fetch each)")
    r.release()
    target.release()
