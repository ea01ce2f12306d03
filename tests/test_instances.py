"""Instances (issue 23): an object drawn many times from one bake, by instanced draws (mesh, coarse, octahedral),
against a reference that traces every copy merged (vdmbake.common.instances)."""
import json
import shlex
import sys

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from scenes import RENDER, bake_and_render
from vdmbake.common import instances
from vdmbake.scene import parse_scene_dict

TECHNIQUES = ('techniques = { mesh = {}, coarse = { ratios = [0.3] }, octahedral = { variants = ["full-9x64-march"] }, '
              'billboards = { resolution = 32, variants = ["greedy-improved", "greedy-hier+coarse", "greedy-hier"] } }')
BOARDS = ("billboards@greedy-improved", "billboards@greedy-hier+coarse", "billboards@greedy-hier")


def scene_of(inst: dict):
    return parse_scene_dict({"objects": [{"name": "b", "primitive": "sphere", "instances": inst,
                                          "techniques": {"mesh": {}}}]}, "test")


def test_placements_scale_turn_and_move_about_the_centre():
    s = scene_of({"placements": [{"translate": [1, 2, 3], "rotate_deg": [0, 0, 90], "scale": 2.0}]})
    centre = np.array([5.0, 0.0, 1.0])
    (m,) = instances.matrices(s.objects[0].instances, (0, 0, 1), centre)
    apply = lambda p: m[:3, :3] @ p + m[:3, 3]   # noqa: E731
    assert apply(centre) == pytest.approx(centre + [1, 2, 3])            # the centre moves by translate
    assert apply(centre + [1, 0, 0]) == pytest.approx(centre + [1, 2, 3] + [0, 2, 0])   # scaled, turned about Z
    assert instances.scales(m[None]) == pytest.approx([2.0])


def test_scatter_is_seeded_on_the_plane_and_within_its_ranges():
    spec = {"scatter": {"count": 500, "area": [40, 10], "scale": [0.5, 2.0], "seed": 7}}
    up, centre = np.array([0.0, 0.0, 1.0]), np.array([1.0, 2.0, 3.0])
    m = instances.matrices(scene_of(spec).objects[0].instances, up, centre)
    assert np.array_equal(m, instances.matrices(scene_of(spec).objects[0].instances, up, centre))
    other = instances.matrices(scene_of({"scatter": {**spec["scatter"], "seed": 8}}).objects[0].instances, up, centre)
    assert not np.allclose(m, other)
    moved = np.einsum("nij,j->ni", m[:, :3, :3], centre) + m[:, :3, 3] - centre
    assert np.abs(moved[:, 2]).max() < 1e-12                        # on the plane through the centre, normal to up
    assert np.abs(moved[:, 0]).max() <= 20 and np.abs(moved[:, 1]).max() <= 5
    s = instances.scales(m)
    assert s.min() >= 0.5 and s.max() <= 2.0 and s.max() - s.min() > 1.0
    rot = m[:, :3, :3] / s[:, None, None]
    assert np.allclose(rot @ up, up)                                  # turned about up only
    assert np.allclose(np.einsum("nij,nkj->nik", rot, rot), np.eye(3))


def test_enclosing_sphere_holds_every_copy():
    m = instances.matrices(scene_of({"scatter": {"count": 50, "area": [8, 8], "scale": [0.2, 3]}}).objects[0].instances,
                           (0, 1, 0), (0, 0, 0))
    c, r = instances.enclosing(m, (0, 0, 0), 1.5)
    centres = m[:, :3, 3]
    assert (np.linalg.norm(centres - c, axis=1) + 1.5 * instances.scales(m) <= r + 1e-9).all()


@pytest.mark.parametrize("extra, message", [
    ('[objects.instances]\nplacements = [{ translate = [1, 0, 0] }]\nscatter = { count = 2, area = [1, 1] }\n',
     "exactly one of"),
    ("[objects.instances]\n", "exactly one of"),
])
def test_instances_need_one_source(tmp_path, extra, message):
    from vdmbake.cli import main as bake_main

    p = tmp_path / "s.toml"
    p.write_text(RENDER + '[[objects]]\nname = "b"\nprimitive = "sphere"\ntechniques = { mesh = {} }\n' + extra)
    r = CliRunner().invoke(bake_main, [str(p), "-o", str(tmp_path / "b")])
    assert r.exit_code == 2 and message in r.output, r.output


def test_instances_of_a_mesostructure_are_refused():
    with pytest.raises(Exception, match="without a mesostructure"):
        parse_scene_dict({"objects": [{"name": "b", "primitive": "plane", "techniques": {"relief": {}},
                                       "mesostructure": {"height": "bricks", "size": 8},
                                       "instances": {"scatter": {"count": 3, "area": [1, 1]}}}]}, "t")


def frames(out, obj, label):
    folder = out / ("reference" if label == "reference" else "frames") / obj / ("" if label == "reference" else label)
    return [np.asarray(Image.open(p).convert("RGB"), int) for p in sorted(folder.glob("[0-9][0-9][0-9].png"))]


LIGHT = np.array([0.45, -0.55, 0.7]) / np.linalg.norm([0.45, -0.55, 0.7])   # the scenes' default light
SURFACES = ('techniques = { mesh = {}, coarse = { ratios = [0.3] }, octahedral = { variants = ["full-9x64-march"] }, '
            'billboards = { resolution = 32, variants = ["greedy-improved", "greedy-hier+coarse"] } }')


def torus_pair(name: str, techniques: str, at=(0.0, 0.0, 0.0), s: float = 1.0) -> str:
    """An object of two torus copies: A at `at`, B 2.3 s towards the light from it (between A and the light, partly
    in front of it), turned and 0.8 of A; both scaled by s."""
    at = np.asarray(at, float)
    b = at + 2.3 * s * LIGHT
    return (f'[[objects]]\nname = "{name}"\nprimitive = "torus"\n{techniques}\n'
            f'[[objects.instances.placements]]\ntranslate = {at.tolist()}\nscale = {s}\n'
            f'[[objects.instances.placements]]\ntranslate = {b.tolist()}\nscale = {0.8 * s}\nrotate_deg = [30, 50, 10]\n')


def share_apart(out, a: str, b: str, label: str) -> list[float]:
    """Per frame, the share of pixels whose 8-bit colours differ by more than 2 between objects a and b."""
    fa, fb = frames(out, a, label), frames(out, b, label)
    assert len(fa) == len(fb) > 0, label
    return [float((np.abs(x - y).max(-1) > 2).mean()) for x, y in zip(fa, fb)]

@pytest.mark.gl
@pytest.mark.slow
def test_one_copy_in_place_draws_as_the_object_alone(tmp_path):
    one = ('[[objects]]\nname = "b"\nprimitive = "sphere"\n' + TECHNIQUES +
           '\n[[objects.instances.placements]]\ntranslate = [0, 0, 0]\n')
    alone = '[[objects]]\nname = "a"\nprimitive = "sphere"\n' + TECHNIQUES + "\n"
    res, out = bake_and_render(tmp_path, RENDER.replace("[32, 32]", "[48, 48]") + one + alone, "--no-flip")
    assert res.exit_code == 0, res.output
    for label in ("reference", "mesh", "coarse@0.3", "octahedral@full-9x64-march", *BOARDS):
        a, b = frames(out, "a", label), frames(out, "b", label)
        assert len(a) == len(b) > 0
        worst = max(int(np.abs(x - y).max()) for x, y in zip(a, b))
        # octahedral: the normal renormalised; hier billboards: a quad over the copy and no occupancy pre-pass
        assert worst <= (0 if label in ("reference", "mesh", "coarse@0.3", BOARDS[0]) else 1), (label, worst)


@pytest.mark.gl
def test_overlapping_copies_hide_and_shadow_each_other_as_in_the_reference(tmp_path):
    """Copy B stands between copy A and the light and partly in front of it: the instanced draws and the merged
    reference agree on every pixel's depth order and on B's shadow over A."""
    b = 2.3 * LIGHT
    pair = ('[[objects]]\nname = "pair"\nprimitive = "sphere"\ntechniques = { mesh = {} }\n'
            '[[objects.instances.placements]]\ntranslate = [0, 0, 0]\n'
            f'[[objects.instances.placements]]\ntranslate = [{b[0]}, {b[1]}, {b[2]}]\nscale = 0.8\n')
    res, out = bake_and_render(tmp_path, RENDER.replace("[32, 32]", "[96, 96]").replace("256", "1024") + pair,
                               "--no-flip")
    assert res.exit_code == 0, res.output
    row = json.loads(res.stdout)["rows"][0]
    assert row["mean_dluv"] < 0.1 and row["iou"] > 0.999, row
    # the scene has what the agreement is about: B casts a shadow on A's lit side (rays from there to the light
    # meet B) and covers part of A in some frame
    from vdmbake.bundle.directory import Bundle
    from vdmbake.common.embree import RayScene

    bundle = Bundle(tmp_path / "b.bundle")
    obj = bundle.scene.objects[0]
    placed = instances.placed(bundle.surface(bundle.manifest["objects"]["pair"]),
                              instances.matrices(obj.instances, bundle.scene.camera.up, (0, 0, 0)))
    lit_side = np.array([LIGHT + 0.2 * d for d in np.eye(3)])
    lit_side /= np.linalg.norm(lit_side, axis=1, keepdims=True)
    assert RayScene(placed.vertices, placed.faces).occluded(lit_side * 1.001, np.tile(LIGHT, (3, 1))).all()
    assert row["coverage"] > 0.05


def test_memory_guard_counts_every_copy(tmp_path):
    from vdmbake.cli import main as bake_main
    from vdmbake.bundle.directory import Bundle
    from vdmbake.bundle.budget import Geometry
    from vdmrender.render import held_geometry

    p = tmp_path / "s.toml"
    p.write_text(RENDER + '[[objects]]\nname = "b"\nprimitive = "sphere"\ntechniques = { mesh = {} }\n'
                 "[objects.instances]\nscatter = { count = 1000, area = [100, 100] }\n")
    assert CliRunner().invoke(bake_main, [str(p), "-o", str(tmp_path / "b")]).exit_code == 0
    bundle = Bundle(tmp_path / "b")
    faces = bundle.manifest["parts"]["objects/b/mesh.ply"]["faces"]
    assert held_geometry(bundle) == (Geometry("b", 1000 * faces),)


@pytest.mark.gl
@pytest.mark.slow
def test_bench_quick_smoke(tmp_path, monkeypatch, no_warm_up):
    """make bench-instances runs end to end (a sphere, 1 and 4 copies) and publishes its JSON with its provenance,
    which the docs' view renders as the bench's own instances.md does."""
    import bench.instances
    from helpers import make_docs

    args = ["-o", str(tmp_path), "--quick", "--publish", str(tmp_path / "results")]
    monkeypatch.setattr(sys, "argv", ["instances.py", *args])
    r = CliRunner().invoke(bench.instances.main, args)
    assert r.exit_code == 0, r.output
    result = json.loads((tmp_path / "instances.json").read_text())
    published = json.loads((tmp_path / "results" / "instances.json").read_text())
    view = make_docs().VIEWS["instances"]
    assert f"`{shlex.join(['python', '-m', 'bench.instances', *args])}`" in view(published, "provenance")
    assert published.pop("provenance")["device"] == result["device"] and published == result
    fields = view(published, "fields")   # the docs' table is the bench's own
    assert fields in (tmp_path / "instances.md").read_text()
    assert fields.count("\n") == 2 + len(result["counts"]) and "| sphere (" in fields
    assert {(r["copies"], r["label"]) for r in result["rows"]} >= {
        (4, "mesh"), (4, "octahedral@full-9x64-virtual"), (4, "billboards@greedy-hier+coarse"), (4, "lod@dluv3")}
    four = {r["label"]: r for r in result["rows"] if r["copies"] == 4}
    assert four["mesh"]["primitives"] == 4 * [r for r in result["rows"] if r["copies"] == 1 and
                                              r["label"] == "mesh"][0]["primitives"]
    assert all(r["mean_dluv"] is not None for r in result["rows"])
    chain = result["bakes"]["sphere"]["chain"]   # one band below the one size measured, its variant the lod row's
    assert [(e["min_px"], e["max_px"]) for e in chain] == [(0, 16)]
    mixed, alone = four["lod@dluv3"], four[chain[0]["variant"]]
    # the same copies by the same variant; the mix's shadow map is the composite's, fitted to another sphere
    assert mixed["primitives"] == alone["primitives"] and abs(mixed["mean_dluv"] - alone["mean_dluv"]) < 0.05
    assert (tmp_path / "instances.md").is_file() and (tmp_path / "instances.png").is_file()


def test_each_copy_takes_the_band_its_screen_size_falls_in():
    from vdmrender.views import lodmix
    from vdmrender.common.camera import Camera
    from vdmrender.views.sweep import distance_for

    entries = [{"variant": "mesh", "min_px": 64, "max_px": 256}, {"variant": "coarse@0.1", "min_px": 16, "max_px": 64},
               {"variant": "octahedral@x", "min_px": 0, "max_px": 16}]
    sizes = np.array([1000.0, 256, 65, 64, 17, 16, 3, 0.5, np.inf])
    assert lodmix.pick(entries, sizes).tolist() == [0, 0, 0, 1, 1, 2, 2, 2, 0]
    cam = Camera(np.zeros(3), np.array([0, 0, -1.0]), np.array([0, 1.0, 0]), 40.0, 300, 200, 0.1, 100.0)
    d = distance_for(48, 1.5, 40.0, 200)   # the sweep's distance for 48 px gives back 48 px
    px = lodmix.screen_px(cam, np.array([[0, 0, -d], [0, 0, -0.5]]), np.array([1.5, 1.0]))
    assert px[0] == pytest.approx(48) and px[1] == np.inf


@pytest.mark.gl
@pytest.mark.slow
def test_per_copy_lod_row_draws_each_copy_by_its_band(tmp_path):
    text = RENDER.replace("[32, 32]", "[80, 48]") + """
[render.sweep]
sizes = [48, 12, 4]
[[render.sweep.lod]]
name = "fine"
mean_dluv = 1.0
[camera]
poses = [{ eye = [-9, -9, 3], target = [0, 0, 0], fov_deg = 60 }, { eye = [9, -9, 2], target = [0, 0, 0] }]
[[objects]]
name = "field"
primitive = "sphere"
techniques = { mesh = {}, coarse = { ratios = [0.2, 0.03] } }
[objects.instances]
scatter = { count = 40, area = [16, 16], scale = [0.6, 1.2], seed = 2 }
"""
    res, out = bake_and_render(tmp_path, text, "--no-flip")
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout)
    rows = {r["label"]: r for r in report["rows"]}
    mix = rows["lod@fine"]
    assert mix["technique"] == "lod" and sum(mix["lod_copies"].values()) == 40 * 2
    priced = report["lod"]["chains"][0]["objects"]["field"]
    chain = priced.get("sweep_entries", priced["entries"])   # the row draws the sweep's chain, whatever the field chose
    assert set(mix["lod_copies"]) == {e["variant"] for e in chain}
    assert priced["field"]["chosen"] in {r["label"] for r in report["rows"]}
    assert mix["counters"]["instances"] == 2 * 40 * 2   # every copy once per pass (light, frame), per camera
    # the mix is drawn by the chain's variants only: its error within theirs, the coverage the reference's
    assert mix["mean_dluv"] <= max(rows[v]["mean_dluv"] for v in mix["lod_copies"]) + 0.05
    assert mix["iou"] > 0.98


@pytest.mark.gl
def test_a_variant_holding_two_bands_draws_the_copies_of_both(ctx):
    """A chain may come back to a variant (coarse@0.1 near, octahedral between, coarse@0.1 far): each frame places
    every copy whose band names it, not the last band's alone."""
    from vdmbake.scene import Light
    from vdmrender.views import lodmix
    from vdmrender.common.camera import Camera

    class Fake:
        anchor, faces = np.zeros(3), 0

        def __init__(self):
            self.shadow, self.placed = None, []

        def place(self, m):
            self.placed.append(len(m))

        def passes(self, camera, target):
            return []

        def release(self):
            pass

    entries = [{"variant": "coarse@0.1", "min_px": 64, "max_px": 256}, {"variant": "oct", "min_px": 32, "max_px": 64},
               {"variant": "coarse@0.1", "min_px": 0, "max_px": 32}]
    world = np.tile(np.eye(4), (3, 1, 1))
    world[:, 0, 3] = [-5.0, -15.0, -400.0]   # one copy near (144 px), one between (47 px), one far (2 px)
    fakes = {"coarse@0.1": Fake(), "oct": Fake()}
    cam = Camera(np.zeros(3), np.array([-1.0, 0, 0]), np.array([0, 0, 1.0]), 40.0, 256, 256, 0.1, 1000.0)
    sizes = lodmix.screen_px(cam, world[:, :3, 3], np.ones(3))
    assert [lodmix.pick(entries, sizes).tolist()] == [[0, 1, 2]]
    mix = lodmix.LodMix(ctx, fakes, entries, world, (np.zeros(3), 1.0), (np.zeros(3), 500.0), Light(), 256)
    target = type("T", (), {"kept": lambda self: self})()
    mix.passes(cam, target)
    assert fakes["coarse@0.1"].placed == [2] and fakes["oct"].placed == [1]
    mix.release()


@pytest.mark.gl
@pytest.mark.slow
def test_billboard_copies_hide_and_shadow_each_other_as_in_the_reference(tmp_path):
    """The overlap case for billboards: copy B, turned and scaled, between copy A and the light and partly in
    front of it, against the merged reference: every billboard method within its bound in mean ΔLuv and IoU (the
    copies are smaller on screen than the torus framed alone, so their silhouette texels weigh more than there;
    with the normals left unturned the error is several times larger)."""
    boards = 'billboards = { resolution = 32, variants = ["greedy-improved", "greedy-hier+coarse", "greedy-hier"] }'
    pair = torus_pair("pair", f"techniques = {{ mesh = {{}}, {boards} }}")
    res, out = bake_and_render(tmp_path, RENDER.replace("[32, 32]", "[96, 96]").replace("256", "1024") + pair,
                               "--no-counters", "--no-flip")
    assert res.exit_code == 0, res.output
    rows = {(r["object"], r["label"]): r for r in json.loads(res.stdout)["rows"]}
    for label in BOARDS:
        assert rows["pair", label]["mean_dluv"] < 4.0 and rows["pair", label]["iou"] > 0.95, rows["pair", label]


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    """One bake and render of the overlapping torus pair four times: at the origin at unit scale ("unit"), placed
    1.7e4 units from the object itself ("far"), and scaled by 1e-3 and 1e3 ("small", "large"); each object is
    framed and drawn alone, so the tests below compare two of them. Without counters or FLIP: the frames and ΔLuv are the subject.
    A 512² shadow map: the pairs are compared with each other, and a 1024² one shows the same differences (none
    above 0.0005 of the pixels, ΔLuv within 0.0001) at 1.8x the CPU."""
    text = RENDER.replace("[32, 32]", "[64, 64]").replace("256", "512")
    text += (torus_pair("unit", SURFACES) + torus_pair("far", SURFACES, at=(1e4, -1e4, 1e4))
             + torus_pair("small", SURFACES, s=1e-3) + torus_pair("large", SURFACES, s=1e3))
    res, out = bake_and_render(tmp_path_factory.mktemp("pairs"), text, "--no-counters", "--no-flip")
    assert res.exit_code == 0, res.output
    return {(r["object"], r["label"]): r for r in json.loads(res.stdout)["rows"]}, out


@pytest.mark.gl
@pytest.mark.slow
def test_surface_copies_far_from_the_object_look_as_near_it(pairs):
    """Every surface technique, the pair of copies placed 1.7e4 units from the object itself, the cameras with
    them: drawn about the copies' own sphere (instances.enclosing), not the object's centre, the frames are the
    near pair's (float32 coordinates stay small, the shadow map spans the copies, not the 1.7e4 units between)."""
    rows, out = pairs
    for label in ("mesh", "coarse@0.3", "octahedral@full-9x64-march", *BOARDS[:2]):
        near, far = rows["unit", label], rows["far", label]
        assert abs(far["mean_dluv"] - near["mean_dluv"]) < 0.05 and far["iou"] > near["iou"] - 0.002, (label, far, near)
        assert max(share_apart(out, "unit", "far", label)) < 0.002, label


@pytest.mark.gl
@pytest.mark.slow
@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_copies_scaled_by_orders_of_magnitude_look_as_at_unit_scale(pairs, scale):
    """Stress: the overlapping pair with both copies (and their offset) scaled by 1e-3 or 1e3, the cameras
    framing them: a scene scaled as a whole looks the same, so the frames equal the unit pair's up to a few
    pixels and the same error (rays taken into a copy's frame divide by s^2; shadow offsets, the coarse mesh's
    push and the shadow map follow the copies' size). It found two faults of the octahedral impostor: its shadow
    offset in atlas texels ignored the copy's scale, and its shadow map was sized for copies of the object's
    size."""
    rows, out = pairs
    scaled = {1e-3: "small", 1e3: "large"}[scale]
    for label in ("reference", "mesh", "coarse@0.3", "octahedral@full-9x64-march", *BOARDS[:2]):
        assert max(share_apart(out, "unit", scaled, label)) < 0.002, label
        if label != "reference":
            assert abs(rows[scaled, label]["mean_dluv"] - rows["unit", label]["mean_dluv"]) < 0.1, label
