"""Mipmaps (issue 30, the scene's render.mipmaps): an albedo map minified far below a texel per pixel reads its
mean when mip-mapped and aliases at level 0; VDM's weights, the mesostructure's normals and colour tile are read
at the pixel footprint's level (Wang2003 §4) when minified and at level 0 when magnified; off, nothing changes
(the goldens, tests/test_golden.py, hold that for every technique)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from PIL import Image

from bench import interleave
from vdmbake.common.mesh import TriMesh
from vdmbake.bake import bake
from vdmbake.common import texture
from vdmbake.scene import Light, Material
from vdmrender.measuring import counters
from vdmrender.gpu import gl
from vdmrender.common.camera import Camera, clip_planes
from vdmrender.passes.raster import RasterMesh
from vdmrender.techniques import variants

import meso_scenes
from meso_scenes import PLANE

SIZE = 32


def camera(fov: float, eye=(0.0, 0.0, 1.5), size: int = SIZE) -> Camera:
    """Straight down on the plane z = 0 at the origin."""
    eye, at = np.array(eye), np.zeros(3)
    return Camera(eye, at, np.array([0.0, 1.0, 0.0]), fov, size, size, *clip_planes(eye, at, at, 1.0))


def frame(ctx, renderer, cam) -> np.ndarray:
    """One frame of `renderer`, which is released."""
    try:
        return frame_of(ctx, renderer, cam)
    finally:
        renderer.release()


# ----------------------------------------------------------------------------- an albedo map far away

def checker_plane(texels: np.ndarray, repeats: float) -> TriMesh:
    """A 2 x 2 square at z = 0 facing +z, its UVs spanning `repeats` copies of the map."""
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    m = TriMesh(v, np.array([[0, 1, 2], [0, 2, 3]]), np.tile([0.0, 0.0, 1.0], (4, 1)))
    m.uvs, m.texture = (v[:, :2] + 1) * 0.5 * repeats, texels
    return m


def test_a_minified_checker_reads_its_mean(ctx):
    """A one-texel black and white checker, 64 texels to a pixel: mip-mapped, every pixel is the frame of a
    flat map of the checker's linear mean (its sRGB code rounded); at level 0 the pixels alias to black or
    white, far from it. Magnified, the two agree (level 0 is read either way)."""
    n = 256
    checker = np.where((np.add.outer(np.arange(n), np.arange(n)) % 2)[..., None] == 1, 255, 0).astype(np.uint8)
    checker = np.repeat(checker, 3, -1)
    mean = float(texture.linear(checker).mean())
    flat = np.full((4, 4, 3), np.argmin(np.abs(texture.linear(np.arange(256, dtype=np.uint8)) - mean)), np.uint8)
    light, material = Light(), Material()
    far = camera(40.0)            # the plane fills about 32 px of the 32 px frame: 8 x 256 texels over them
    shot = {}
    for name, texels, mips in (("mip", checker, True), ("level0", checker, False), ("flat", flat, False)):
        mesh = checker_plane(texels, 7.3)
        shot[name] = frame(ctx, RasterMesh(ctx, mesh, light, material, 256, mipmaps=mips), far)
    inner = (slice(4, -4), slice(4, -4))
    flat_rgb = shot["flat"][inner][..., :3]
    assert (shot["flat"][inner][..., 3] == 1).all()
    off_mip = np.abs(shot["mip"][inner][..., :3] - flat_rgb).max() / flat_rgb.mean()
    off_level0 = np.abs(shot["level0"][inner][..., :3] - flat_rgb).mean() / flat_rgb.mean()
    assert off_mip < 0.03 and off_level0 > 0.15, (off_mip, off_level0)   # measured: 0.006, 0.27
    near = camera(0.5)            # about 1.4 texels per pixel the other way: magnified
    pair = [frame(ctx, RasterMesh(ctx, checker_plane(checker, 7.3), light, material, 256, mipmaps=m), near)
            for m in (True, False)]
    np.testing.assert_array_equal(*pair)


def test_the_texture_is_mip_mapped_only_when_asked(ctx):
    """albedo_texture's chain: with mipmaps a full one (counters.texture_bytes counts it: 4/3 of level 0)."""
    texels = np.zeros((64, 64, 3), np.uint8)
    plain, mipped = (gl.albedo_texture(ctx, texels, m) for m in (False, True))
    try:
        assert counters.texture_bytes(mipped) > 1.3 * counters.texture_bytes(plain)
    finally:
        gl.release(plain, mipped)


# ----------------------------------------------------------------------------- VDM at a small size

@pytest.fixture(scope="module")
def bricks(tmp_path_factory):
    """A plane of 16 x 16 brick tiles (16^2 texels each, a colour tile), baked for vdm, pom and bump; its bundle."""
    d = tmp_path_factory.mktemp("mips")
    tile = (np.random.default_rng(3).random((16, 16, 3)) * 255).astype(np.uint8)
    Image.fromarray(tile).save(d / "tile.png")
    text = meso_scenes.scene(meso_scenes.TOP, PLANE, "vdm = { k = [4], refine = [0, 2] }, pom = { steps = [8] }, bump = {}",
                             tiling=(16, 16), size=16, phi=8, theta=4, curvatures=1, res=SIZE)
    text = text.replace("[objects.mesostructure]\n", '[objects.mesostructure]\nalbedo = "tile.png"\n')
    (d / "s.toml").write_text(text)
    bake(d / "s.toml", d / "b.bundle")
    bundle, scene, obj, entry, _ = interleave.scene_of(d / "b.bundle")
    return bundle, scene, obj, entry


def builds(bricks, mipmaps: bool) -> dict:
    bundle, scene, obj, entry = bricks
    scene = dataclasses.replace(scene, render=dataclasses.replace(scene.render, mipmaps=mipmaps))
    return {v.label: v.build for v in variants(obj, entry, bundle, scene)}


@pytest.mark.parametrize("label", ["vdm@4", "vdm@4r2", "pom@8", "bump"])
def test_mesostructure_reads_the_footprints_level(ctx, bricks, label):
    """Seen from 1.5 above (about 4 texels per pixel) the mip-mapped frame differs from the level-0 one, its
    pixels closer to their neighbours (the footprint's mean); through a 2-degree lens (magnified) the two
    are the same frame. The mip-mapped build fetches as often as the level-0 one (a level is one read)."""
    on, off = builds(bricks, True)[label], builds(bricks, False)[label]
    far, near = camera(40.0), camera(2.0)
    a, b = frame(ctx, on(ctx), far), frame(ctx, off(ctx), far)
    assert (a[..., 3] == 1).all() and (b[..., 3] == 1).all()

    def roughness(f):
        return float(np.abs(np.diff(f[..., :3], axis=1)).mean())

    assert roughness(a) < 0.8 * roughness(b), (roughness(a), roughness(b))
    np.testing.assert_array_equal(frame(ctx, on(ctx), near), frame(ctx, off(ctx), near))
    target = gl.Target(ctx, SIZE, SIZE)
    try:
        counts = []
        for build in (on, off):
            with counters.counting(ctx):
                r = build(ctx)
            counts.append(counters.count_frame(ctx, r, far, target)["passes"]["frame"]["fetches"])
            r.release()
        assert counts[0] == counts[1] > 0
    finally:
        target.release()


def test_vdm_reads_its_weights_at_the_footprints_level(ctx, bricks):
    """The weights W are uploaded with their chain under mipmaps (the texture bytes count it). With the chain cut
    to level 0, the frame from afar changes (a level > 0 was read there) and the close-up does not (level 0 only)."""
    on, off = (builds(bricks, m)["vdm@4"](ctx) for m in (True, False))
    W = on.textures["u_W"]
    try:
        assert counters.texture_bytes(W) > 1.3 * counters.texture_bytes(off.textures["u_W"])
        far, near = camera(40.0), camera(2.0)
        before = [frame_of(ctx, on, cam) for cam in (far, near)]
        W.build_mipmaps(0, 0)                 # the chain cut to level 0 (GL's max level), the filter unchanged
        after = [frame_of(ctx, on, cam) for cam in (far, near)]
        assert np.abs(after[0] - before[0]).max() > 0.005     # measured: 0.012 (the hits move; the tile is blurred)
        np.testing.assert_array_equal(after[1], before[1])
    finally:
        on.release()
        off.release()


def frame_of(ctx, renderer, cam) -> np.ndarray:
    """`frame` without releasing the renderer."""
    target = gl.Target(ctx, cam.width, cam.height)
    try:
        renderer.render(cam, target)
        return target.read()
    finally:
        target.release()


# ----------------------------------------------------------------------------- colour maps of billboards and atlases

@pytest.fixture(scope="module")
def bunny(tmp_path_factory):
    """pymeshlab's textured bunny baked for billboards (both renderers) and an octahedral atlas, small maps."""
    pytest.importorskip("pymeshlab")   # a test extra: only its sample meshes are used
    d = tmp_path_factory.mktemp("bunny")
    (d / "s.toml").write_text(f"""
[render]
resolution = [{SIZE}, {SIZE}]
shadow_map = 256
[camera]
up = [0, 0, 1]
orbit = {{ count = 1, elevation_deg = 20, azimuth_deg = 30, distance = 2.6, fov_deg = 40 }}
[[objects]]
name = "bunny"
mesh = "pkg:pymeshlab/tests/sample_meshes/bunny10k_textured.obj"
transform = {{ rotate_deg = [90, 0, 0] }}
[objects.techniques]
billboards = {{ variants = ["greedy-hier", "greedy-improved"], resolution = 64 }}
octahedral = {{ variants = ["full-5x64-march"] }}
""")
    bake(d / "s.toml", d / "b.bundle")
    bundle, scene, obj, entry, cams = interleave.scene_of(d / "b.bundle")
    return (bundle, scene, obj, entry), cams[0]


@pytest.mark.parametrize("label", ["billboards@greedy-hier", "billboards@greedy-improved", "octahedral@full-5x64-march"])
def test_colour_maps_are_read_at_the_footprints_level(ctx, bunny, label):
    """The bunny 32 px across: with mipmaps its colour maps are read above level 0 (the colours change, finite),
    the coverage and the searched depth do not (the same pixels, the same shading besides the colour)."""
    baked, cam = bunny
    on, off = builds(baked, True)[label], builds(baked, False)[label]
    a, b = frame(ctx, on(ctx), cam), frame(ctx, off(ctx), cam)
    assert np.isfinite(a).all()
    np.testing.assert_array_equal(a[..., 3], b[..., 3])
    assert np.abs(a - b)[..., :3].max() > 0.01
