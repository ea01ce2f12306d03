# Run from the repository root: .venv/bin/python docs/trust-scripts/golden_margins.py
import sys, tempfile
from pathlib import Path
import numpy as np
sys.path.insert(0, "tests")
import test_golden as g
for scene in g.SCENES:
    old = g.stored(scene)
    with tempfile.TemporaryDirectory() as t:
        new = g.render(Path(t), (g.GOLDEN / f"{scene}.toml").read_text())
    with tempfile.TemporaryDirectory() as t:
        text = (g.GOLDEN / f"{scene}.toml").read_text()
        dark = g.render(Path(t), text.replace("[camera]", "[light]\ncolor = [0.97, 0.97, 0.97]\n[camera]", 1))
    for key, img in old.items():
        sh = np.concatenate([img[:, :1], img[:, :-1]], 1); sh[:, 0] = img[0, 0]
        f = lambda d: "IoU %.4f mean %.3f above %.3f" % (d["iou"], d["mean"], d["above"])
        print(f"{scene}/{key}: same [{f(g.difference(new[key], img))}]  shift [{f(g.difference(sh, img))}]  darker [{f(g.difference(dark[key], img))}]  cov {(img[...,3]>0).mean():.3f}")
