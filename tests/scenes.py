"""Scene snippets shared by the tests: small enough that a bake and a render take well under a second."""
import json

RENDER = """\
[render]
resolution = [32, 32]
repeats = 1
warmup = 0
shadow_map = 256
"""
CAMERA = """
[camera]
orbit = { count = 1 }
"""
TINY_HEAD = RENDER + CAMERA
BALL = """
[[objects]]
name = "ball"
primitive = "sphere"
params = { segments = 16, rings = 8 }
techniques = { mesh = {} }
"""
GOOD_SCENE = TINY_HEAD + BALL   # the bad-input tests' good scene, which they damage


# A brick mesostructure on a plane, drawn by the two techniques that bake nothing of their own (object "p").
BRICK_PLANE = """
[[objects]]
name = "p"
primitive = "plane"
params = { size = 2.0, segments = 4 }
techniques = { pom = { steps = [8] }, bump = {} }
[objects.mesostructure]
height = "bricks"
size = 16
depth = 0.06
tiling = [2, 2]
"""

def scan_sweep(resolution: int, reference_spp: int, orbits: int, shadow_map: int = 2048) -> str:
    """The scanned Stanford bunny's 1% coarse mesh (object "scan", pymeshfix's copy) supersampled (ssaa4) and swept
    to 512 and 16 px across: its facets about a dozen pixels wide at 512, under half a pixel at 16."""
    return f"""
[render]
resolution = [{resolution}, {resolution}]
repeats = 1
warmup = 0
shadow_map = {shadow_map}
reference_spp = {reference_spp}
antialias = "ssaa4"

[render.sweep]
sizes = [512, 16]

[camera]
up = [0, 0, 1]
orbit = {{ count = {orbits}, elevation_deg = 20, azimuth_deg = 30, distance = 2.6, fov_deg = 40 }}

[[objects]]
name = "scan"
mesh = "pkg:pymeshfix/examples/StanfordBunny.ply"
[objects.techniques]
coarse = {{ ratios = [0.01] }}
"""


# Two copies of a sphere, one at the origin and one at [FAR, 0, 0] (the test replaces FAR), object "b".
FAR_COPIES = RENDER + """
[[objects]]
name = "b"
primitive = "sphere"
techniques = { mesh = {} }
[[objects.instances.placements]]
translate = [0, 0, 0]
[[objects.instances.placements]]
translate = [FAR, 0, 0]
"""


def bake_and_render(tmp_path, scene_text: str, *render_args, empty_reference_ok: bool = False):
    """Write scene_text, bake it, render it with --json; returns vdmrender's CliRunner result and
    the output folder (the bake must succeed; the render's exit code is the caller's to check).
    Every frame of the reference must cover pixels (a test of an empty frame measures nothing),
    unless empty_reference_ok."""
    from click.testing import CliRunner

    from vdmbake.cli import main as bake_main
    from vdmrender.cli import main as render_main

    scene, bundle, out = tmp_path / "scene.toml", tmp_path / "b.bundle", tmp_path / "out"
    scene.write_text(scene_text)
    r = CliRunner().invoke(bake_main, [str(scene), "-o", str(bundle)])
    assert r.exit_code == 0, r.output
    result = CliRunner().invoke(render_main, [str(bundle), "-o", str(out), "--json", *render_args])
    if not empty_reference_ok and (out / "report.json").is_file():
        report = json.loads((out / "report.json").read_text())
        for row in report["rows"]:
            empty = [f["frame"] for f in row["per_frame"] if f["coverage"] == 0]
            assert not empty, f"{row['object']}: the reference covers no pixel in frames {empty}"
    return result, out


def rows_by_label(result) -> dict:
    return {row["label"]: row for row in json.loads(result.stdout)["rows"]}
