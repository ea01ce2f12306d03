import time, sys
from vdmbake import primitives, displace, heightfields as hf
t = primitives.torus(1.0, 0.35, 256, 64); h = hf.pattern("bricks", 128)
lv = 3
c = time.process_time(); d = displace.displaced(t, h, 0.06, (16, 4), lv); print(sys.argv[1], "levels", lv, "faces", len(d.faces), "cpu s", round(time.process_time() - c, 2))
