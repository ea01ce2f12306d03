"""What a viewer sees of a pixel (issue 30): the box-filtered reference against the exact coverage of a sphere's
silhouette, the GL frames anti-aliased and resolved in linear colour, and the error that falls with screen size
once both sides are filtered."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from scenes import scan_sweep
from vdmbake.assets import primitives
from vdmbake.common.colour import srgb8_to_linear
from vdmbake.kernels.quadrics import QuadricSet
from vdmbake.scene import Light, Material
from vdmrender.measuring import antialias
from vdmrender.gpu import gl
from vdmrender.common import images
from vdmrender.tracing import reference
from vdmrender.common.camera import Camera, clip_planes
from vdmrender.passes.raster import RasterMesh

SIZE, FOV, DISTANCE, RADIUS = 40, 40.0, 4.0, 1.0
FLAT = Light(direction=(0.0, 0.0, 1.0), color=(0.0, 0.0, 0.0), ambient=(0.5, 0.5, 0.5))   # radiance: 0.5 albedo
MATTE = Material(albedo=(1.0, 1.0, 1.0), diffuse=0.0, specular=0.0)


def camera(size: int = SIZE) -> Camera:
    eye, centre = np.array([0.0, 0.0, DISTANCE]), np.zeros(3)
    return Camera(eye, centre, np.array([0.0, 1.0, 0.0]), FOV, size, size, *clip_planes(eye, centre, centre, RADIUS))


def coverage(size: int = SIZE, steps: int = 4000) -> np.ndarray:
    """(H, W): the fraction of each pixel inside the sphere's silhouette, a circle about the image centre of radius
    tan(asin(r / D)) on the plane at view depth 1; by the midpoint rule across each pixel column of the exact
    height of the circle within the pixel's row."""
    rho = RADIUS / math.sqrt(DISTANCE**2 - RADIUS**2) / math.tan(math.radians(FOV) / 2) * size / 2
    c = size / 2
    x = (np.arange(size * steps) + 0.5) / steps                      # every column's sample positions, pixels
    half = np.sqrt(np.maximum(rho**2 - (x - c) ** 2, 0.0))
    rows = np.arange(size)[:, None]
    inside = np.clip(np.minimum(rows + 1, c + half) - np.maximum(rows, c - half), 0.0, None)   # (rows, columns)
    return inside.reshape(size, size, steps).mean(-1)


def sphere_reference() -> reference.QuadricReference:
    q = QuadricSet(np.array([[0.0, 0.0, 0.0, RADIUS]]), np.ones((1, 3), np.float32), np.zeros((0, 7)),
                   np.zeros((0, 3), np.float32))
    return reference.QuadricReference(q, FLAT, MATTE)


def test_the_exact_coverage_is_a_circle():
    """The test's own yardstick: the coverage sums to the circle's area."""
    rho = RADIUS / math.sqrt(DISTANCE**2 - RADIUS**2) / math.tan(math.radians(FOV) / 2) * SIZE / 2
    assert coverage().sum() == pytest.approx(math.pi * rho**2, rel=1e-5)


def test_one_sample_is_the_pixel_centre():
    """At 1 spp the filtered reference is the point-sampled one, bit for bit."""
    ref, cam = sphere_reference(), camera()
    frame, half = reference.filtered(ref.render, cam, 1)
    np.testing.assert_array_equal(frame, ref.render(cam))
    assert half is None   # one sample: no noise to estimate


def test_the_noise_estimate_from_two_halves_of_the_strata_is_the_true_error():
    """The reference's own noise (scoring.noise, from two halves of its strata, each pixel by its own counts: the
    samples are adaptive) against its true error, the filtered frame against the sphere's exact coverage (both
    encoded over the background, mean ΔLuv over the pixels either covers): within 30% of it at 16, 36 and 64 spp,
    falling as the samples grow; 0 for a frame whose every sample agrees (the inside of the silhouette)."""
    from vdmrender.comparing import metrics, scoring

    ref, cam, exact = sphere_reference(), camera(), coverage()
    bg = np.array([0.1, 0.2, 0.3])
    truth = images.encode(np.dstack([0.5 * exact[..., None].repeat(3, -1), exact]).astype(np.float32), bg)
    estimated, true = {}, {}
    for spp in (16, 36, 64):
        f, half = reference.filtered(ref.render, cam, spp)
        estimated[spp] = scoring.noise([f], [half], bg)
        true[spp] = metrics.compare(images.encode(f, bg), truth)["mean"]
        assert estimated[spp] == pytest.approx(true[spp], rel=0.3), (spp, estimated[spp], true[spp])
    assert estimated[16] > estimated[36] > estimated[64] > 0
    inside = np.zeros((cam.height, cam.width, 4), np.float32)
    inside[15:25, 15:25] = (0.5, 0.5, 0.5, 1.0)
    counts = np.full(inside.shape[:2], 16)
    assert scoring.noise([inside], [reference.Halves(inside, counts, counts // 2)], bg) == 0.0


def test_filtered_reference_is_coverage_times_radiance():
    """Edge pixels of a flat-shaded sphere: the filtered reference's alpha is the pixel's covered fraction within
    the stratified sampling's error (falling as 1/N), its colour that fraction times the radiance
    (premultiplied), and encoded over the background it is the mix a viewer sees."""
    ref, cam, exact = sphere_reference(), camera(), coverage()
    errors = {}
    for spp in (4, 64):
        f, _ = reference.filtered(ref.render, cam, spp)
        np.testing.assert_allclose(f[..., :3], np.broadcast_to(0.5 * f[..., 3:], f[..., :3].shape), atol=1e-6)
        edge = (exact > 0) & (exact < 1)
        inner, outer = exact == 1, exact == 0
        assert (f[inner, 3] == 1).all() and (f[outer, 3] == 0).all()
        errors[spp] = np.abs(f[edge, 3] - exact[edge])
    assert errors[64].mean() < 0.02 and errors[64].max() < 0.1
    assert errors[64].mean() < 0.25 * errors[4].mean()
    bg = np.array([0.1, 0.2, 0.3])
    shown = srgb8_to_linear(images.encode(f, bg)[..., :3])
    mix = f[..., 3:] * 0.5 + (1 - f[..., 3:]) * bg
    np.testing.assert_allclose(shown, mix, atol=0.01)


def test_supersampled_resolve_is_the_box_mean(ctx):
    """ssaaK's resolve: each pixel the mean of its K x K texels in linear colour (shaders/resolve.frag)."""
    t = antialias.Target(ctx, 5, 3, "ssaa3")
    try:
        big = np.random.default_rng(1).random((9, 15, 4)).astype(np.float32)
        t.buffers.color.write(big.tobytes())
        t.resolve()
        expected = big.reshape(3, 3, 5, 3, 4).mean((1, 3))[::-1]    # read() puts row 0 at the top
        np.testing.assert_allclose(t.read(), expected, rtol=1e-6, atol=1e-6)
    finally:
        t.release()


@pytest.mark.parametrize("mode, worst", [("ssaa4", 0.1), ("msaa4", 0.25)])
def test_antialiased_frames_cover_edge_pixels_in_part(ctx, mode, worst):
    """A finely tessellated sphere drawn through an anti-aliased target and its resolve (timed as a pass): its
    alpha is each pixel's coverage within the mode's sampling error, and its colour premultiplied as the
    filtered reference's; without anti-aliasing every pixel is covered wholly or not at all."""
    mesh = primitives.sphere(RADIUS, 256, 128)
    cam, exact = camera(), coverage()
    edge = (exact > 0.02) & (exact < 0.98)
    renderer = RasterMesh(ctx, mesh, FLAT, MATTE, 256)
    shipped = antialias.Target(ctx, SIZE, SIZE, mode)
    plain = gl.Target(ctx, SIZE, SIZE)
    try:
        shipped.clear()
        passes = antialias.Resolved(renderer).passes(cam, shipped.kept())
        assert passes[-1][0] == "resolve"
        for _, run in passes:
            run()
        f = shipped.read()
        renderer.render(cam, plain)
        point = plain.read()
    finally:
        renderer.release()
        shipped.release()
        plain.release()
    assert np.abs(f[edge, 3] - exact[edge]).mean() < worst / 2 and np.abs(f[edge, 3] - exact[edge]).max() <= worst
    np.testing.assert_allclose(f[..., :3], np.broadcast_to(0.5 * f[..., 3:], f[..., :3].shape), atol=2e-3)
    assert set(np.unique(point[..., 3])) <= {0.0, 1.0}


def test_msaa_beyond_the_device_is_refused(ctx):
    with pytest.raises(Exception, match="at most"):
        antialias.Target(ctx, 8, 8, f"msaa{2 * ctx.max_samples}")


SCAN = scan_sweep(64, reference_spp=64, orbits=4, shadow_map=512)


@pytest.mark.slow
def test_filtered_error_falls_with_screen_size(tmp_path):
    """The scanned bunny's 1% coarse mesh: its facets are about a dozen pixels wide at 512 px across and under half
    a pixel at 16, so what a viewer sees of its error falls; against the pixel-centre reference (aliased_*), a facet edge
    still flips whole pixels at 16 px and the error does not fall alike."""
    from vdmbake.cli import main as bake
    from vdmrender.cli import main as render

    (tmp_path / "scan.toml").write_text(SCAN)
    r = CliRunner().invoke(bake, [str(tmp_path / "scan.toml"), "-o", str(tmp_path / "b")])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(render, [str(tmp_path / "b"), "-o", str(tmp_path / "o"), "--no-flip", "--no-counters"])
    assert r.exit_code == 0, r.output
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["filtering"]["reference_spp"] == 64 and report["filtering"]["antialias"] == "ssaa4"
    # adaptive: every pixel its first 8 samples, only the pixels that need them all 64 (25.5 on average here)
    assert 8 < report["filtering"]["reference_mean_spp"] < 48
    rows = {row["size_px"]: row for row in report["sweep"]["rows"]}
    filtered = rows[16]["mean_dluv"] / rows[512]["mean_dluv"]
    aliased = rows[16]["aliased_mean_dluv"] / rows[512]["aliased_mean_dluv"]
    assert filtered < 0.7 and filtered < aliased - 0.1, (rows[16], rows[512])
    assert (tmp_path / "o" / "reference" / "scan" / "point" / "000.exr").is_file()
    assert "resolve" in report["rows"][0]["passes_ms"]


def test_a_baseline_measured_otherwise_is_not_compared_for_error(tmp_path):
    """Errors against a 1-spp reference and against a 16-spp one are different measures: --max-error-increase
    across them is refused (exit 2), and without it the change table leaves the error changes out, saying why."""
    from vdmrender.deciding import baseline

    old = {"filtering": {"reference_spp": 1, "antialias": "none"}}
    assert baseline.errors_comparable(old, {"reference_spp": 1, "antialias": "none"}) is None
    assert baseline.errors_comparable({}, {"reference_spp": 1, "antialias": "none"}) is None   # an older report
    assert "16 spp" in baseline.errors_comparable(old, {"reference_spp": 16, "antialias": "msaa4"})
    row = {"object": "o", "label": "mesh", "median_ms": 1.0, "spread_ms": 0.1, "mean_dluv": 1.0}
    block = baseline.compare({**old, "rows": [row]}, {"filtering": {"reference_spp": 16, "antialias": "none"},
                                                      "rows": [{**row, "mean_dluv": 9.0}]}, 0.5, None)
    assert block["rows"][0]["d_mean_dluv"] is None and not block["failed"]
    assert any("errors not compared" in n for n in block["notes"])


def _impostor_frame(ctx, q, cam, mode):
    """The direct impostors of q drawn through an anti-aliased target and its resolve: the frame (linear RGBA)."""
    from vdmrender.techniques.impostor import Impostors

    renderer = Impostors(ctx, q, FLAT, MATTE, 256, "direct", 0.0, 0.0)
    shipped = antialias.Target(ctx, cam.width, cam.height, mode)
    try:
        shipped.clear()
        for _, run in antialias.Resolved(renderer).passes(cam, shipped.kept()):
            run()
        return shipped.read()
    finally:
        renderer.release()
        shipped.release()


def test_msaa_covers_a_ray_cast_spheres_edge_pixels_in_part(ctx):
    """Under MSAA an impostor's quad covers its whole box, so the pixel centre's ray alone decided a pixel: covered
    wholly or not at all (villin's atoms smaller than a pixel vanished, IoU 0.003 at 16 px under msaa4). Each
    sample's ray now decides its sample (gl_SampleMask): the edge pixels' alpha is their coverage within msaa4's
    error, as a tessellated sphere's is, and colour stays premultiplied."""
    cam, exact = camera(), coverage()
    edge = (exact > 0.02) & (exact < 0.98)
    f = _impostor_frame(ctx, sphere_reference().q, cam, "msaa4")
    assert np.abs(f[edge, 3] - exact[edge]).mean() < 0.125 and np.abs(f[edge, 3] - exact[edge]).max() <= 0.25
    assert ((f[edge, 3] > 0) & (f[edge, 3] < 1)).mean() > 0.5   # most edge pixels covered in part
    np.testing.assert_allclose(f[..., :3], np.broadcast_to(0.5 * f[..., 3:], f[..., :3].shape), atol=2e-3)


def test_a_sphere_smaller_than_a_pixel_keeps_its_samples_under_msaa(ctx):
    """A sphere 0.9 pixel across centred on a pixel corner: no pixel centre's ray meets it, so it was not drawn at
    all; its samples' rays now cover about its area (0.64 px; each of msaa4's 16 samples around it stands for a
    quarter of a pixel, and two of them either way is within the pattern's error)."""
    size, fov, radius = 40, 40.0, 0.45   # radius in pixels on the image plane
    f_px = 0.5 * size / math.tan(math.radians(fov) / 2)
    distance = math.sqrt(1.0 + (f_px / radius) ** 2)            # rho = f r / sqrt(d^2 - r^2) for r = 1
    eye, centre = np.array([0.0, 0.0, distance]), np.zeros(3)
    cam = Camera(eye, centre, np.array([0.0, 1.0, 0.0]), fov, size, size, *clip_planes(eye, centre, centre, RADIUS))
    covered = _impostor_frame(ctx, sphere_reference().q, cam, "msaa4")[..., 3].sum()
    assert covered > 0 and covered == pytest.approx(math.pi * radius ** 2, abs=2 / 4), covered
