"""Scenes shared by the end-to-end tests of the mesostructure techniques (test_vdm_render.py,
test_relief_render.py): small cameras, base surfaces and one object "p" with a mesostructure, and a
render helper that checks every frame is finite and prints the figures the bounds come from; and the files the
mesostructure fixes' tests write (a real elevation map, 16-bit PNGs, OBJs as exporters write them)."""
from __future__ import annotations

import json

import numpy as np
from PIL import Image

from vdmbake.assets import primitives
from vdmrender.comparing.metrics import delta_luv

from scenes import bake_and_render, rows_by_label

HEAD = """\
[render]
resolution = [{res}, {res}]
repeats = 1
warmup = 0
shadow_map = {shadow_map}
"""
# Cameras. TOP: straight down on the plane's centre; with an odd resolution the centre pixel's ray
# is the normal itself (theta_V = 0). The up vector must not be parallel to the view.
TOP = "[camera]\nup = [0, 1, 0]\n[[camera.poses]]\neye = [0, 0, 1.5]\ntarget = [0, 0, 0]\nfov_deg = 40\n"
# Head-on at a cylinder's side: V = N along the middle column, where the surface is curved (k = 1 / r).
HEAD_ON = "[camera]\nup = [0, 0, 1]\n[[camera.poses]]\neye = [3, 0, 0]\ntarget = [0, 0, 0]\nfov_deg = 40\n"
# Oblique, the plane filling the frame (no plane edge in view, so no silhouette pixels: the error
# is the mesostructure's alone).
OBLIQUE = "[camera]\nup = [0, 0, 1]\n[[camera.poses]]\neye = [0.2, -0.6, 0.6]\ntarget = [0, 0, 0]\nfov_deg = 35\n"
# 2.5 degrees above an 8 x 8 plane at its centre: theta_V from 72.8 (bottom row) to 88.5 degrees (far
# edge); of the 1248 plane pixels at 48^2, 23 % are above 85 degrees, 27 % beyond the last theta sample.
GRAZING = "[camera]\nup = [0, 0, 1]\n[[camera.poses]]\neye = [0, -4.5, 0.2]\ntarget = [0, 0, 0]\nfov_deg = 30\n"
ORBIT = "[camera]\norbit = {{ count = {count}, elevation_deg = 30 }}\n"

PLANE = 'primitive = "plane"\nparams = { size = 2.0, segments = 8 }'
BIG_PLANE = 'primitive = "plane"\nparams = { size = 8.0, segments = 16 }'
TORUS = 'primitive = "torus"\nparams = { segments = 64, rings = 32 }'
CYLINDER = 'primitive = "cylinder"\nparams = { radius = 0.5, height = 2.0, segments = 64, rings = 8, caps = 0 }'

def scene(camera, obj, techniques, height="bricks", depth=0.06, tiling=(2, 2), size=16, phi=16, theta=8,
          curvatures=4, res=48, light="", shadow_map=256):
    return (HEAD.format(res=res, shadow_map=shadow_map) + camera + light
            + f'[[objects]]\nname = "p"\n{obj}\ntechniques = {{ {techniques} }}\n'
            + f'[objects.mesostructure]\nheight = "{height}"\nsize = {size}\ndepth = {depth}\n'
            + f"tiling = [{tiling[0]}, {tiling[1]}]\nphi = {phi}\ntheta = {theta}\ncurvatures = {curvatures}\n")


def render(tmp_path, text):
    """Bake and render (no FLIP score: no mesostructure test looks at it); every row's frames must be finite
    everywhere (a NaN or Inf in the float target anywhere, even in a discarded or background pixel, counts)."""
    r, out = bake_and_render(tmp_path, text, "--no-flip")
    assert r.exit_code == 0, r.output
    rows = rows_by_label(r)
    for label, row in rows.items():   # the figures the bounds come from (pytest -s shows them)
        print(f"{label:>12}: mean {row['mean_dluv']:.3f}  p95 {row['p95_dluv']:.3f}  IoU {row['iou']:.4f}")
    for label, row in rows.items():
        assert row["nonfinite"] == 0, f"{label}: {row['nonfinite']} non-finite pixels"
    return rows, out


def manifest(tmp_path) -> dict:
    return json.loads((tmp_path / "b.bundle" / "manifest.json").read_text())


def mean(rows, label):
    return rows[label]["mean_dluv"]


def centre_dluv(out, label):
    """delta-Luv of the centre pixel of frame 0 against the reference (odd resolutions)."""
    ref = np.asarray(Image.open(out / "reference/p/000.png"))[..., :3]
    img = np.asarray(Image.open(out / f"frames/p/{label}/000.png"))[..., :3]
    c = ref.shape[0] // 2
    return float(delta_luv(img[c:c + 1, c:c + 1], ref[c:c + 1, c:c + 1])[0, 0])


def dem() -> np.ndarray:
    """Elevation in metres (int16), row 0 the north (the top of the map, as matplotlib draws it)."""
    from matplotlib import cbook

    return np.asarray(cbook.get_sample_data("jacksboro_fault_dem.npz")["elevation"])


def write_png16(path, a: np.ndarray):
    im = Image.new("I;16", a.shape[::-1])
    im.frombytes(np.asarray(a, "<u2").tobytes())
    im.save(path)


def write_obj(path, v, uv, f_v, f_uv):
    """An OBJ as exporters write it: unique positions, unique UVs, faces index both (v/vt)."""
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in v] + [f"vt {a:.17g} {b:.17g}" for a, b in uv]
    lines += [" ".join(["f"] + [f"{i + 1}/{j + 1}" for i, j in zip(fv, ft)]) for fv, ft in zip(f_v, f_uv)]
    path.write_text("\n".join(lines) + "\n")


def torus_obj(tmp_path, segments=24, rings=12):
    """The torus primitive as an exporter writes it: one position per point of the surface, UVs split
    at the u = 0 / 1 and v = 0 / 1 seams (so trimesh's loader splits those vertices)."""
    t = primitives.torus(1.0, 0.35, segments, rings)
    grid = np.arange(len(t.vertices)).reshape(rings + 1, segments + 1)
    pos_id = grid.copy()
    pos_id[:, -1] = pos_id[:, 0]                               # phi = 2 pi is phi = 0
    pos_id[-1, :] = pos_id[0, :]                               # t = 1 is t = 0
    used = np.unique(pos_id)
    remap = np.full(len(t.vertices), -1)
    remap[used] = np.arange(len(used))
    write_obj(tmp_path / "torus.obj", t.vertices[used], t.uvs, remap[pos_id.ravel()[t.faces]], t.faces)
    return tmp_path / "torus.obj"
