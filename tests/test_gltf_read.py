"""glTF colours read to the spec (issue 22, item 4): COLOR_0 is linear (glTF 2.0 §3.7.2.1), baseColorFactor,
the base-colour texture and COLOR_0 multiply in linear floats (§3.9.2), a factor alone is the asset's colour, a
texture read otherwise than the renderer reads it is refused, and the nodes' transforms are applied (§3.5.2). The
files are written here as plain JSON, their buffer a base64 data: URI, a .bin file or a GLB's binary chunk."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vdmbake.assets.meshes import load_mesh_file

from vdmbake.common.mesh import TriMesh
from vdmbake.bundle import parts
from vdmbake.common import texture
from vdmbake.common.colour import srgb8_to_linear
from vdmbake.errors import InputError
from vdmbake.scene import Light, Material
from vdmrender.common import images
from vdmrender.tracing import reference
from vdmrender.common.camera import orbit

from gltf_files import BG, QUAD, UV, Gltf, drawn_and_traced

def quad_file(path, colour=None, uv=None, **materials) -> TriMesh:
    """A one-quad glTF loaded: COLOR_0 `colour`, and a material made by Gltf.material(**materials) if given."""
    g = Gltf()
    material = g.material(**materials) if materials else None
    g.node(mesh=g.mesh(g.primitive(colour, material, UV if uv is None and "picture" in materials else uv)))
    return load_mesh_file(g.write(path))


def albedo(m: TriMesh) -> np.ndarray:
    """The asset's linear albedo at the quad's centre, as the reference reads it (None: the scene's material)."""
    return texture.surface_albedo(m, np.array([0]), np.array([[0.25, 0.25, 0.5]]), None)[0] if texture.has_albedo(m) \
        else None


# --------------------------------------------------------------------------------------- 1. COLOR_0 is linear

@pytest.mark.parametrize("colour, want", [
    (np.full((4, 3), 0.5, np.float32), 0.5),                  # before this fix: 0.2159 (128 decoded as sRGB)
    (np.full((4, 4), 128, np.uint8), 128 / 255),              # before: 0.2159
    (np.full((4, 3), 32768, np.uint16), 32768 / 65535),       # before: 0.0 (trimesh took 32768 for a byte)
])
def test_colour_0_is_linear(tmp_path, colour, want):
    m = quad_file(tmp_path / "q.gltf", colour)
    assert m.colors is not None and np.allclose(m.colors, want, rtol=0, atol=1e-12), m.colors


@pytest.mark.parametrize("name, buffer", [("q.glb", "glb"), ("q.gltf", "q.bin")])
def test_colour_0_from_a_glb_or_a_buffer_file(tmp_path, name, buffer):
    """Strided (VEC4 of bytes in a float-aligned view) and offset into the GLB's binary chunk or a .bin file."""
    g = Gltf()
    p = g.primitive()
    p["attributes"]["COLOR_0"] = g.accessor(np.repeat([[51, 102, 204, 255, 0, 0, 0, 0]], 4, 0).astype(np.uint8), True)
    g.tree["accessors"][-1].update(type="VEC4")
    g.tree["bufferViews"][-1]["byteStride"] = 8
    g.node(mesh=g.mesh(p))
    m = load_mesh_file(g.write(tmp_path / name, buffer))
    assert np.allclose(m.colors, [0.2, 0.4, 0.8], rtol=0, atol=1e-12), m.colors


@pytest.mark.parametrize("colour, match", [
    (np.full((4, 3), 1.5, np.float32), "outside"),
    (np.full((4, 3), 100, np.int8), "normalized unsigned byte"),
])
def test_colour_0_out_of_spec_is_refused(tmp_path, colour, match):
    with pytest.raises(InputError, match=match):
        quad_file(tmp_path / "q.gltf", colour)


def test_colour_0_multiplies_the_texture(tmp_path):
    """COLOR_0 = 0.5 on a white texture: 0.5 (before: COLOR_0 dropped, 1.0)."""
    m = quad_file(tmp_path / "q.gltf", np.full((4, 3), 0.5, np.float32), picture=np.full((2, 2, 3), 255))
    assert m.texture is not None and (m.texture == 255).all()
    assert np.allclose(albedo(m), 0.5, rtol=0, atol=1e-12), albedo(m)


# ------------------------------------------------------- 2. factor x texture x COLOR_0 in linear floats, once

def test_factor_multiplies_in_linear_floats(tmp_path):
    """A white texture with factor [0.9, 0.7, 1]: exactly the factor (before: [0.90466, 0.70110, 1.0], the factor
    rounded to 1/255 and the product re-encoded to 8-bit sRGB); the texture stays the file's picture."""
    m = quad_file(tmp_path / "q.gltf", factor=[0.9, 0.7, 1.0, 0.5], picture=np.full((2, 2, 3), 255))
    assert (m.texture == 255).all()
    assert np.allclose(albedo(m), [0.9, 0.7, 1.0], rtol=0, atol=1e-12), albedo(m)
    picture = np.full((2, 2, 3), 200)
    m = quad_file(tmp_path / "r.gltf", np.full((4, 3), 0.5, np.float32), factor=[0.3, 0.7, 0.9, 1], picture=picture)
    want = 0.5 * np.array([0.3, 0.7, 0.9]) * srgb8_to_linear(200)
    assert (m.texture == 200).all() and np.allclose(albedo(m), want, rtol=0, atol=1e-12), (albedo(m), want)


# ----------------------------------------------------------------------- 3. a factor alone is the asset's colour

def test_factor_alone_is_the_asset_colour(tmp_path):
    """Before: no colour (the scene's material applied); a file without any colour keeps that."""
    m = quad_file(tmp_path / "q.gltf", factor=[0.9, 0.7, 0.2, 1])
    assert m.texture is None and np.allclose(m.colors, [0.9, 0.7, 0.2], rtol=0, atol=1e-12)
    plain = quad_file(tmp_path / "p.gltf", factor=None)   # a material without a factor
    assert plain.colors is None and plain.texture is None
    ignored = load_mesh_file(tmp_path / "q.gltf", textures=False)   # textures = "ignore": the material is not read
    assert ignored.colors is None


# ------------------------------------- 4. wrap modes: refused, not ignored (transforms: tests/test_gltf_published.py)

@pytest.mark.parametrize("info, sampler, uv, match", [
    ({"extensions": {"KHR_texture_transform": {"offset": "x"}}}, None, None, "KHR_texture_transform offset"),
    ({"texCoord": 1}, None, None, "TEXCOORD_1, which the primitive does not have"),
    (None, {"wrapS": 9728}, None, "wrap modes"),              # NEAREST is a filter, not a wrap mode
])
def test_texture_read_otherwise_is_refused(tmp_path, info, sampler, uv, match):
    picture = np.arange(16 * 3).reshape(4, 4, 3) * 5
    with pytest.raises(InputError, match=match):
        quad_file(tmp_path / "q.gltf", picture=picture, info=info, sampler=sampler, uv=uv)


@pytest.mark.parametrize("info, sampler, uv", [
    ({"extensions": {"KHR_texture_transform": {"scale": [1, 1], "rotation": 0}}}, None, None),   # the identity
    (None, {"wrapS": 10497, "wrapT": 10497}, None),                                             # REPEAT, spelt out
    (None, {"wrapS": 33071, "wrapT": 33648}, UV * 0.75 + 0.125),   # UVs half a texel in: the mode reads nothing
])
def test_texture_read_as_the_renderer_reads_it_loads(tmp_path, info, sampler, uv):
    m = quad_file(tmp_path / "q.gltf", picture=np.full((4, 4, 3), 90), info=info, sampler=sampler, uv=uv)
    assert m.texture is not None


# ------------------------------------------------------------------------------- 5. the nodes' transforms

def test_node_transforms_and_colours_follow_each_instance(tmp_path):
    """A mesh drawn by two nodes (translation, rotation, scale; identity) and another by a child node (matrix,
    under the first): every vertex where its node chain puts it, with its own primitive's colour. The points
    primitive, left out (with a warning), checks that colours stay with their primitives."""
    g = Gltf()
    dim, bright = g.material([0.25, 0.25, 0.25, 1]), g.material([0.75, 0.5, 0.25, 1])
    a = g.mesh(g.primitive(material=bright, mode=0), g.primitive(material=dim))
    b = g.mesh(g.primitive(np.full((4, 3), 0.5, np.float32), material=bright))
    half = np.sqrt(0.5)
    parent = g.node(mesh=a, translation=[5, 0, 0], rotation=[0, 0, half, half], scale=[2, 2, 2])   # 90 deg about z
    g.tree["nodes"][parent]["children"] = [g.node(root=False, mesh=b, matrix=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0,
                                                                             0, 0, 3, 1])]
    g.node(mesh=a)
    m = load_mesh_file(g.write(tmp_path / "nodes.gltf"))
    trs = np.array([[0, -2, 0, 5], [2, 0, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1.0]])
    place = lambda matrix: (np.c_[QUAD, np.ones(4)] @ matrix.T)[:, :3]   # noqa: E731
    want = np.r_[np.c_[place(trs), np.full((4, 3), 0.25)], np.c_[place(np.eye(4)), np.full((4, 3), 0.25)],
                 np.c_[place(trs @ [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]),   # child after parent
                       np.tile(0.5 * np.array([0.75, 0.5, 0.25]), (4, 1))]]
    got = np.round(np.c_[m.vertices, m.colors], 9)   # sorted below: a rotation's 1e-16 must not reorder rows
    assert len(got) == len(want)
    assert np.allclose(got[np.lexsort(got.T)], want[np.lexsort(want.T)], rtol=0, atol=1e-6)


# -------------------------------------------------- render: the `mesh` technique and the reference agree with glTF

@pytest.mark.parametrize("materials, colour, want", [
    ({}, np.full((4, 3), 0.5, np.float32), (0.5, 0.5, 0.5)),                   # before this fix: 21.1 mean dLuv
    ({"picture": np.full((2, 2, 3), 255)}, np.full((4, 3), 0.5, np.float32), (0.5, 0.5, 0.5)),   # before: 22.3
    ({"factor": [0.9, 0.7, 0.2, 1]}, None, (0.9, 0.7, 0.2)),                    # before: 55.9
    ({"factor": [0.9, 0.7, 1, 1], "picture": np.full((2, 2, 3), 255)}, None, (0.9, 0.7, 1.0)),   # before: 0.54
])
def test_render_shows_the_glTF_albedo(tmp_path, ctx, materials, colour, want):
    """The loaded quad stored as the bundle stores it, rasterised by `mesh` and traced by the reference, against
    the reference of a plain quad whose scene material has the albedo glTF gives: both near-exact."""
    m = quad_file(tmp_path / "q.gltf", colour, **materials)
    light, material = Light(), Material()
    centre, radius = m.bounding_sphere()
    cam = orbit(SimpleNamespace(count=1, elevation_deg=20, azimuth_deg=-60, distance=2.6, fov_deg=40),
                [0, 1, 0], centre, radius, 32, 32)[0]
    stored = parts.stored(parts.MESH, m)
    stored.texture = m.texture
    expected = images.encode(reference.MeshReference(TriMesh(m.vertices, m.faces, m.normals), light,
                                                     Material(albedo=want)).render(cam), BG)
    drawn, traced = drawn_and_traced(ctx, m, stored, cam, light, material, expected)
    assert drawn["iou"] > 0.99 and traced["iou"] > 0.99
    # measured: 0.0 for both (at 32 px, on llvmpipe)
    assert traced["mean"] < 1e-6 and drawn["mean"] < 0.1, (traced["mean"], drawn["mean"])
