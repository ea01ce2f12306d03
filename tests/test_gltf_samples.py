"""glTF as published samples have it (issue 33, reading): several materials and textures per file, factors applied
once, the file's normals (and coarse levels that agree with them), sparse accessors, morph targets, strips and
fans, points and lines refused or left out by name. The files are rebuilt from the samples' numbers
(tests/gltf_files.py); every expected value is written from those numbers, not from our reader or reference."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import gltf_files as G
from gltf_files import BG, albedo_at, drawn_and_traced
from vdmbake.assets.meshes import load_mesh_file
from vdmbake.common.mesh import TriMesh
from vdmbake.bundle import parts
from vdmbake.common.colour import srgb8_to_linear
from vdmbake.errors import InputError
from vdmbake.kernels import coarse


def at_uv(k: int, s: float, t: float) -> list[float]:
    """The point of quad k (node at x = 2k) at glTF texture coordinates (s, t): the quad's UVs are (x, 1 - y)."""
    return [2 * k + s, 1 - t, 0]


# ------------------------------------------------------------- 1. several textures, each read at its own UVs

def test_each_textured_primitive_reads_its_own_picture(tmp_path):
    m = load_mesh_file(G.texture_coordinate_test(tmp_path / "tct.gltf"))
    for k, picture in enumerate(G.PICTURES):
        for row in (0, 1):
            for col in (0, 1):   # the texel's centre: (col + 1/2) / 2 across, (row + 1/2) / 2 down the picture
                got = albedo_at(m, [at_uv(k, (col + 0.5) / 2, (row + 0.5) / 2)])[0]
                want = srgb8_to_linear(picture[row, col])
                assert np.allclose(got, want, rtol=0, atol=1e-6), (k, row, col, got, want)
    assert np.allclose(albedo_at(m, [at_uv(3, 0.3, 0.6)]), [0.85, 0.425, 0.2], rtol=0, atol=1e-6)


def test_uvs_between_texel_centres_blend_as_the_file_wraps(tmp_path):
    """Bilinear between the texel centres and across the picture's edge (REPEAT: the opposite edge's texel)."""
    m = load_mesh_file(G.texture_coordinate_test(tmp_path / "tct.gltf", factor_only=None))
    lin = [srgb8_to_linear(p) for p in G.PICTURES]
    for k in range(3):
        middle = lin[k].mean((0, 1))                                     # between all four centres
        edge = 0.5 * (lin[k][0, 0] + lin[k][0, 1])                       # at s = 0, on row 0's centre: wraps
        got = albedo_at(m, [at_uv(k, 0.5, 0.5), at_uv(k, 0.0, 0.25)])
        assert np.allclose(got, [middle, edge], rtol=0, atol=1e-6), (k, got)


def test_uvs_leaving_the_picture_with_several_pictures_wrap(tmp_path):
    """Refused before issue 43 (a wrapped UV read the neighbouring tile): UVs over [0, 2] read each picture as
    REPEAT does, texel (0, 0) at (0.25, 0.25), (1.25, 0.25) and (0.25, 1.25) (the quad's point (s / 2, 1 - t / 2))."""
    g = G.Gltf()
    for k, picture in enumerate(G.PICTURES[:2]):
        g.node(mesh=g.mesh(g.primitive(material=g.material(picture=picture), uv=G.UV * 2)), translation=[2 * k, 0, 0])
    m = load_mesh_file(g.write(tmp_path / "wrap.gltf"))
    for k, picture in enumerate(G.PICTURES[:2]):
        got = albedo_at(m, [[2 * k + s / 2, 1 - t / 2, 0] for s, t in ((0.25, 0.25), (1.25, 0.25), (0.25, 1.25))])
        assert np.allclose(got, srgb8_to_linear(picture[0, 0]), rtol=0, atol=1e-6), (k, got)


def test_render_of_several_textures_shows_the_file_colours(tmp_path, ctx):
    """Uniform pictures and a factor-only quad: the `mesh` technique's frame against the reference of the same quads
    coloured per vertex with the colours the file gives (no texture), and our reference likewise."""
    from vdmbake.scene import Light, Material
    from vdmrender.common import images
    from vdmrender.tracing import reference
    from vdmrender.common.camera import orbit

    colours = np.array([[200, 30, 30], [30, 200, 60], [40, 60, 220]], np.uint8)
    m = load_mesh_file(G.texture_coordinate_test(tmp_path / "u.gltf", [np.tile(c, (2, 2, 1)) for c in colours]))
    want = np.r_[srgb8_to_linear(colours), [[0.85, 0.425, 0.2]]]
    expected = TriMesh(m.vertices, m.faces, m.normals, colors=want[np.clip(m.vertices[:, 0] // 2, 0, 3).astype(int)])
    light, material = Light(), Material()
    centre, radius = m.bounding_sphere()
    cam = orbit(SimpleNamespace(count=1, elevation_deg=10, azimuth_deg=-90, distance=2.6, fov_deg=40),
                [0, 1, 0], centre, radius, 64, 32)[0]
    stored = parts.stored(parts.MESH, m)
    stored.texture = m.texture
    truth = images.encode(reference.MeshReference(expected, light, material).render(cam), BG)
    drawn, traced = drawn_and_traced(ctx, m, stored, cam, light, material, truth)
    assert drawn["iou"] > 0.99 and traced["iou"] > 0.99
    assert traced["mean"] < 0.05 and drawn["mean"] < 0.2, (traced["mean"], drawn["mean"])


# ------------------------------------------------------------------------------- 2. factors applied once

def test_factor_only_primitives_read_their_factor_once(tmp_path):
    m = load_mesh_file(G.factor_only_engine(tmp_path / "engine.gltf"))
    got = albedo_at(m, [[0.5, 0.25, 0], [0.5, 0.25, 1]])
    assert np.allclose(got, [[0.85] * 3, [0.425] * 3], rtol=0, atol=1e-9), got


# ------------------------------------------------------------------------- 3. the file's normals, and LODs

@pytest.mark.parametrize("sides", [4, 12])
def test_file_normals_are_kept(tmp_path, sides):
    m = load_mesh_file(G.prism(tmp_path / "p.gltf", sides=sides))
    tri = m.vertices[m.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.allclose(m.normals[m.faces], n[:, None], rtol=0, atol=1e-6)


def test_smooth_file_normals_are_kept(tmp_path):
    m = load_mesh_file(G.prism(tmp_path / "p.gltf", sides=12, hard=False))
    side = np.abs(m.normals[:, 2]) < 0.5
    radial = np.c_[m.vertices[side, :2], np.zeros(side.sum())]
    assert np.allclose(m.normals[side], radial / np.linalg.norm(radial, axis=1, keepdims=True), atol=1e-6)


def angles_deg(a, b) -> np.ndarray:
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1, 1)))


@pytest.mark.parametrize("hard", [True, False])
def test_coarse_levels_shade_as_the_file_normals(tmp_path, hard):
    """A 12-sided prism (30 degrees between sides: inside the 60 degree crease rule, which rounds them): hard-edged,
    every coarse corner's normal is one of the file's face normals, its face's where the face lies in a side;
    smooth, every side corner's normal is radial."""
    m = load_mesh_file(G.prism(tmp_path / "p.gltf", sides=12, hard=hard))
    c = coarse.simplify(m, 0.3)
    assert len(c.faces) < 0.5 * len(m.faces)
    tri = c.vertices[c.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    if hard:   # every corner shades as one side of the file; a face in a side's plane as that side
        sides = np.unique(np.round(m.normals, 6), axis=0)
        assert angles_deg(c.normals[:, None], sides[None]).min(1).max() < 1.0
        flat = angles_deg(n[:, None], sides[None]).min(1) < 1.0
        assert flat.mean() > 0.8 and angles_deg(c.normals[c.faces[flat]], n[flat, None]).max() < 1.0
    else:
        side = np.abs(c.normals[:, 2]) < 0.5
        radial = np.c_[c.vertices[side, :2], np.zeros(side.sum())]
        radial /= np.linalg.norm(radial, axis=1, keepdims=True)
        assert angles_deg(c.normals[side], radial).max() < 1.0


def test_coarse_without_file_normals_keeps_the_crease_rule():
    from vdmbake.assets import primitives

    m = primitives.torus(1.0, 0.35, 48, 24)
    assert not m.file_normals
    c = coarse.simplify(m, 0.2)
    v, f, n, _ = coarse.crease_normals(*coarse.surface(m, 0.2)[:2], coarse.CREASE_DEG)
    assert np.array_equal(c.normals, n) and np.array_equal(c.faces, f)


# ------------------------------------------------------------------- 4. sparse accessors and morph targets

def test_sparse_positions_are_applied(tmp_path):
    m = load_mesh_file(G.simple_sparse_accessor(tmp_path / "s.gltf"))
    for p in ([1, 2, 0], [3, 3, 0], [5, 4, 0]):
        assert np.isclose(m.vertices, p).all(1).any(), p
    assert not np.isclose(m.vertices, [1, 1, 0]).all(1).any()
    assert np.isclose(m.vertices, [2, 1, 0]).all(1).any()


def test_sparse_over_zeros_is_applied(tmp_path):
    m = load_mesh_file(G.simple_sparse_accessor(tmp_path / "z.gltf", zeros=True))
    assert {tuple(p) for p in np.round(m.vertices, 6)} == {(0, 0, 0), (1, 2, 0), (3, 3, 0), (5, 4, 0)}


def test_sparse_colour_is_applied(tmp_path):
    m = load_mesh_file(G.sparse_colour(tmp_path / "c.gltf"))
    assert np.allclose(albedo_at(m, [[1, 0, 0], [0, 1, 0], [0, 0, 0]]), [[0.2, 0.4, 0.8], [0.2, 0.4, 0.8], [0, 0, 0]])


@pytest.mark.parametrize("weights, node_weights, want", [((0.5, 0.25), None, (0.5, 0.25)),
                                                         ((0.5, 0.25), (1.0, 0.0), (1.0, 0.0))])
def test_morph_targets_at_the_default_weights(tmp_path, weights, node_weights, want):
    m = load_mesh_file(G.simple_morph(tmp_path / "m.gltf", weights, node_weights))
    w0, w1 = want
    assert np.isclose(m.vertices, [-w1, 0, 0]).all(1).any(), m.vertices
    lifted = np.isclose(m.vertices, [1, 1, w0]).all(1)
    assert lifted.any(), m.vertices
    n = np.array([w0, 0, 1 - w0])
    assert np.allclose(m.normals[lifted], n / np.linalg.norm(n), atol=1e-6)


# --------------------------------------------------------------- 5. strips, fans, points and lines by name

def test_fan_and_strip_are_read_with_their_winding(tmp_path):
    m = load_mesh_file(G.primitive_modes(tmp_path / "modes.gltf", modes=(6, 5)))
    assert len(m.faces) == 6 + 4
    tri = m.vertices[m.faces]
    assert (np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2] > 0).all()


def test_a_lone_fan_loads(tmp_path):
    m = load_mesh_file(G.primitive_modes(tmp_path / "fan.gltf", modes=(6,)))
    assert len(m.faces) == 6


@pytest.mark.parametrize("mode, name", [(0, "points"), (1, "lines"), (2, "line loop"), (3, "line strip")])
def test_points_and_lines_alone_are_refused_by_name(tmp_path, mode, name):
    with pytest.raises(InputError, match=rf"mesh 0 primitive 0 draws {name} \(mode {mode}\); only triangles"):
        load_mesh_file(G.primitive_modes(tmp_path / "p.gltf", modes=(mode,)))


def test_points_and_lines_beside_triangles_are_left_out_by_name(tmp_path):
    said = []
    m = load_mesh_file(G.primitive_modes(tmp_path / "modes.gltf", modes=(6, 0, 1)), warn=said.append)
    assert len(m.faces) == 6
    assert len(said) == 1 and "mesh 0 primitive 1 draws points (mode 0)" in said[0] \
        and "mesh 0 primitive 2 draws lines (mode 1)" in said[0], said


def test_box_vertex_colors(tmp_path):
    m = load_mesh_file(G.box_vertex_colors(tmp_path / "b.gltf"))
    want = np.round((m.vertices + 1) / 2 * 65535) / 65535
    assert np.allclose(m.colors, want, rtol=0, atol=2 / 65535)   # float32 positions


def test_gutters_follow_each_pictures_wrap_mode(tmp_path):
    """Two pictures in one file, the first CLAMP_TO_EDGE: at s = 0 it reads its own edge texel, the second
    (REPEAT) blends its two edge texels."""
    g = G.Gltf()
    for k, sampler in enumerate(({"wrapS": 33071, "wrapT": 33071}, None)):
        g.node(mesh=g.mesh(g.primitive(material=g.material(picture=G.PICTURES[k], sampler=sampler), uv=G.UV)),
               translation=[2 * k, 0, 0])
    m = load_mesh_file(g.write(tmp_path / "clamp.gltf"))
    lin = [srgb8_to_linear(p) for p in G.PICTURES[:2]]
    got = albedo_at(m, [at_uv(0, 0.0, 0.25), at_uv(1, 0.0, 0.25)])
    assert np.allclose(got, [lin[0][0, 0], 0.5 * (lin[1][0, 0] + lin[1][0, 1])], rtol=0, atol=1e-6), got


def test_left_out_primitives_are_printed_by_default(tmp_path, capsys):
    load_mesh_file(G.primitive_modes(tmp_path / "modes.gltf", modes=(6, 3)))
    err = capsys.readouterr().err
    assert err.startswith("warning:") and "mesh 0 primitive 1 draws line strip (mode 3)" in err, err


@pytest.mark.parametrize("spoil, match", [
    (lambda t: t.update(extensionsRequired=["KHR_meshopt_compression"]), "requires the extension KHR_meshopt_"),
    (lambda t: t["nodes"][0].update(children=[0]), "node 0 is reached twice \\(its own ancestor"),
    (lambda t: t["meshes"][0]["primitives"][0].update(mode=7), "has mode 7; glTF 2.0 gives 0 to 6"),
    (lambda t: t["meshes"][0]["primitives"][0].update(targets=[{"COLOR_0": 0}]) or t["meshes"][0].update(weights=[1]),
     "morph target 0 moves COLOR_0 at weight 1"),
])
def test_what_is_not_read_is_refused_by_name(tmp_path, spoil, match):
    import json

    path = G.primitive_modes(tmp_path / "f.gltf", modes=(6,))
    tree = json.loads(path.read_text())
    spoil(tree)
    path.write_text(json.dumps(tree))
    with pytest.raises(InputError, match=match):
        load_mesh_file(path)


def test_the_bake_log_names_what_it_left_out(tmp_path):
    """vdmbake says in its own log (the object's lines) which primitives of the file it left out."""
    from click.testing import CliRunner

    from vdmbake.cli import main as bake_main

    G.primitive_modes(tmp_path / "modes.gltf", modes=(6, 3))
    (tmp_path / "s.toml").write_text('[render]\nresolution = [16, 16]\n[[objects]]\nname = "m"\nmesh = "modes.gltf"\n'
                                     'techniques = { mesh = {} }\n')
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s.toml"), "-o", str(tmp_path / "b.bundle"), "--verbose"])
    assert r.exit_code == 0, r.output
    line = next(x for x in r.output.splitlines() if "warning:" in x)
    assert line.startswith("m: warning: ") and "mesh 0 primitive 1 draws line strip (mode 3)" in line, r.output
