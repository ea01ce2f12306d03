"""Per-vertex colours (issue 12): an asset's own colours (a PLY's red/green/blue) as the shared shading
model's albedo, through loading, the bundle's mesh parts (only when the asset has them), the coarse
meshes, the `mesh`/`coarse` rasteriser and the reference; on pymeshlab's vertex-coloured airplane."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from scenes import bake_and_render, rows_by_label
from vdmbake.kernels import coarse
from vdmbake.bundle import parts
from vdmbake.assets import primitives
from vdmbake.assets.meshes import load_mesh_file, resolve_path
from vdmbake.common.mesh import TriMesh
from vdmbake.scene import Light, Material
from vdmrender.gpu import gl
from vdmrender.common import images
from vdmrender.comparing import metrics
from vdmrender.tracing import reference
from vdmrender.common.camera import orbit
from vdmrender.passes.raster import RasterMesh

AIRPLANE = "pkg:pymeshlab/tests/sample_meshes/colored_airplane.ply"
BG = (0.05, 0.05, 0.06)


def airplane() -> TriMesh:
    pytest.importorskip("pymeshlab")   # a test extra: only its sample meshes are used
    return load_mesh_file(resolve_path(AIRPLANE, Path(".")))


def test_loading_keeps_colours_only_where_the_asset_has_them():
    m = airplane()
    assert m.colors is not None and m.colors.shape == (len(m.vertices), 3)
    assert 0.0 <= m.colors.min() and m.colors.max() <= 1.0 and np.ptp(m.colors, axis=0).min() > 0.5
    back = parts.stored(parts.MESH, m)
    np.testing.assert_array_equal(back.colors, m.colors.astype(np.float32))
    plain = load_mesh_file(resolve_path("pkg:pymeshfix/examples/StanfordBunny.ply", Path(".")))
    assert plain.colors is None and b"red" not in parts.MESH.pack(plain)[0][:600]


def test_coarse_carries_colours():
    """A torus (UV-seamed) coloured by a smooth function of position: each coarse vertex's colour, the
    area-weighted mean of the vertices collapsed into it, is close to the function at its position."""
    m = primitives.torus(1.0, 0.35, 96, 48)
    f = lambda p: 0.5 + 0.5 * np.stack([np.sin(2 * p[:, 0]), np.cos(3 * p[:, 1]), np.sin(4 * p[:, 2])], 1)  # noqa: E731
    m = TriMesh(m.vertices, m.faces, m.normals, m.uvs, colors=f(m.vertices))
    for ratio, max_bound, mean_bound in ((0.5, 0.02, 0.001), (0.1, 0.15, 0.012)):
        c = coarse.simplify(m, ratio)
        assert c.colors is not None and c.colors.shape == (len(c.vertices), 3)
        error = np.abs(c.colors - f(c.vertices))
        # measured: max 0.0160, mean 0.00076 (0.5); max 0.123, mean 0.0090 (0.1)
        assert error.max() < max_bound and error.mean() < mean_bound


def test_raster_matches_the_coloured_reference():
    """The `mesh` rasteriser against the traced reference, both with the airplane's colours: near-exact,
    where the same frame against the reference with the material's albedo is far off."""
    m = airplane()
    light, material = Light(), Material()
    centre, radius = m.bounding_sphere()
    cams = orbit(SimpleNamespace(count=2, elevation_deg=25, azimuth_deg=30, distance=2.4, fov_deg=40),
                 [0, 1, 0], centre, radius, 96, 96)
    ctx = gl.create_context()
    target = gl.Target(ctx, 96, 96)
    r = RasterMesh(ctx, parts.stored(parts.MESH, m), light, material, 1024)
    coloured, plain = reference.MeshReference(m, light, material), \
        reference.MeshReference(TriMesh(m.vertices, m.faces, m.normals), light, material)
    try:
        for cam in cams:
            r.render(cam, target)
            frame = images.encode(target.read(), BG)
            good = metrics.compare(frame, images.encode(coloured.render(cam), BG))
            bad = metrics.compare(frame, images.encode(plain.render(cam), BG))
            # measured: 0.066 / 0.110 (IoU 1.0) against the coloured reference, 51.4 / 48.0 against the plain
            assert good["mean"] < 0.2 and good["iou"] > 0.999, good["mean"]
            assert bad["mean"] > 20
    finally:
        r.release()
        target.release()
        ctx.release()


def test_scene_to_report(tmp_path):
    """Scene -> bundle -> report: the bundle's full and coarse meshes carry the colours; `mesh` and `coarse`
    are scored against the coloured reference."""
    airplane()
    scene = ('[render]\nresolution = [64, 64]\nrepeats = 1\nwarmup = 0\nshadow_map = 512\n'
             '[camera]\nup = [0, 1, 0]\norbit = { count = 1, elevation_deg = 25, distance = 2.4 }\n'
             f'[[objects]]\nname = "plane"\nmesh = "{AIRPLANE}"\n'
             'techniques = { mesh = {}, coarse = { ratios = [0.5] } }\n')
    result, out = bake_and_render(tmp_path, scene, "--no-flip")
    assert result.exit_code == 0, result.output
    rows = rows_by_label(result)
    # measured at 64 px with a 512² shadow map: mesh 0.2425 (IoU 0.9981), coarse@0.5 0.918 (IoU 0.9981)
    assert rows["mesh"]["mean_dluv"] < 0.35 and rows["coarse@0.5"]["mean_dluv"] < 1.3
    from vdmbake.bundle.directory import Bundle
    b = Bundle(tmp_path / "b.bundle")
    entry = b.manifest["objects"]["plane"]
    assert b.read(entry["mesh"], parts.MESH).colors is not None
    assert b.read(entry["techniques"]["coarse"]["meshes"][0]["mesh"], parts.MESH).colors is not None
