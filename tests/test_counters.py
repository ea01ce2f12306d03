"""The device-independent cost counters (vdmrender/measuring/counters.py, shaders/include/cost_count.glsl): every
fragment stage counts, the instrumented build draws the very frame the normal one draws (it only adds
atomics), the counts are what the stages do on cases whose work is known exactly, and they repeat."""
from __future__ import annotations

import re

import numpy as np
import pytest
from PIL import Image

from bench import interleave
from vdmbake.kernels import billboard_maps, coarse, octahedral, quadrics
from vdmbake.assets import primitives
from vdmbake.kernels import billboards as bb
from vdmbake.bake import bake
from vdmbake.common.mesh import TriMesh
from vdmbake.scene import Light, Material
from vdmrender.measuring import counters
from vdmrender.gpu import gl
from vdmrender.tracing import quadric_math as qm
from vdmrender.common.camera import Camera, clip_planes
from vdmrender.techniques import variants
from vdmrender.techniques.billboards import Billboards
from vdmrender.techniques.billboards_hier import HierBillboards
from vdmrender.techniques.impostor import Impostors
from vdmrender.techniques.octahedral import Octahedral
from vdmrender.passes.raster import RasterMesh
from vdmrender.passes.shadowmap import translation
from vdmrender.techniques.tessellated import Tessellated

import meso_scenes
from meso_scenes import PLANE, TOP, TORUS

LIGHT, MATERIAL, SHADOW = Light(), Material(), 256
BELOW = "[light]\ndirection = [0.3, 0.2, -0.9]\n"    # under the plane: no self-shadow search, known counts


def frame_and_counts(ctx, build, camera):
    """(normal frame, instrumented frame, count_frame's counts, a second run's): build(ctx) twice."""
    target = gl.Target(ctx, camera.width, camera.height)
    try:
        r = build(ctx)
        r.render(camera, target)
        normal = target.read()
        r.release()
        with counters.counting(ctx):
            r = build(ctx)
        first = counters.count_frame(ctx, r, camera, target)
        counted = target.read()
        second = counters.count_frame(ctx, r, camera, target)
        r.release()
        return normal, counted, first, second
    finally:
        target.release()


def look(c, r, azimuth=30.0, elevation=25.0, size=24, distance=2.8) -> Camera:
    """A camera on an orbit around the sphere (c, r)."""
    a, e = np.radians(azimuth), np.radians(elevation)
    eye = c + distance * r * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    return Camera(eye, c, np.array([0.0, 0.0, 1.0]), 40.0, size, size, *clip_planes(eye, c, c, r))


# ----------------------------------------------------------------------------- every stage counts

def test_every_fragment_stage_counts():
    """Every fragment stage includes cost_count.glsl and counts its fragments first thing in main; no stage
    writes counts instead of a colour any more."""
    for path in sorted(gl.SHADERS.iterdir()):
        if path.name.endswith(".frag"):
            text = path.read_text()
            assert '#include "cost_count.glsl"' in text, path.name
            assert re.search(r"void main\(\) \{\n    COUNT_FRAGMENT\(\);", text), path.name
    for path in [*gl.SHADERS.iterdir(), *(gl.SHADERS / "include").iterdir()]:
        if path.suffix in (".frag", ".vert", ".glsl") and path.name != "cost_count.glsl":
            assert "defined(COUNT)" not in path.read_text() and "COUNT_OUT" not in path.read_text(), path.name


def test_counting_compiles_apart(ctx):
    """counting() compiles the fragment stages with COUNT beside the normal programs; outside it nothing
    changes, and a renderer built outside it is refused by count_frame."""
    m = plane()
    normal = RasterMesh(ctx, m, LIGHT, MATERIAL, SHADOW)
    with counters.counting(ctx):
        counted = RasterMesh(ctx, m, LIGHT, MATERIAL, SHADOW)
    again = RasterMesh(ctx, m, LIGHT, MATERIAL, SHADOW)
    progs = [[p for _, p, _, _ in r.draws] for r in (normal, counted, again)]
    assert progs[0] == progs[2] and not set(progs[0]) & set(progs[1])
    assert all("CostCounts" in p and "COUNT" in p.extra["name"] for p in progs[1])
    assert "counting" not in ctx.extra
    target = gl.Target(ctx, 8, 8)
    with pytest.raises(ValueError, match="counting"):
        counters.count_frame(ctx, normal, head_on(8, 8), target)
    for r in (normal, counted, again):
        r.release()
    target.release()


# ----------------------------------------------------------------------------- exact counts

def plane(half=2.0) -> TriMesh:
    v = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]])
    return TriMesh(v, np.array([[0, 1, 2], [0, 2, 3]]), np.tile([0.0, 0.0, 1.0], (4, 1)))


def head_on(w, h) -> Camera:
    return Camera(np.array([0.0, 0.0, 1.5]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 40.0, w, h, 0.1, 10.0)


def test_mesh_on_a_full_screen_quad(ctx):
    """A plane filling the frame: one fragment per pixel (each pixel in one of the two triangles), one
    shadow-map fetch each; two triangles in each pass, one draw of one instance; the shadow pass's
    depth.frag fetches nothing. resident_bytes: the three buffers and the shadow map."""
    cam = head_on(20, 14)
    normal, counted, c, again = frame_and_counts(ctx, lambda x: RasterMesh(x, plane(), LIGHT, MATERIAL, SHADOW), cam)
    assert np.array_equal(normal, counted) and c == again
    frame, shadow = c["passes"]["frame"], c["passes"]["shadow"]
    assert c["covered"] == 20 * 14
    assert frame == {"fragments": 280, "fetches": 280, "steps": 0, "searches": 0, "primitives": 2, "draws": 1,
                     "instances": 1}
    assert shadow["fetches"] == 0 and shadow["primitives"] == 2 and 0 < shadow["fragments"] <= SHADOW * SHADOW
    with counters.counting(ctx):
        r = RasterMesh(ctx, plane(), LIGHT, MATERIAL, SHADOW)
    assert counters.resident_bytes(r) == 4 * 3 * 4 + 4 * 3 * 4 + 2 * 3 * 4 + SHADOW * SHADOW * 4
    r.release()


def test_impostor_sphere_runs_its_quad(ctx):
    """One ray-cast sphere, direct shading: the stage runs once per pixel of its screen quad (Sigg's bounds,
    numpy twin quadric_math.projected_bounds), covers fewer, and fetches the shadow map once per hit."""
    q = quadrics.inline([[0.0, 0.0, 0.0, 1.0]], np.zeros((0, 7)), (0.7, 0.7, 0.7))
    w, h = 40, 30
    eye = np.array([2.2, -3.1, 1.3])
    cam = Camera(eye, np.array([0.3, 0.1, 0.0]), np.array([0.0, 0.0, 1.0]), 45.0, w, h, 0.1, 20.0)
    _, counted, c, again = frame_and_counts(ctx, lambda x: Impostors(x, q, LIGHT, MATERIAL, SHADOW, "direct", 0, 0), cam)
    anchor, _ = q.bounding_sphere()
    box = qm.projected_bounds(cam.projection() @ cam.view() @ translation(anchor),
                              qm.sphere_variance(q.spheres[0, :3] - anchor, 1.0))
    lo = (np.clip(box[:2], -1, 1) * 0.5 + 0.5) * (w, h)          # window coordinates of the quad
    hi = (np.clip(box[2:], -1, 1) * 0.5 + 0.5) * (w, h)
    centres = [np.arange(n) + 0.5 for n in (w, h)]
    inside = [((x > a) & (x < b)).sum() for x, a, b in zip(centres, lo, hi)]
    gaps = np.abs(np.concatenate([x[:, None] - np.array([a, b])[None] for x, a, b in zip(centres, lo, hi)]))
    assert gaps.min() > 1e-3                                        # no pixel centre on the quad's edge
    frame = c["passes"]["frame"]
    assert frame["fragments"] == inside[0] * inside[1] > c["covered"] == frame["fetches"] > 0
    assert frame["primitives"] == 2 and frame["instances"] == 1 and c == again


@pytest.fixture(scope="module")
def floor(tmp_path_factory):
    """A plane under the heights' floor (one texel of a 64^2 tile at the top, in its corner, out of view)
    seen from straight above, the light below it, baked for vdm, pom, relief and bump; and its camera."""
    d = tmp_path_factory.mktemp("floor")
    img = np.zeros((64, 64), np.uint8)
    img[0, 0] = 255
    Image.fromarray(img).save(d / "floor.png")
    techniques = 'vdm = { k = [4], refine = [0, 2] }, pom = { steps = [8] }, relief = { iterations = [16] }, bump = {}'
    (d / "s.toml").write_text(meso_scenes.scene(TOP, PLANE, techniques, height="floor.png", size=64, tiling=(1, 1),
                                                phi=8, theta=4, curvatures=1, res=16, light=BELOW, shadow_map=SHADOW))
    bake(d / "s.toml", d / "b.bundle")
    bundle, scene, obj, entry, cams = interleave.scene_of(d / "b.bundle")
    return {v.label: v.build for v in variants(obj, entry, bundle, scene)}, cams[0]


@pytest.mark.parametrize("label,fetches,steps,searches", [
    ("pom@8", 1 + 8 + 2, 8, 1),      # the first height, one per layer of the search; the normal, the shadow map
    ("vdm@4", 4 + 3, 0, 1),          # one group: 2 weights (phi interpolated), 2 eigenfunctions; height, normal, shadow
    ("vdm@4r2", 3 + 3 + 3, 3, 1),    # 1 weight (nearest phi), 2 eigenfunctions; 3 height samples; the 3
    ("bump", 2, 0, 0),               # the normal, the shadow map
])
def test_mesostructure_on_the_floor(ctx, floor, label, fetches, steps, searches):
    """Over the floor every view ray goes all the way down: pom's linear search takes all its u_steps layers,
    refined VDM its REFINE + 1 samples; with the light below the surface no shadow ray is searched. Every
    pixel is the plane's, one fragment each, one search each (bump: none)."""
    builds, cam = floor
    normal, counted, c, again = frame_and_counts(ctx, builds[label], cam)
    assert np.array_equal(normal, counted) and c == again
    n = cam.width * cam.height
    frame = c["passes"]["frame"]
    assert c["covered"] == n and frame["fragments"] == n
    assert (frame["fetches"], frame["steps"], frame["searches"]) == (fetches * n, steps * n, searches * n)


def test_relief_on_the_floor(ctx, floor):
    """relief: a view ray and a (zero-length) shadow ray per fragment, each cell visit one pyramid fetch."""
    builds, cam = floor
    normal, counted, c, again = frame_and_counts(ctx, builds["relief@16"], cam)
    assert np.array_equal(normal, counted) and c == again
    n, frame = cam.width * cam.height, c["passes"]["frame"]
    assert frame["fragments"] == n and frame["searches"] == 2 * n
    assert frame["fetches"] == frame["steps"] + 2 * n and n <= frame["steps"] <= 2 * 16 * n


# ----------------------------------------------------------------------------- the same frames, every family

@pytest.fixture(scope="module")
def bricks(tmp_path_factory):
    """Bricks on a torus, every mesostructure technique and its peers, baked small."""
    d = tmp_path_factory.mktemp("bricks")
    techniques = ('mesh = {}, vdm = { k = [4], refine = [0, 2] }, pom = { steps = [8] }, relief = { iterations = [16] }, '
                  'bump = {}, displaced = { levels = [1] }')
    (d / "s.toml").write_text(meso_scenes.scene(meso_scenes.ORBIT.format(count=1), TORUS, techniques, size=16,
                                                tiling=(8, 2), phi=8, theta=4, curvatures=2, res=24, shadow_map=SHADOW))
    bake(d / "s.toml", d / "b.bundle")
    bundle, scene, obj, entry, cams = interleave.scene_of(d / "b.bundle")
    return {v.label: v.build for v in variants(obj, entry, bundle, scene)}, cams[0]


@pytest.fixture(scope="module")
def sphere_bakes():
    m = primitives.sphere(1.0, 32, 16)
    boards = bb.bake(m, bb.Settings(resolution=16)).billboards
    atlas = octahedral.to_part(octahedral.bake(m, octahedral.Settings(5, 16)))
    return m, boards, coarse.simplify(m, 0.2), atlas


def families(bricks, sphere_bakes):
    builds, cam = bricks
    m, boards, co, atlas = sphere_bakes
    flat = [billboard_maps.bordered(b, False) for b in boards]
    pyramids = [billboard_maps.bordered(b, True) for b in boards]
    q = quadrics.inline([[0, 0, 0, 1.0], [1.3, 0.2, 0.1, 0.6]], [[0, 0, 0, 1.3, 0.2, 0.1, 0.2]], (0.6, 0.7, 0.8))
    qcam, bcam = look(*q.bounding_sphere()), look(*m.bounding_sphere())
    out = {label: (b, cam) for label, b in builds.items()}
    out |= {"thesis": (lambda x: Billboards(x, boards, flat, LIGHT, MATERIAL, SHADOW, "thesis", 0.02), bcam),
            "improved+coarse": (lambda x: Billboards(x, boards, flat, LIGHT, MATERIAL, SHADOW, coarse=co), bcam),
            "hier+coarse": (lambda x: HierBillboards(x, boards, pyramids, LIGHT, MATERIAL, SHADOW, co,
                                                     m.bounding_sphere(), shadow_mesh=co), bcam),
            "hier": (lambda x: HierBillboards(x, boards, pyramids, LIGHT, MATERIAL, SHADOW, None, m.bounding_sphere()), bcam),
            "octahedral march": (lambda x: Octahedral(x, atlas, LIGHT, MATERIAL, SHADOW), bcam),
            "octahedral virtual": (lambda x: Octahedral(x, atlas, LIGHT, MATERIAL, SHADOW, "virtual"), bcam),
            "tessellated": (lambda x: Tessellated(x, q, LIGHT, MATERIAL, SHADOW, 1), qcam)}
    for shading in ("direct", "deferred", "outlines"):
        out[f"impostor {shading}"] = (lambda x, s=shading: Impostors(x, q, LIGHT, MATERIAL, SHADOW, s, 1.0, 1.0), qcam)
    return out


def test_instrumented_frames_are_the_same(ctx, bricks, sphere_bakes):
    """Every technique family draws the identical frame built with the counters on, counts the same twice,
    and counts what it does: fragments where it covers pixels, searches and steps where it searches."""
    searching = {"vdm@4", "vdm@4r2", "pom@8", "relief@16", "thesis", "improved+coarse", "hier+coarse", "hier",
                 "octahedral march", "octahedral virtual"}
    for label, (build, cam) in families(bricks, sphere_bakes).items():
        normal, counted, c, again = frame_and_counts(ctx, build, cam)
        assert np.array_equal(normal, counted), label
        assert c == again, label
        t = c["total"]
        assert c["covered"] > 0 and t["fragments"] >= c["covered"] and t["primitives"] > 0, label
        assert (t["searches"] > 0) == (label in searching) and (t["steps"] > 0) <= (label in searching), label
        print(f"{label:20} covered {c['covered']:4}  per covered px: "
              + "  ".join(f"{k} {t[k] / c['covered']:.2f}" for k in counters.COUNTERS))


def test_counts_carry_past_32_bits(ctx):
    """Each counter is two 32-bit words, the add that wraps the low word carrying into the high one: started just
    below 2^32, a 64 x 64 frame's 4096 fragments count on exactly (one 32-bit atomic would wrap to 4095 - 100)."""
    frag = gl.expand('#version 430\n#define COUNT\n#include "cost_count.glsl"\nout vec4 frag;\n'
                     "void main() {\n    COUNT_FRAGMENT();\n    frag = FETCH(vec4(1.0));\n}\n")
    prog = ctx.program(vertex_shader=gl.source("fullscreen.vert"), fragment_shader=frag)
    start = 2**32 - 100
    ssbo = ctx.buffer(np.array([start, start, 0, 0, 0, 0, 0, 0], np.uint32).tobytes())
    target = gl.Target(ctx, 64, 64)
    try:
        target.clear()
        ssbo.bind_to_storage_buffer(counters.BINDING)
        ctx.vertex_array(prog, []).render(vertices=3)
        ctx.memory_barrier()
        assert counters.read_counts(ssbo.read()) == [start + 4096, start + 4096, 0, 0]
    finally:
        target.release()
        ssbo.release()
