"""Issue 43: published glTF files that were refused now read. Each test builds its tiny file here (no download) and
fails on main at 20e813d: a missing picture the renderer never reads (BoomBox's occlusion), KHR_texture_transform
and TEXCOORD_1 on the base colour (TextureTransformTest), Draco-compressed geometry (KHR_draco_mesh_compression)."""
from __future__ import annotations

import json

import numpy as np
import pytest

import gltf_files as G
from gltf_files import BG, CLAMP, MIRROR, PICTURE, REPEAT, UV, Gltf, albedo_at, drawn_and_traced
from helpers import gltf_asset
from vdmbake.assets.meshes import load_mesh_file
from vdmbake.common import texture
from vdmbake.errors import InputError


def _with(path, change):
    tree = json.loads(path.read_text())
    change(tree)
    path.write_text(json.dumps(tree))
    return path


# ------------------------------------------------------------------ 4. only what is drawn is required

def _unread_picture(tree, uri="missing_occlusion.png"):
    """BoomBox-like: the material's occlusion, metallic-roughness and normal pictures name a file that is not there."""
    tree["images"].append({"uri": uri})
    tree["textures"].append({"source": 1})
    m = tree["materials"][0]
    m["occlusionTexture"] = m["normalTexture"] = {"index": 1}
    m["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {"index": 1}


def test_a_missing_picture_that_is_not_drawn_is_a_warning(tmp_path):
    _with(tmp_path / gltf_asset(tmp_path), _unread_picture)
    heard = []
    m = load_mesh_file(tmp_path / "quad.gltf", warn=heard.append)
    assert m.texture is not None
    assert len(heard) == 1 and "image 1 'missing_occlusion.png'" in heard[0] and "not found" in heard[0], heard


def test_a_present_picture_that_is_not_drawn_is_not_read(tmp_path):
    _with(tmp_path / gltf_asset(tmp_path), lambda t: _unread_picture(t, "occlusion.png"))
    (tmp_path / "occlusion.png").write_bytes(b"not a picture")   # never opened, so never refused
    heard = []
    assert load_mesh_file(tmp_path / "quad.gltf", warn=heard.append).texture is not None
    assert heard == []


def test_a_missing_base_colour_picture_is_still_refused(tmp_path):
    gltf_asset(tmp_path)
    (tmp_path / "tex.png").unlink()
    with pytest.raises(InputError, match="tex.png"):
        load_mesh_file(tmp_path / "quad.gltf")


# ---------------------------------------------------------- 3. KHR_texture_transform and TEXCOORD_1 on the base colour

def _texel(m, x, y, row, col):
    from vdmbake.common.colour import srgb8_to_linear

    got, want = albedo_at(m, [[x, y, 0]])[0], srgb8_to_linear(PICTURE[row, col])
    assert np.allclose(got, want, rtol=0, atol=1e-6), (x, y, row, col, got, want)


def _quad(path, info=None, uv1=None, sampler=None, pictures=1, uv=UV):
    """The quad (glTF UV (x, 1 - y)) reading PICTURE with textureInfo `info`, TEXCOORD_1 `uv1`; `pictures` = 2 adds
    a second quad at x = 2 with a plain picture, so the file's pictures share an atlas."""
    g = Gltf()
    p = g.primitive(material=g.material(picture=PICTURE, info=info, sampler=sampler), uv=uv)
    if uv1 is not None:
        p["attributes"]["TEXCOORD_1"] = g.accessor(np.asarray(uv1, np.float32))
    g.node(mesh=g.mesh(p))
    if pictures == 2:
        g.node(mesh=g.mesh(g.primitive(material=g.material(picture=np.full((2, 2, 3), 77)), uv=UV)),
               translation=[2.0, 0, 0])
    return load_mesh_file(g.write(path))


SPEC_EXAMPLE = {"extensions": {"KHR_texture_transform": {"offset": [0, 1], "rotation": np.pi / 2,
                                                         "scale": [0.5, 0.5]}}}


@pytest.mark.parametrize("pictures", [1, 2])
def test_texture_transform_is_applied(tmp_path, pictures):
    """The extension's own example: 'only the lower left quadrant of the source image, rotated clockwise 90 deg'
    (scale 0.5, rotation pi/2, offset (0, 1)): glTF UV (s, t) reads (t / 2, 1 - s / 2), so the quad's point (x, y)
    shows texel row 3 - floor(2x), column floor(2 - 2y) (rows 2-3, columns 0-1). Alone, and in an atlas."""
    m = _quad(tmp_path / "t.gltf", SPEC_EXAMPLE, pictures=pictures)
    for x in (0.25, 0.75):
        for y in (0.25, 0.75):
            _texel(m, x, y, row=int(4 - 0.5 - 2 * x), col=int(2 - 2 * y))


@pytest.mark.parametrize("info", [{"texCoord": 1},
                                  {"extensions": {"KHR_texture_transform": {"texCoord": 1}}}])
def test_base_colour_on_texcoord_1(tmp_path, info):
    """TEXCOORD_1 = half of TEXCOORD_0: the quad shows the picture's top-left quadrant (the extension's texCoord
    overrides the textureInfo's)."""
    m = _quad(tmp_path / "t.gltf", info, uv1=UV * 0.5)
    for x in (0.25, 0.75):
        for y in (0.25, 0.75):
            _texel(m, x, y, row=int(2 * (1 - y)), col=int(2 * x))


@pytest.mark.parametrize("info, uv1, match", [
    ({"texCoord": 2}, UV, "TEXCOORD_2, which the primitive does not have"),
    ({"extensions": {"KHR_texture_transform": {"rotation": "x"}}}, None, "KHR_texture_transform"),
    ({"extensions": {"KHR_texture_transform": {"scale": [1]}}}, None, "KHR_texture_transform"),
])
def test_texture_coordinates_out_of_spec_are_refused(tmp_path, info, uv1, match):
    with pytest.raises(InputError, match=match):
        _quad(tmp_path / "t.gltf", info, uv1=uv1)


def test_a_transform_leaving_an_atlas_tile_wraps(tmp_path):
    """Scale 2 in an atlas: glTF UV (2x, 2 - 2y) reads, as REPEAT does, texel (floor(8 - 8y) mod 4, floor(8x) mod
    4). Refused before this step (a wrapped UV read the neighbouring tile)."""
    m = _quad(tmp_path / "t.gltf", {"extensions": {"KHR_texture_transform": {"scale": [2, 2]}}}, pictures=2)
    for x, y in ((0.0625, 0.9375), (0.6875, 0.9375), (0.6875, 0.3125)):
        _texel(m, x, y, row=int(8 - 8 * y) % 4, col=int(8 * x) % 4)


# ------------------------------------------------------------------- 1. KHR_draco_mesh_compression decoded

@pytest.mark.parametrize("glb", [False, True])
def test_draco_reads_as_the_plain_file(tmp_path, glb):
    """The grid compressed by Draco loads as the same grid written plain: positions within the 16-bit quantisation
    (3 / 65535), the lossless normals, UVs, colours and the triangles exactly."""

    plain = load_mesh_file(G.draco_grid(tmp_path / "plain.gltf", draco=False))
    packed = load_mesh_file(G.draco_grid(tmp_path / ("d.glb" if glb else "d.gltf"), glb=glb))
    assert len(packed.faces) == len(plain.faces) == 18 and len(packed.vertices) == len(plain.vertices) == 16
    assert np.abs(packed.vertices - plain.vertices).max() <= 3 / 65535 + 1e-6
    assert np.array_equal(packed.faces, plain.faces)
    for name in ("uvs", "colors", "normals"):
        assert np.allclose(getattr(packed, name), getattr(plain, name), rtol=0, atol=1e-6), name
    assert np.allclose(plain.colors[5], np.arange(15, 18) * 5 / 255)   # COLOR_0 normalized, as written


@pytest.mark.parametrize("spoil, match", [
    (lambda tree, ext: tree["accessors"][0].update(count=15), r"POSITION: decodes to 16 x 3 values .* declares 15"),
    (lambda tree, ext: ext["attributes"].update(NORMAL=9), r"NORMAL: KHR_draco_mesh_compression names attribute 9"),
    (lambda tree, ext: tree["accessors"][-1].update(count=6), "decodes to 54 indices where its indices accessor "
                                                              "declares 6"),
    (lambda tree, ext: tree["bufferViews"][ext["bufferView"]].update(byteLength=20), "cannot be decoded"),
    (lambda tree, ext: tree["accessors"][3].update(componentType=5126, normalized=False),   # COLOR_0 bytes as floats:
     r"COLOR_0 accessor \d+ has values outside \[0, 1\]"),                                 # exact, then out of range
    (lambda tree, ext: tree["accessors"][2].update(componentType=5121), r"TEXCOORD_0: decodes to 16 x 2 values of "
                                                                       "float32"),
    (lambda tree, ext: tree["accessors"][0].update(count=10 ** 12), "Draco-compressed primitives of 1000000000000 "
                                                                     "vertices .* GiB of memory"),
])
def test_decoded_data_meets_the_accessor_checks(tmp_path, spoil, match):
    """Decoded attributes are checked against what their accessors declare, as plain ones are; a damaged stream
    and a declared size over the memory budget (checked before decoding) are refused, naming the primitive."""

    with pytest.raises(InputError, match=match):
        load_mesh_file(G.draco_grid(tmp_path / "d.gltf", spoil=spoil))


def test_fuzz_compressed(tmp_path_factory):
    """tests/fuzz_untrusted.py's target for compressed files, 200 derandomised examples here."""
    from hypothesis import given

    from fuzz_inputs import examples
    from fuzz_untrusted import check_compressed, compressed_case

    @given(case=compressed_case())
    @examples(200)
    def run(case):
        check_compressed(tmp_path_factory.mktemp("packed"), case)

    run()


# --------------------------------------------------------------------- 1. EXT_meshopt_compression decoded

def test_meshopt_reads_as_the_plain_file(tmp_path):
    """The grid with every bufferView meshopt-compressed (lossless, as gltfpack writes it without quantisation)
    loads exactly as the grid written plain (each triangle with its winding, though the index codec may start it at
    another corner); the fallback buffer, which holds no data, is never read."""

    def started(faces):   # each triangle rotated to start at its smallest index: the same winding, one spelling
        return np.array([np.roll(f, -int(np.argmin(f))) for f in faces])

    plain = load_mesh_file(G.draco_grid(tmp_path / "plain.gltf", draco=False))
    packed = load_mesh_file(G.meshopt_grid(tmp_path / "m.gltf"))
    assert np.array_equal(started(packed.faces), started(plain.faces))
    for name in ("vertices", "uvs", "colors", "normals"):
        assert np.array_equal(getattr(packed, name), getattr(plain, name)), name


@pytest.mark.parametrize("spoil, match", [
    (lambda tree, exts: exts[0].update(count=15), r"bufferView 0 \(EXT_meshopt_compression\): count 15, byteStride 12"
                                                  r".* for a view of 192 bytes"),
    (lambda tree, exts: exts[0].update(mode="POINTS"), r"mode 'POINTS'"),
    (lambda tree, exts: exts[4].update(byteStride=4, count=27) or tree["bufferViews"][4].update(byteLength=108),
     r"bufferView 4 \(EXT_meshopt_compression\): its \d+ compressed bytes cannot be decoded"),
    (lambda tree, exts: exts[1].update(byteLength=10 ** 6), r"bufferView 1 .* are not within a buffer of the file"),
    (lambda tree, exts: exts[0].update(count=2 ** 40) or tree["bufferViews"][0].update(byteLength=12 * 2 ** 40),
     "meshopt-compressed bufferViews, decoded .* GiB of memory"),
])
def test_meshopt_views_are_checked(tmp_path, spoil, match):
    """Each view's declarations are checked before decoding, its decoded size held to the memory budget, and a
    stream meshoptimizer cannot decode refused, naming the view."""

    with pytest.raises(InputError, match=match):
        load_mesh_file(G.meshopt_grid(tmp_path / "m.gltf", spoil=spoil))


# --------------------------------------------------------------------- 2. every wrap mode as the file says

@pytest.mark.parametrize("pictures", [1, 2])
@pytest.mark.parametrize("wrap_s, wrap_t", [(CLAMP, MIRROR), (MIRROR, CLAMP), (MIRROR, REPEAT), (CLAMP, CLAMP)])
def test_every_wrap_mode_reads_as_the_file_says(tmp_path, pictures, wrap_s, wrap_t):
    """UVs over [-0.5, 1.5] (the quad's glTF UV (2x - 0.5, 1.5 - 2y)), the picture alone or beside another (then in
    an atlas): at each point the texel the GL spec's wrap gives (§8.14.2: CLAMP_TO_EDGE the edge texel, MIRRORED_REPEAT
    the mirror image, REPEAT the opposite side), bilinear between texel centres. Refused before issue 43 (the UVs
    reach the edge of a CLAMP_TO_EDGE or MIRRORED_REPEAT picture, or leave [0, 1] in an atlas)."""
    from vdmbake.common.colour import srgb8_to_linear

    m = _quad(tmp_path / "w.gltf", sampler={"wrapS": wrap_s, "wrapT": wrap_t}, pictures=pictures, uv=UV * 2 - 0.5)
    lin = srgb8_to_linear(PICTURE)

    def texel(i, mode):   # the file's texel index i along an axis of 4 texels, wrapped by hand
        return {CLAMP: min(max(i, 0), 3), REPEAT: i % 4, MIRROR: i % 8 if i % 8 < 4 else 7 - i % 8}[mode]

    for s in (-0.375, -0.125, 0.0, 0.625, 1.0, 1.125, 1.375):
        for t in (-0.375, 0.125, 1.0, 1.375):
            x, y = (s + 0.5) / 2, (1.5 - t) / 2
            fs, ft = s * 4 - 0.5, t * 4 - 0.5          # bilinear in the file's texel space (rows from the top)
            i0, j0 = int(np.floor(fs)), int(np.floor(ft))
            a, b = fs - i0, ft - j0
            want = sum(w * lin[texel(j, wrap_t), texel(i, wrap_s)] for i, j, w in (
                (i0, j0, (1 - a) * (1 - b)), (i0 + 1, j0, a * (1 - b)), (i0, j0 + 1, (1 - a) * b),
                (i0 + 1, j0 + 1, a * b)))
            got = albedo_at(m, [[x, y, 0]])[0]
            assert np.allclose(got, want, rtol=0, atol=1e-6), (s, t, got, want)


def test_a_span_too_wide_to_lay_out_is_refused_by_name(tmp_path):
    """UVs over 10,000 pictures of a CLAMP_TO_EDGE sampler: laid out, 40,002 texels a side, over GL's least
    GL_MAX_TEXTURE_SIZE: refused before a texel is copied, naming the primitive, its span and its modes."""
    with pytest.raises(InputError, match=r"mesh 0 primitive 0 \(material 0\): its base-colour UVs span u 0 to 1e\+04"
                                         r".* wrap modes 33071, 10497.* laid out as 40002 x 6 texels"):
        _quad(tmp_path / "w.gltf", sampler={"wrapS": CLAMP}, uv=UV * [10 ** 4, 1])


def test_render_of_wrap_modes_in_an_atlas_matches_the_reference(tmp_path, ctx):
    """The mirrored and clamped picture beside a second one (an atlas), UVs over [-0.5, 1.5]: the `mesh` technique's
    frame (llvmpipe, 64 x 64) against the reference of the same loaded mesh; its reading is checked point by point
    above, so this checks that the renderer reads the laid-out atlas as the reference does."""
    from types import SimpleNamespace

    from vdmbake.bundle import parts
    from vdmbake.scene import Light, Material
    from vdmrender.common import images
    from vdmrender.tracing import reference
    from vdmrender.common.camera import orbit

    m = _quad(tmp_path / "w.gltf", sampler={"wrapS": MIRROR, "wrapT": CLAMP}, pictures=2, uv=UV * 2 - 0.5)
    light, material = Light(), Material()
    centre, radius = m.bounding_sphere()
    cam = orbit(SimpleNamespace(count=1, elevation_deg=0, azimuth_deg=-90, distance=2.2, fov_deg=40),
                [0, 1, 0], centre, radius, 64, 64)[0]
    stored = parts.stored(parts.MESH, m)
    stored.texture = m.texture
    truth = images.encode(reference.MeshReference(m, light, material).render(cam), BG)
    drawn, traced = drawn_and_traced(ctx, m, stored, cam, light, material, truth)
    print(f"wrap modes in an atlas: frame against reference {drawn['mean']:.4f} mean dLuv, IoU {drawn['iou']:.4f}")
    assert drawn["iou"] > 0.99 and drawn["mean"] < 0.3, drawn


# ------------------------------------------------------ 5. mip levels of an atlas keep the unpictured parts' colour

def _box_level(lin: np.ndarray, level: int) -> np.ndarray:
    """Mip level `level` of linear texels by 2 x 2 boxes (glGenerateMipmap's filter on even sides)."""
    for _ in range(level):
        h, w = lin.shape[0] // 2 * 2, lin.shape[1] // 2 * 2
        lin = lin[:h, :w].reshape(h // 2, 2, w // 2, 2, 3).mean((1, 3))
    return lin


def test_unpictured_parts_stay_white_through_the_mip_levels(tmp_path):
    """Dark pictures beside a factor-only quad share an atlas: the quad's UV reads white at mip levels 0 to 5, where
    before issue 43 its one-texel tile averaged in its dark neighbours (sRGB 213 -> 100 at level 2, 10 at level 4)."""

    m = load_mesh_file(G.texture_coordinate_test(tmp_path / "a.gltf", [np.full((8, 8, 3), 20, np.uint8)] * 3))
    uv = m.uvs[np.flatnonzero(m.vertices[:, 0] >= 6 - 1e-9)]
    assert (uv == uv[0]).all()
    for level in range(6):
        lin = _box_level(texture.linear(m.texture), level)
        h, w = lin.shape[:2]
        x, y = uv[0, 0] * w - 0.5, uv[0, 1] * h - 0.5
        i, j = int(np.floor(x)), int(np.floor(y))
        a, b = x - i, y - j   # the bilinear read at this level (the UV is inside the map: no wrap)
        got = ((1 - b) * ((1 - a) * lin[j, i] + a * lin[j, (i + 1) % w])
               + b * ((1 - a) * lin[(j + 1) % h, i] + a * lin[(j + 1) % h, (i + 1) % w]))
        assert np.allclose(got, 1.0), (level, got)


def test_meshopt_octahedral_normals_decode_to_the_files_normals(tmp_path):
    """gltfpack's default normals: normalized bytes through meshopt's OCTAHEDRAL filter (8 bits): decoded, mapped as
    §3.11 maps normalized bytes and renormalised, within 1.5 degrees of the normals written."""

    plain = load_mesh_file(G.draco_grid(tmp_path / "plain.gltf", draco=False))
    packed = load_mesh_file(G.meshopt_grid(tmp_path / "m.gltf", octahedral=True))
    cos = (packed.normals * plain.normals).sum(1)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1.5
    assert np.array_equal(packed.vertices, plain.vertices)
