# Run from the repository root: .venv/bin/python docs/trust-scripts/inside.py OUTDIR
"""Stiff quadric cases: impostor against the fixed reference and against the old walk (reach = 0)."""
import sys
import numpy as np
from pathlib import Path
from vdmbake.bake import bake
from vdmrender.tracing import reference
from vdmrender.render import Options, run

HEAD = """[render]
resolution = [{w}, {h}]
repeats = 1
warmup = 0
shadow_map = 2048
[[camera.poses]]
eye = {eye}
target = {target}
fov_deg = {fov}
[[objects]]
name = "q"
"""
rng = np.random.default_rng(11)
def water_box(n=3, spacing=2.9):
    rows = []
    for i in range(n):
        for j in range(n):
            for k in range(n):
                o = (np.array([i, j, k]) - (n - 1) / 2) * spacing + rng.normal(scale=0.2, size=3)
                a = rng.normal(size=3); a /= np.linalg.norm(a)
                b = np.cross(a, rng.normal(size=3)); b /= np.linalg.norm(b)
                h1 = o + 0.96 * a
                h2 = o + 0.96 * (np.cos(np.radians(104.5)) * a + np.sin(np.radians(104.5)) * b)
                rows += [("OW", "O", o), ("HW1", "H", h1), ("HW2", "H", h2)]
    return rows

w = water_box()
sys.path.insert(0, "tests")
from test_molecules import pdb_text
base = Path(sys.argv[1]); base.mkdir(parents=True, exist_ok=True)
(base / "water.pdb").write_text(pdb_text([("HOH", i + 1, w[3 * i:3 * i + 3]) for i in range(len(w) // 3)]))
eye_w = [round(float(x), 4) for x in w[39][2] + 0.6 * (w[40][2] - w[39][2])]
CASES = {
 "inside-atom": (HEAD.format(w=96, h=72, eye="[0.261, 2.085, -0.044]", target="[0.054, 0.6345, 0.8745]", fov=90)
                 + 'molecule = "pkg:pdbfixer/tests/data/test.pdb"\nstyle = "spacefill"\n'),
 "inside-water-box": (HEAD.format(w=96, h=72, eye=str(eye_w), target="[0.0, 0.0, -5.0]", fov=90)
                 + f'molecule = "{base}/water.pdb"\nstyle = "spacefill"\n'),
 "inside-cylinder": (HEAD.format(w=96, h=72, eye="[0.05, 0.0, 0.2]", target="[0.5, 0.3, 3.0]", fov=90)
                 + "spheres = [[0, 0, -3, 0.5], [0, 0, 3, 0.5], [2.0, 1.0, 0.0, 0.8]]\n"
                 + "cylinders = [[0, 0, -3, 0, 0, 3, 0.3], [0, 0, 3, 2.0, 1.0, 0.0, 0.2]]\n"),
 "inside-bond-licorice": (HEAD.format(w=96, h=72, eye="[0.96, -9.7, -3.46]", target="[0.054, 0.6345, 0.8745]", fov=90)
                 + 'molecule = "pkg:pdbfixer/tests/data/test.pdb"\nstyle = "licorice"\n'),
}
TECH = 'techniques = { impostor = { shading = ["direct", "deferred"] }, tessellated = { levels = [3] } }\n'
orig = reference.QuadricTracer.__init__
def old_init(self, q):
    orig(self, q); self.reach = 0.0
for name, text in CASES.items():
    d = base / name; d.mkdir(parents=True, exist_ok=True)
    (d / "s.toml").write_text(text + TECH)
    bake(d / "s.toml", d / "b.bundle")
    for mode in ("fixed", "old"):
        reference.QuadricTracer.__init__ = orig if mode == "fixed" else old_init
        rep = run(d / "b.bundle", d / f"out-{mode}", Options(flip=False))
        print(name, mode, {r["label"]: (r["mean_dluv"], r["iou"], r["coverage"]) for r in rep["rows"]}, flush=True)
    reference.QuadricTracer.__init__ = orig
