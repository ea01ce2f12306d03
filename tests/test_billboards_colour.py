"""Colour maps (issue 12): assets with their own colours through the billboards (thesis sec. 3.1: each
billboard's colour map, read at the hit, sec. 3.3 step 2.3) and the octahedral impostors (an albedo atlas),
on pymeshlab's textured 10k bunny (an albedo map at UVs: a UV test card) and vertex-coloured airplane.
Every method is scored against the coloured reference, and against the same frames rendered from the same
bake with the colour maps left out (the material's albedo, as before issue 12), which must be far worse.
Bounds sit a little above the values measured on llvmpipe (in comments: 64x64 frames, 2 orbit frames, billboard maps of 64^2, an atlas of 9 x 9 views of 64^2)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from vdmbake.kernels import billboard_maps, billboards, coarse, octahedral
from vdmbake.bundle import parts
from vdmbake.assets.meshes import load_mesh_file, resolve_path
from vdmbake.common.mesh import TriMesh
from vdmrender.common.camera import orbit
from vdmrender.techniques.billboards import Billboards
from vdmrender.techniques.billboards_hier import HierBillboards
from vdmrender.techniques.octahedral import Octahedral

from frames import LIGHT, MATERIAL, draw, score

ASSETS = {"bunny": ("pkg:pymeshlab/tests/sample_meshes/bunny10k_textured.obj", [0.0, 1.0, 0.0]),
          "airplane": ("pkg:pymeshlab/tests/sample_meshes/colored_airplane.ply", [0.0, 1.0, 0.0])}
SIZE, RES, SHADOW = 64, 64, 512
_cache: dict = {}


def asset(name: str):
    """The mesh, and its bakes as the bundle stores them: billboards with colour maps, their bordered maps
    with pyramids, the coarse mesh at 10% (colours and UVs carried; the albedo map attached) and an
    octahedral atlas of 9 x 9 views of 64^2 texels with albedo."""
    if name not in _cache:
        pytest.importorskip("pymeshlab")   # a test extra: only its sample meshes are used
        spec, up = ASSETS[name]
        m = load_mesh_file(resolve_path(spec, Path(".")))
        boards = parts.stored(parts.BILLBOARDS, billboards.bake(m, billboards.Settings(resolution=RES)).billboards)
        maps = parts.stored(parts.BORDERED, [billboard_maps.bordered(b, True) for b in boards])
        c = parts.stored(parts.MESH, coarse.simplify(m, 0.1))
        c.texture = m.texture if c.uvs is not None else None
        atlas = parts.stored(parts.OCTAHEDRAL, octahedral.to_part(octahedral.bake(m, octahedral.Settings(9, 64), up)))
        centre, radius = m.bounding_sphere()
        cams = orbit(SimpleNamespace(count=2, elevation_deg=25, azimuth_deg=30, distance=2.4, fov_deg=40), up,
                     centre, radius, SIZE, SIZE)
        _cache[name] = SimpleNamespace(mesh=m, boards=boards, maps=maps, coarse=c, atlas=atlas, cams=cams,
                                       bounds=(centre, radius))
    return _cache[name]


def renderer(ctx, a, method: str, colour: bool):
    """One method's renderer of asset a, with its colour (maps, coarse mesh's colours) or without."""
    maps = a.maps if colour else [replace(m, albedo=None) for m in a.maps]
    plain = a.coarse if colour else TriMesh(a.coarse.vertices, a.coarse.faces, a.coarse.normals)
    if method == "hier+coarse":
        return HierBillboards(ctx, a.boards, maps, LIGHT, MATERIAL, SHADOW, plain, a.bounds, shadow_mesh=a.coarse)
    if method == "improved+coarse":
        return Billboards(ctx, a.boards, maps, LIGHT, MATERIAL, SHADOW, "improved", coarse=plain, bounds=a.bounds)
    if method == "thesis":
        return Billboards(ctx, a.boards, maps, LIGHT, MATERIAL, SHADOW, "thesis", 0.01, bounds=a.bounds)
    return Octahedral(ctx, a.atlas if colour else replace(a.atlas, albedo=None), LIGHT, MATERIAL, SHADOW)


# Mean dLuv bound with colour: measured with colour / without (the material's albedo) in the comments. Most of
# what is left is the texture's detail finer than a map texel (the bunny's UV test card has thin lines): at
# 128x128 with maps of 1024^2, hier+coarse measures 0.78 / 0.90 (bunny), 0.45 / 1.05 (airplane) per frame.
# The thesis's 100-step march leaves holes (sec. 3.4) and misses thin parts.
BOUNDS = {
    ("bunny", "hier+coarse"): 6.7,         # 5.81 / 37.3 (6.35 with a coarse mesh without UVs)
    ("bunny", "improved+coarse"): 6.9,     # 6.00 / 37.5 (6.28 likewise)
    ("bunny", "thesis"): 13.4,             # 11.65 / 38.2
    ("bunny", "octahedral"): 7.5,          # 6.52 / 37.1
    ("airplane", "hier+coarse"): 7.4,      # 6.44 / 47.5
    ("airplane", "improved+coarse"): 4.4,  # 3.84 / 48.9
    ("airplane", "thesis"): 8.4,           # 7.34 / 48.7
    ("airplane", "octahedral"): 8.2,       # 7.11 / 48.8
}
RATIO = 0.4   # the colour maps cut the error at least this much (measured ratios 0.08 to 0.31; 1 without them)


@pytest.mark.parametrize("name, method", list(BOUNDS))
def test_colour_against_the_coloured_reference(ctx, name, method):
    a = asset(name)
    errors = {}
    for colour in (True, False):
        errors[colour] = float(np.mean([score(draw(renderer(ctx, a, method, colour), cam), a.mesh, cam)[0]
                                        for cam in a.cams]))
    assert errors[True] < BOUNDS[(name, method)] and errors[True] < RATIO * errors[False], errors


def test_maps_hold_colour_only_for_coloured_assets():
    """The bunny's billboards and atlas without its albedo map: the same geometry, so the same bytes as the
    coloured bake's parts with their colour left out; no albedo channels and no `albedo` metadata."""
    a = asset("bunny")
    m = a.mesh
    plain = TriMesh(m.vertices, m.faces, m.normals, m.uvs)
    boards = billboards.bake(plain, billboards.Settings(resolution=RES)).billboards
    assert all(b.albedo is None for b in boards)
    for kind, value, coloured in (
            (parts.BILLBOARDS, boards, [replace(b, albedo=None) for b in a.boards]),
            (parts.BORDERED, [billboard_maps.bordered(b, True) for b in boards], [replace(b, albedo=None) for b in a.maps]),
            (parts.OCTAHEDRAL, octahedral.to_part(octahedral.bake(plain, octahedral.Settings(9, 64), ASSETS["bunny"][1])),
             replace(a.atlas, albedo=None))):
        data, meta = kind.pack(value)
        assert "albedo" not in meta and b"albedo" not in data
        assert (data, meta) == kind.pack(coloured)
        assert b"albedo.R" in kind.pack(a.boards if kind is parts.BILLBOARDS else a.maps if kind is parts.BORDERED
                                        else a.atlas)[0]


# the command line last: its own GL context leaves the module's context no longer current
@pytest.mark.slow
def test_textured_scene_to_report(tmp_path):
    """Scene -> bundle -> report for the textured bunny: the billboards' parts carry colour maps, the atlas
    its albedo, and every variant is scored against the textured reference."""
    import json

    from scenes import bake_and_render, rows_by_label

    pytest.importorskip("pymeshlab")
    scene = ('[render]\nresolution = [48, 48]\nrepeats = 1\nwarmup = 0\nshadow_map = 512\n'
             '[camera]\nup = [0, 1, 0]\norbit = { count = 1, elevation_deg = 25, distance = 2.4 }\n'
             f'[[objects]]\nname = "bunny"\nmesh = "{ASSETS["bunny"][0]}"\n'
             'techniques = { billboards = { variants = ["greedy-hier+coarse", "greedy-improved+coarse"], '
             'resolution = 48 }, octahedral = { variants = ["full-9x64-march"] } }\n')
    result, out = bake_and_render(tmp_path, scene, "--no-flip")
    assert result.exit_code == 0, result.output
    rows = rows_by_label(result)
    # measured at 48x48 (maps 48^2, atlas 9 x 64^2): hier+coarse 7.66, improved+coarse 7.19, octahedral 6.17
    assert rows["billboards@greedy-hier+coarse"]["mean_dluv"] < 8.8
    assert rows["billboards@greedy-improved+coarse"]["mean_dluv"] < 8.3
    assert rows["octahedral@full-9x64-march"]["mean_dluv"] < 7.1
    manifest = json.loads((tmp_path / "b.bundle" / "manifest.json").read_text())
    entry = manifest["objects"]["bunny"]["techniques"]
    assert manifest["parts"][entry["billboards"]["greedy"]["maps"]]["albedo"]
    assert manifest["parts"][entry["billboards"]["greedy"]["bordered"]]["albedo"]
    assert manifest["parts"][entry["octahedral"]["full-9x64"]]["albedo"]
