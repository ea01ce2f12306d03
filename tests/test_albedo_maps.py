"""Albedo maps (issue 12): an asset's base-colour texture (OBJ map_Kd, glTF baseColorTexture) through
loading, the bundle, the `mesh`/`coarse` rasteriser and the reference, and carried through simplification
by UV transfer; on pymeshlab's textured bunny (its texture is a UV test card) and a UV-seamed torus."""
from __future__ import annotations

import json

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from scenes import bake_and_render
from vdmbake.kernels import coarse
from vdmbake.bundle import parts
from vdmbake.assets import primitives
from vdmbake.common import texture
from vdmbake.assets.meshes import load_mesh_file, resolve_path
from vdmbake.common.mesh import TriMesh, weld
from vdmbake.scene import Light, Material
from vdmrender.gpu import gl
from vdmrender.common import images
from vdmrender.comparing import metrics
from vdmrender.tracing import reference
from vdmrender.common.camera import orbit
from vdmrender.passes.raster import RasterMesh

BUNNY = "pkg:pymeshlab/tests/sample_meshes/bunny10k_textured.obj"
BG = (0.05, 0.05, 0.06)
RNG = np.random.default_rng(12)


def bunny() -> TriMesh:
    pytest.importorskip("pymeshlab")   # a test extra: only its sample meshes are used
    return load_mesh_file(resolve_path(BUNNY, Path(".")))


def test_sample_conventions():
    """Row 0 is v = 0; texel centres return the texel itself, decoded from sRGB; wrap-around."""
    amap = np.zeros((2, 2, 3), np.uint8)
    amap[0, 0] = 255                       # bottom-left texel white
    assert np.allclose(texture.sample(amap, np.array([[0.25, 0.25]])), 1.0)
    assert np.allclose(texture.sample(amap, np.array([[0.75, 0.75], [-0.25, 0.75]])), 0.0)
    assert np.allclose(texture.sample(amap, np.array([[1.25, 1.25], [-0.75, 2.25]])), 1.0)
    amap[0, 0] = 128
    assert np.allclose(texture.sample(amap, np.array([[0.25, 0.25]])), ((128 / 255 + 0.055) / 1.055) ** 2.4)
    assert np.allclose(texture.sample(amap, np.array([[0.0, 0.25]])), 0.5 * ((128 / 255 + 0.055) / 1.055) ** 2.4)


def test_obj_and_glb_load_the_same_albedo(tmp_path):
    """OBJ map_Kd is taken as it is; the same model written as GLB (trimesh) gives the same colour at every
    vertex (the glTF v flip undone), and glTF's baseColorFactor, a colour per vertex, multiplies the map."""
    import trimesh

    m = bunny()
    assert m.texture is not None and m.texture.shape == (512, 512, 3) and m.uvs is not None
    # the test card: its bottom-right quadrant is coloured, the others grey (texture row 0 = v = 0)
    spread = np.ptp(m.texture.astype(int), axis=2)          # 0 on grey texels
    assert spread[:256, 256:].mean() > 200 and spread[256:].mean() < 1
    t = trimesh.load(str(resolve_path(BUNNY, Path("."))), force="mesh")
    t.visual.material = t.visual.material.to_pbr()
    for factor, scale in ((np.array([255, 255, 255, 255], np.uint8), 1.0), (np.array([255, 128, 255, 255], np.uint8), 128 / 255)):
        t.visual.material.baseColorFactor = factor
        t.export(tmp_path / "b.glb")
        g = load_mesh_file(tmp_path / "b.glb")
        assert g.texture is not None
        want = texture.sample(m.texture, m.uvs)
        # the same vertices in another order: compare the colours at matching positions
        order_m, order_g = np.lexsort(m.vertices.T), np.lexsort(g.vertices.T)
        got = (texture.sample(g.texture, g.uvs) * (1.0 if g.colors is None else g.colors))[order_g]
        want = want[order_m] * np.array([1.0, scale, 1.0])
        assert np.abs(got - want).max() < 0.01, np.abs(got - want).max()


def test_obj_with_uvs_and_no_material_has_no_map(tmp_path):
    """trimesh gives an OBJ with UVs but no MTL a grey placeholder image: the material's albedo applies instead."""
    (tmp_path / "t.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    m = load_mesh_file(tmp_path / "t.obj")
    assert m.uvs is not None and m.texture is None


def test_bundle_stores_the_map_only_for_textured_assets():
    m = bunny()
    back = parts.stored(parts.ALBEDO_MAP, m.texture)
    np.testing.assert_array_equal(back, m.texture)
    with pytest.raises(Exception, match="PNG"):
        parts.ALBEDO_MAP.unpack(b"not a png", {"width": 1, "height": 1}, "x")


def cameras(m, n=2, size=96):
    centre, radius = m.bounding_sphere()
    return orbit(SimpleNamespace(count=n, elevation_deg=20, azimuth_deg=30, distance=2.6, fov_deg=40),
                 [0, 1, 0], centre, radius, size, size)


def scores(ctx, drawn: TriMesh, traced: list[TriMesh], cams) -> list[list[float]]:
    """Mean dLuv of `drawn` rasterised against each of the `traced` references, per camera."""
    light, material = Light(), Material()
    target = gl.Target(ctx, cams[0].width, cams[0].height)
    r = RasterMesh(ctx, drawn, light, material, 1024)
    refs = [reference.MeshReference(t, light, material) for t in traced]
    try:
        out = []
        for cam in cams:
            r.render(cam, target)
            frame = images.encode(target.read(), BG)
            out.append([metrics.compare(frame, images.encode(ref.render(cam), BG))["mean"] for ref in refs])
        return out
    finally:
        r.release()
        target.release()


def test_raster_matches_the_textured_reference(ctx):
    """`mesh` with the map against the textured reference: near-exact; against the untextured one far off."""
    m = bunny()
    plain = TriMesh(m.vertices, m.faces, m.normals)
    stored = parts.stored(parts.MESH, m)
    stored.texture = m.texture
    for good, bad in scores(ctx, stored, [m, plain], cameras(m)):
        # measured at 96 px: 0.103 / 0.154 against the textured reference, 38.2 / 36.0 against the plain one
        assert good < 0.3 and bad > 20, (good, bad)


def test_coarse_transfers_the_uv_charts():
    """A UV-seamed torus (one chart that wraps around both ways): every coarse corner's transferred UV is the
    analytic texture coordinate of its position (the torus's angles), on both sides of the seams; no face
    reads across a seam (its corners' UVs would span the whole square), and the geometry stays closed."""
    m = primitives.torus(1.0, 0.35, 64, 32)
    m.texture = np.zeros((4, 4, 3), np.uint8)
    # measured (max, 99th percentile, mean): 0.5: 0.0095, 0.00068, 0.00030; 0.1: 0.072, 0.0059, 0.00067; the
    # maxima are corners beyond a seam, where the nearest face's chart is continued linearly across a tube
    # that curves (taking the origin face's UV map alone gave 0.0098 / 0.14 max, 0.0014 / 0.0076 mean)
    for ratio, bounds in ((0.5, (0.015, 0.001, 0.0005)), (0.1, (0.1, 0.009, 0.001))):
        c = coarse.simplify(m, ratio)
        assert c.uvs is not None and c.texture is m.texture and len(c.uvs) == len(c.vertices)
        p = c.vertices[c.faces]
        u = np.arctan2(p[..., 1], p[..., 0]) / (2 * np.pi)
        v = np.arctan2(p[..., 2], np.hypot(p[..., 0], p[..., 1]) - 1.0) / (2 * np.pi)
        got = c.uvs[c.faces]
        err = np.maximum(np.abs((got[..., 0] - u + 0.5) % 1 - 0.5), np.abs((got[..., 1] - v + 0.5) % 1 - 0.5))
        assert np.ptp(got, axis=1).max() < 0.25, ratio
        measured = (err.max(), np.percentile(err, 99), err.mean())
        assert all(e < b for e, b in zip(measured, bounds)), (ratio, measured)
        # the split copies share positions, so no border edge is added
        w = weld(c.vertices)[c.faces]
        sides = np.sort(np.stack([w, np.roll(w, -1, 1)], 2).reshape(-1, 2), 1)
        assert (np.unique(sides, axis=0, return_counts=True)[1] == 2).all()


def test_coarse_keeps_the_texture(ctx):
    """coarse@0.5 of the textured bunny keeps its texture: against the textured reference it is far better than
    the same coarse mesh drawn with per-vertex colours of the texture (the alternative that drops the UVs)."""
    m = bunny()
    c = coarse.simplify(m, 0.5)
    baked = TriMesh(m.vertices, m.faces, m.normals, colors=texture.sample(m.texture, m.uvs))
    by_colour = coarse.simplify(baked, 0.5)
    cams = cameras(m)
    with_uv = [s[0] for s in scores(ctx, c, [m], cams)]
    with_colour = [s[0] for s in scores(ctx, by_colour, [m], cams)]
    # measured at 96 px: UV transfer 2.95 / 2.87, per-vertex colours 6.24 / 5.89
    assert max(with_uv) < 3.5 and np.mean(with_uv) < 0.6 * np.mean(with_colour), (with_uv, with_colour)


def test_scene_to_report(tmp_path):
    """Scene -> bundle -> report: the bundle holds the map as a part; `mesh` and `coarse` are scored against the
    textured reference; an untextured asset gets no map."""
    bunny()
    scene = ('[render]\nresolution = [64, 64]\nrepeats = 1\nwarmup = 0\nshadow_map = 512\n'
             '[camera]\nup = [0, 1, 0]\norbit = { count = 1, elevation_deg = 20, distance = 2.6 }\n'
             f'[[objects]]\nname = "bunny"\nmesh = "{BUNNY}"\n'
             'techniques = { mesh = {}, coarse = { ratios = [0.5] } }\n'
             '[[objects]]\nname = "plain"\nmesh = "pkg:pymeshfix/examples/StanfordBunny.ply"\n'
             'techniques = { mesh = {} }\n')
    result, out = bake_and_render(tmp_path, scene, "--no-flip")
    assert result.exit_code == 0, result.output
    rows = {(r["object"], r["label"]): r for r in json.loads(result.stdout)["rows"]}
    # measured at 64 px with a 512² shadow map: mesh 0.145, coarse@0.5 2.437 (IoU 0.9961); the plain bunny 0.056
    assert rows["bunny", "mesh"]["mean_dluv"] < 0.3 and rows["bunny", "coarse@0.5"]["mean_dluv"] < 3.2
    from vdmbake.bundle.directory import Bundle
    b = Bundle(tmp_path / "b.bundle")
    entry = b.manifest["objects"]["bunny"]
    assert b.manifest["parts"][entry["albedo_map"]]["kind"] == "albedo-map"
    assert "albedo_map" not in b.manifest["objects"]["plain"]
    assert b.surface(entry, entry["techniques"]["coarse"]["meshes"][0]["mesh"]).texture is not None
