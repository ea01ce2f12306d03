"""Instances of quadrics objects (issue 23): molecules and inline spheres and cylinders drawn many times from one
bake by `impostor` and `tessellated`, every copy in one instanced draw per pass and kind
(vdmrender.techniques.impostor.Copies), against a reference that traces every copy merged
(vdmbake.common.instances.placed_quadrics)."""
import importlib.util
import json

import numpy as np
import pytest
from PIL import Image

from scenes import RENDER, bake_and_render, rows_by_label
from vdmbake.common import instances

LIGHT = np.array([0.45, -0.55, 0.7]) / np.linalg.norm([0.45, -0.55, 0.7])   # the scenes' default light
SHAPE = ("spheres = [[0, 0, 0, 1], [1.4, 0.3, 0.2, 0.55]]\n"   # not symmetric: a copy's turn shows
         "cylinders = [[0, 0, 0, 1.4, 0.3, 0.2, 0.22], [0, 0, 0, 0, -0.2, 1.7, 0.3]]\n")
TECHNIQUES = 'techniques = { impostor = { shading = ["direct", "deferred", "outlines"] }, tessellated = { levels = [3] } }\n'
VILLIN = 'molecule = "pkg:pdbfixer/tests/data/test.pdb"\nstyle = "ball-and-stick"\n'   # 596 atoms, radius 18.03


def head(size: int, shadow_map: int = 256, poses: str | None = None) -> str:
    """[render] and [camera]: two orbit cameras, or the poses given."""
    return (RENDER.replace("[32, 32]", f"[{size}, {size}]").replace("256", str(shadow_map))
            + ("[camera]\norbit = { count = 2 }\n" if poses is None else f"[camera]\nposes = [{poses}]\n"))


def placements(*copies) -> str:
    """[[objects.instances.placements]] tables: (translate, rotate_deg, scale) each."""
    return "".join(f"[[objects.instances.placements]]\ntranslate = {list(map(float, t))}\nrotate_deg = {list(r)}\n"
                   f"scale = {s}\n" for t, r, s in copies)


def frames(out, obj, label):
    folder = out / ("reference" if label == "reference" else "frames") / obj / ("" if label == "reference" else label)
    return [np.asarray(Image.open(p).convert("RGB"), int) for p in sorted(folder.glob("[0-9][0-9][0-9].png"))]


def villin():
    if importlib.util.find_spec("pdbfixer") is None:   # found without importing it (it imports openmm)
        pytest.skip("pdbfixer is not installed (pip install --no-deps pdbfixer==1.12.0)")
    return VILLIN


def pair(centre, radius: float, offset=(0.0, 0.0, 0.0)) -> tuple[str, str]:
    """Copy A in place, copy B 1.4 radii towards the light (their bounding spheres overlap; B shadows A), turned and
    scaled, both moved by `offset`; and two camera poses at the pair: one 25 degrees off the light (B hides part
    of A), one from the side (B's shadow on A)."""
    offset = np.asarray(offset, float)
    target = np.asarray(centre) + offset + 0.7 * radius * LIGHT
    across = np.cross(LIGHT, [1.0, 0.0, 0.0])
    off_light = np.cos(np.radians(25)) * LIGHT + np.sin(np.radians(25)) * across / np.linalg.norm(across)
    eyes = [target + 3.2 * radius * off_light, target + 3.2 * radius * np.array([0.81, 0.47, 0.34])]
    poses = ", ".join(f"{{ eye = {e.tolist()}, target = {target.tolist()} }}" for e in eyes)
    return placements((offset, (0, 0, 0), 1.0), (offset + 1.4 * radius * LIGHT, (30, 60, 10), 0.75)), poses


@pytest.mark.gl
def test_one_copy_in_place_draws_as_the_object_alone(tmp_path):
    """A copy at the identity: every technique's frames and the reference's are those of the object alone."""
    one = '[[objects]]\nname = "b"\n' + SHAPE + TECHNIQUES + placements(((0, 0, 0), (0, 0, 0), 1.0))
    alone = '[[objects]]\nname = "a"\n' + SHAPE + TECHNIQUES
    res, out = bake_and_render(tmp_path, head(64) + one + alone, "--no-flip")
    assert res.exit_code == 0, res.output
    for label in ("reference", "impostor@direct", "impostor@deferred", "impostor@outlines", "tessellated@3"):
        a, b = frames(out, "a", label), frames(out, "b", label)
        assert len(a) == len(b) == 2
        assert all(np.array_equal(x, y) for x, y in zip(a, b)), label
    from vdmbake.formats import exr   # the reference's float frames (its cache), not only their PNGs

    for k in range(2):
        a, b = (exr.read(out / f"reference/{o}/{k:03d}.exr")["reference"] for o in "ab")
        assert all(np.array_equal(a[c], b[c]) for c in "RGBA")


@pytest.mark.gl
def test_one_copy_in_place_gives_the_same_floats(ctx):
    """The renderers' float frames, not only their 8-bit encodings: a copy at the identity is drawn through the
    storage buffers (INSTANCED) exactly as the object through its per-instance attributes."""
    from vdmbake.kernels import quadrics
    from vdmrender.common.camera import Camera
    from vdmrender.techniques.impostor import Impostors
    from vdmrender.techniques.tessellated import Tessellated
    from frames import LIGHT as L, MATERIAL, draw

    q = quadrics.inline([[0, 0, 0, 1], [1.4, 0.3, 0.2, 0.55]], [[0, 0, 0, 1.4, 0.3, 0.2, 0.22],
                                                                [0, 0, 0, 0, -0.2, 1.7, 0.3]], (0.7, 0.6, 0.5))
    cam = Camera(np.array([3.5, -4.0, 2.5]), np.array([0.4, 0.0, 0.5]), np.array([0.0, 0.0, 1.0]), 40.0, 72, 64,
                 0.1, 20.0)
    one = np.eye(4)[None]
    for build in [lambda i, s=s: Impostors(ctx, q, L, MATERIAL, 256, s, 0.5, 0.5, i)
                  for s in ("direct", "deferred", "outlines")] + [lambda i: Tessellated(ctx, q, L, MATERIAL, 256, 2, i)]:
        alone, copy = draw(build(None), cam), draw(build(one), cam)
        assert (alone[..., 3] > 0).sum() > 500 and np.array_equal(alone, copy)


def shadowed_share(bundle_path, name: str) -> float:
    """The share of copy A's atoms whose lit pole (the point facing the light) copy B shadows (the reference's
    float64 tracer): what the pair's agreement on shadows is about."""
    from vdmbake.bundle import parts
    from vdmbake.bundle.directory import Bundle
    from vdmrender.tracing.reference import QuadricTracer
    from vdmbake.common.instances import placed_quadrics

    bundle = Bundle(bundle_path)
    obj = next(o for o in bundle.scene.objects if o.name == name)
    entry = bundle.manifest["objects"][name]
    m = instances.matrices(obj.instances, bundle.scene.camera.up, entry["centre"])
    q = bundle.read(entry["quadrics"], parts.QUADRICS)
    a, b = placed_quadrics(q, m[:1]), placed_quadrics(q, m[1:])
    poles = a.spheres[:, :3] + 1.001 * a.spheres[:, 3:] * LIGHT
    n = len(poles)
    t, _, _ = QuadricTracer(b).first_hit(poles, np.tile(LIGHT, (n, 1)), np.zeros(n), np.full(n, np.inf),
                                         stop_at_any=True)
    return float(np.isfinite(t).mean())


@pytest.mark.gl
@pytest.mark.parametrize("source, centre, radius", [("inline", (0.475, 0.0, 0.5), 1.69),
                                                    ("villin", (0.054, 0.7535, 0.8745), 18.03)])
@pytest.mark.slow
def test_overlapping_copies_against_the_merged_reference(tmp_path, source, centre, radius):
    """Copy B stands between copy A and the light, turned and scaled: every technique agrees with the merged
    reference on which copy hides which and on B's shadow over A."""
    shape = SHAPE if source == "inline" else villin()
    copies, poses = pair(centre, radius)
    res, out = bake_and_render(tmp_path, head(96, 1024, poses) + '[[objects]]\nname = "pair"\n' + shape + TECHNIQUES
                               + copies, "--no-flip")
    assert res.exit_code == 0, res.output
    assert shadowed_share(tmp_path / "b.bundle", "pair") > 0.3   # measured: inline 0.5, villin 0.32
    rows = rows_by_label(res)
    # measured (96 px, llvmpipe): inline mean ΔLuv 0.076 direct, 0.107 deferred, 0.381 tessellated@3, IoU 1.0,
    # 1.0, 0.9974; villin 0.95, 0.96, 0.88 (single pixels of its thin bonds and small atoms), IoU 1.0, 1.0, 0.9971
    limits = {"inline": (0.25, 0.75), "villin": (1.5, 1.4)}[source]
    for label, limit, iou in (("impostor@direct", limits[0], 0.999), ("impostor@deferred", limits[0], 0.999),
                              ("tessellated@3", limits[1], 0.995), ("impostor@outlines", None, 0.999)):
        r = rows[label]
        assert (limit is None or r["mean_dluv"] < limit) and r["iou"] > iou, (label, r["mean_dluv"], r["iou"])


@pytest.mark.gl
def test_a_copy_moved_and_turned_is_drawn_where_the_reference_has_it(tmp_path):
    """One copy far off the object's place, turned and scaled up: the cameras frame the copy, so a renderer that
    ignored its matrix would draw the object outside the frames (IoU near 0), and one that ignored its turn or
    scale would miss much of it."""
    res, out = bake_and_render(tmp_path, head(64) + '[[objects]]\nname = "moved"\n' + SHAPE + TECHNIQUES
                               + placements(((9, -4, 3), (0, 90, 45), 1.5)), "--no-flip")
    assert res.exit_code == 0, res.output
    for label, r in rows_by_label(res).items():
        assert r["iou"] > 0.99 and (label == "impostor@outlines" or r["mean_dluv"] < 0.75), (label, r)


@pytest.mark.gl
def test_a_scatter_of_copies_is_one_instanced_draw_per_pass_and_kind(tmp_path):
    """200 copies: each pass draws each kind (spheres, cylinders) once, with 200 instances a quadric, and the GPU
    holds the quadrics once plus a matrix (64 bytes) a copy."""
    field = ('[[objects]]\nname = "field"\n' + SHAPE + TECHNIQUES
             + "[objects.instances]\nscatter = { count = 200, area = [60, 60], scale = [0.6, 1.4], seed = 3 }\n")
    res, out = bake_and_render(tmp_path, head(64) + field + '[[objects]]\nname = "alone"\n' + SHAPE + TECHNIQUES,
                               "--no-flip")
    assert res.exit_code == 0, res.output
    rows = {(r["object"], r["label"]): r for r in json.loads(res.stdout)["rows"]}
    cameras, per_kind = 2, 2 * 200   # two spheres and two cylinders in the shape
    quads = {"shadow", "frame", "gbuffer"}
    for label in ("impostor@direct", "impostor@deferred", "impostor@outlines", "tessellated@3"):
        r = rows[("field", label)]
        for name, p in r["counters_per_pass"].items():
            if name in quads:
                assert p["draws"] == 2 * cameras and p["instances"] == 2 * per_kind * cameras, (label, name, p)
            else:   # the deferred shading pass: one full-screen triangle
                assert name == "shade" and p["draws"] == cameras, (label, name, p)
        assert r["counters"]["bytes"] == rows[("alone", label)]["counters"]["bytes"] + 200 * 64, label
        assert r["iou"] > 0.99 and (label == "impostor@outlines" or r["mean_dluv"] < 1.0), (label, r)


@pytest.mark.gl
def test_copies_far_from_the_origin_keep_float32_precision(tmp_path):
    """The pair 1.7e4 units from the origin, the cameras with it (orbiting its copies): copies placed that far from
    the object, or the object itself moved there, are drawn in coordinates relative to the copies' own sphere
    (instances.enclosing), so they look as the pair does near the origin, and agree with the reference as well."""
    shift = (1e4, -1e4, 1e4)
    near, _ = pair((0.475, 0.0, 0.5), 1.69)
    far, _ = pair((0.475, 0.0, 0.5), 1.69, shift)
    moved = f"transform = {{ translate = {list(shift)} }}\n"
    res, out = bake_and_render(tmp_path, head(96, 1024) + "".join(
        f'[[objects]]\nname = "{name}"\n' + SHAPE + extra + TECHNIQUES + copies
        for name, extra, copies in (("near", "", near), ("far", "", far), ("moved", moved, near))), "--no-flip")
    assert res.exit_code == 0, res.output
    rows = {(r["object"], r["label"]): r for r in json.loads(res.stdout)["rows"]}
    # measured: every 8-bit frame of both equal to the near pair's; mean ΔLuv as near (0.016 direct, 0.038
    # deferred, 0.21 tessellated@3). Relative to the object's centre instead, the far copies' shadow map spans
    # 1.7e4 units and loses B's shadow: mean ΔLuv 8.1 (tests/test_instances.py has the surfaces' case).
    for label in ("reference", "impostor@direct", "impostor@deferred", "impostor@outlines", "tessellated@3"):
        for obj in ("far", "moved"):
            a, b = frames(out, "near", label), frames(out, obj, label)
            assert len(a) == len(b) == 2
            assert all((np.abs(x - y).max(-1) > 2).mean() < 0.002 for x, y in zip(a, b)), (label, obj)
            if label != "reference":
                r = rows[(obj, label)]
                assert abs(r["mean_dluv"] - rows[("near", label)]["mean_dluv"]) < 0.05 and r["iou"] > 0.995, (label, r)
                assert label == "impostor@outlines" or r["mean_dluv"] < 0.75, (label, r)


@pytest.mark.gl
def test_place_draws_the_copies_it_is_given(ctx):
    """A per-copy LOD mix (vdmrender.views.lodmix.LodMix) hands each variant, per frame, the copies whose band names it:
    `place` sets how many copies the next frame draws, from the buffer sized for all of them."""
    from vdmbake.kernels import quadrics
    from vdmrender.measuring import counters
    from vdmrender.gpu import gl
    from vdmrender.common.camera import Camera
    from vdmrender.techniques.impostor import Impostors
    from vdmrender.techniques.tessellated import Tessellated
    from frames import LIGHT as L, MATERIAL

    q = quadrics.inline([[0, 0, 0, 1], [2, 0, 0, 0.5]], [[0, 0, 0, 2, 0, 0, 0.2]], (0.7, 0.6, 0.5))
    world = np.tile(np.eye(4), (5, 1, 1))
    world[:, 1, 3] = np.arange(5) * 3.0
    cam = Camera(np.array([1.0, 6.0, 25.0]), np.array([1.0, 6.0, 0.0]), np.array([0.0, 1.0, 0.0]), 60.0, 48, 48,
                 0.1, 100.0)
    target = gl.Target(ctx, 48, 48)
    with counters.counting(ctx):
        renderers = [Impostors(ctx, q, L, MATERIAL, 128, "direct", 0, 0, world),
                     Tessellated(ctx, q, L, MATERIAL, 128, 1, world)]
    for r in renderers:
        covered = []
        for n in (5, 2):
            r.place(world[:n])
            target.clear()
            c = counters.count_frame(ctx, r, cam, target.kept())
            # a sphere draw and a cylinder draw per pass; two spheres and a cylinder a copy
            assert all(p["draws"] == 2 and p["instances"] == 3 * n for p in c["passes"].values()), c["passes"]
            covered.append(c["covered"])
        assert 0 < covered[1] < 0.6 * covered[0]   # two copies of five drawn
        r.release()
    target.release()


@pytest.mark.gl
@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_copies_scaled_by_orders_of_magnitude_look_as_at_unit_scale(tmp_path, scale):
    """Stress: the overlapping pair (B towards the light, turned, 0.75 of A) with both copies and their offset
    scaled by 1e-3 or 1e3, the orbit framing them: a scene scaled as a whole looks the same, so every impostor and
    tessellated frame equals the unit pair's (Sigg's bounds and the ray casts of the placed quadrics, the shadow
    map and its offsets follow the copies' size)."""
    radius = 1.69
    text = head(96, 1024)
    for name, s in (("unit", 1.0), ("scaled", scale)):
        text += (f'[[objects]]\nname = "{name}"\n' + SHAPE + TECHNIQUES +
                 placements(((0, 0, 0), (0, 0, 0), s), (1.4 * radius * s * LIGHT, (30, 60, 10), 0.75 * s)))
    res, out = bake_and_render(tmp_path, text, "--no-flip")
    assert res.exit_code == 0, res.output
    rows = {(r["object"], r["label"]): r for r in json.loads(res.stdout)["rows"]}
    for label in ("reference", "impostor@direct", "impostor@deferred", "impostor@outlines", "tessellated@3"):
        a, b = frames(out, "unit", label), frames(out, "scaled", label)
        assert len(a) == len(b) == 2 and all((np.abs(x - y).max(-1) > 2).mean() < 0.002 for x, y in zip(a, b)), label
        if label != "reference":   # measured: identical frames and errors at both scales
            assert abs(rows["scaled", label]["mean_dluv"] - rows["unit", label]["mean_dluv"]) < 0.05, label
