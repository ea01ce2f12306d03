"""Assets are untrusted input (issue 42): the files a mesh file names resolve inside the scene's folder or the mesh
file's own (one rule for every format: references.confined), each read once; bounded work per file; glTF's required
extensions honoured or refused (§3.12) and GLB headers checked; GL limits checked before drawing; vdmexport's
lod.json typed; a lone far copy refused. Each finding's test failed at 62f9cd8 (exit 0, a traceback, or work without
a bound); the tests of what must keep working (a sibling folder of the scene's tree, a deep node chain) say so. The
assets are written here, a few hundred bytes each."""
from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from helpers import QUAD_V, assert_input_error, bake, gltf_asset, obj_asset, png, scene, write_scene
from scenes import FAR_COPIES
from vdmbake.assets import references
from vdmbake.assets.meshes import load_mesh_file
from vdmbake.errors import InputError


def _with(path: Path, edit) -> Path:
    """The glTF at `path` with its JSON tree changed by `edit` (in place)."""
    tree = json.loads(path.read_text())
    edit(tree)
    path.write_text(json.dumps(tree))
    return path


def _buffer_uri(uri: str):
    def edit(tree):
        tree["buffers"][0]["uri"] = uri
    return edit


# --- one rule for file references -------------------------------------------------------------------------------

def _outside(tmp_path: Path) -> Path:
    """tmp/X/secret.bin (the quad's own bytes, so a read would bake) beside the scene's folder tmp/scene."""
    (tmp_path / "X").mkdir()
    (tmp_path / "scene").mkdir()
    gltf_asset(tmp_path / "X")
    os.rename(tmp_path / "X" / "quad.bin", tmp_path / "X" / "secret.bin")
    gltf_asset(tmp_path / "scene")
    return tmp_path / "scene"


@pytest.mark.parametrize("uri", ["/etc/passwd", "../X/secret.bin", "%2e%2e%2fX%2fsecret.bin", "link.bin"])
def test_a_buffer_outside_the_scene_is_refused(tmp_path, uri):
    """Failed before: each was read and baked with exit 0 (/etc/passwd as vertex colours)."""
    d = _outside(tmp_path)
    (d / "link.bin").symlink_to(tmp_path / "X" / "secret.bin")
    _with(d / "quad.gltf", _buffer_uri(uri))
    decoded = r" \('\.\./X/secret\.bin' percent-decoded\)" if uri.startswith("%") else ""
    with pytest.raises(InputError, match=rf"quad.gltf: the buffer '{uri}'{decoded} resolves to .*, outside .*scene; a "
                                         "mesh file may name only files inside the scene's folder or its own"):
        load_mesh_file(d / "quad.gltf", root=d)


def test_the_bake_refuses_passwd_as_vertex_colours(tmp_path):
    """The finding as a hostile user made it: /etc/passwd read as a normalized COLOR_0 accessor."""
    d = _outside(tmp_path)

    def edit(tree):
        tree["buffers"].append({"uri": "/etc/passwd", "byteLength": 12})
        tree["bufferViews"].append({"buffer": 1, "byteLength": 12})
        tree["accessors"].append({"bufferView": 3, "componentType": 5121, "normalized": True, "count": 4,
                                  "type": "VEC3"})
        tree["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = 3
    _with(d / "quad.gltf", edit)
    out = d / "out.bundle"
    assert_input_error(bake(write_scene(d, scene("quad.gltf")), "-o", out),
                       ["the buffer '/etc/passwd' resolves to /etc/passwd, outside"], out)


@pytest.mark.parametrize("where", ["mtllib", "map_Kd"])
def test_an_obj_reference_outside_is_refused(tmp_path, where):
    """Failed before: `mtllib ../outside/o.mtl` and its map_Kd were read like the glTF's buffers."""
    (tmp_path / "outside").mkdir()
    (tmp_path / "scene").mkdir()
    d = tmp_path / "scene"
    obj_asset(d)
    png(tmp_path / "outside" / "t.png")
    if where == "mtllib":
        (tmp_path / "outside" / "o.mtl").write_text("newmtl mat\nKd 1 1 1\nmap_Kd t.png\n")
        (d / "quad.obj").write_text((d / "quad.obj").read_text().replace("mtllib m.mtl", "mtllib ../outside/o.mtl"))
    else:
        (d / "m.mtl").write_text("newmtl mat\nKd 1 1 1\nmap_Kd ../outside/t.png\n")
    shown = "the material library '../outside/o.mtl'" if where == "mtllib" else "the texture '../outside/t.png'"
    with pytest.raises(InputError, match=f"{shown} resolves to .*outside"):
        load_mesh_file(d / "quad.obj", root=d)


def _sibling(tmp_path: Path) -> Path:
    """scene/models/quad.gltf whose picture sits in scene/textures: a sibling folder of the scene's tree."""
    models, textures = tmp_path / "models", tmp_path / "textures"
    models.mkdir()
    textures.mkdir()
    gltf_asset(models)
    os.rename(models / "tex.png", textures / "tex.png")
    return _with(models / "quad.gltf", lambda tree: tree["images"][0].update(uri="../textures/tex.png"))


def test_textures_in_a_sibling_folder_of_the_scene_still_load(tmp_path):
    """What must keep working: ../textures beside a model in the scene's tree, the scene's folder the root."""
    m = load_mesh_file(_sibling(tmp_path), root=tmp_path)
    assert m.texture is not None and m.texture.shape == (4, 4, 3)


def test_the_bake_reads_textures_in_a_sibling_folder_of_the_scenes_tree(tmp_path):
    """The scene's folder is the root the bake passes: models/quad.gltf reads ../textures/tex.png; a scene's
    `assets` folder names another root, and outside it the same reference is refused."""
    _sibling(tmp_path)
    out = tmp_path / "out"
    r = bake(write_scene(tmp_path, scene("models/quad.gltf")), "-o", out)
    assert r.exit_code == 0, r.output
    assert "albedo_map" in json.loads((out / "manifest.json").read_text())["objects"]["thing"]
    r = bake(write_scene(tmp_path, scene("models/quad.gltf", 'assets = "models"\n'), "narrow.toml"), "-o",
             tmp_path / "narrow")
    assert_input_error(r, ["the texture '../textures/tex.png' resolves to", "outside"], tmp_path / "narrow")


def test_the_default_root_is_the_mesh_files_folder(tmp_path):
    with pytest.raises(InputError, match="the texture '../textures/tex.png' resolves to .*outside .*models;"):
        load_mesh_file(_sibling(tmp_path))


def test_one_file_in_several_spellings_is_read_once(tmp_path):
    """Failed before: a buffer named in five spellings was read five times (1.2 GB: MemoryError at 4.6 GB)."""
    gltf_asset(tmp_path)

    def edit(tree):
        tree["buffers"] = [{"uri": u, "byteLength": 92} for u in ("quad.bin", "./quad.bin", "%71uad.bin",
                                                                  "sub/../quad.bin", "quad%2ebin")]
        for k, view in enumerate(tree["bufferViews"]):
            view["buffer"] = k
    (tmp_path / "sub").mkdir()
    _with(tmp_path / "quad.gltf", edit)
    files = references.reached_files(tmp_path / "quad.gltf", "quad.gltf")
    buffers = [f.data for chain, f in files.items() if f.what == "buffer"]
    assert len(buffers) == 5 and all(b is buffers[0] for b in buffers)
    assert len(load_mesh_file(tmp_path / "quad.gltf").faces) == 2


def test_the_files_reached_are_bounded_together(tmp_path, monkeypatch):
    gltf_asset(tmp_path)
    size = sum(len((tmp_path / n).read_bytes()) for n in ("quad.gltf", "quad.bin"))
    monkeypatch.setattr(references, "MAX_FILE_BYTES", size + 10)
    with pytest.raises(InputError, match=r"the texture named by quad.gltf \(the files a mesh file reaches hold at "
                                         rf"most {size + 10} bytes together, {size} read before it\) has"):
        references.reached_files(tmp_path / "quad.gltf", "quad.gltf")


# --- bounded work per file ---------------------------------------------------------------------------------------

def test_an_accessor_without_bytes_is_bounded_by_the_file(tmp_path):
    """Failed before: a 1 KB glTF whose 2^26-count accessor has no bufferView reached 5.2 GB (here 2^20: 25 MB of
    zeros, refused before as 'no area' only after they were made)."""
    gltf_asset(tmp_path)

    def edit(tree):
        tree["accessors"][0] = {"componentType": 5126, "count": 1 << 20, "type": "VEC3"}
        del tree["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"]
    _with(tmp_path / "quad.gltf", edit)
    with pytest.raises(InputError, match=r"quad.gltf: accessor 0 has 1048576 elements and no bufferView, more than "
                                         r"the \d+ bytes of the file and its buffers"):
        load_mesh_file(tmp_path / "quad.gltf")


def _chain(tmp_path: Path, depth: int, twice: bool = False) -> Path:
    """The quad under a chain of `depth` nodes, each naming the next (twice: a node of two parents)."""
    gltf_asset(tmp_path)

    def edit(tree):
        tree["nodes"] = [{"children": [k + 1] * (2 if twice else 1), "translation": [0, 0, 1e-3]}
                         for k in range(depth)] + [{"mesh": 0}]
    return _with(tmp_path / "quad.gltf", edit)


def test_a_deep_node_chain_is_read_in_linear_work(tmp_path):
    """The tree walked once per node: before, the ancestors' tuple was copied per node (a 100,000-deep chain baked in
    34 s, 3.6 s now; no wall time is asserted, so this passed before too). Read here at 20,000."""
    m = load_mesh_file(_chain(tmp_path, 20_000), textures=False)
    assert np.allclose(m.vertices[:, 2].min(), 20.0)


def test_nodes_naming_the_next_twice_are_refused(tmp_path):
    """Failed before: 23 such nodes placed 2^22 copies of the mesh."""
    with pytest.raises(InputError, match=r"node 23 is reached twice \(its own ancestor, or a child of two parents\); "
                                         r"glTF 2.0 node hierarchies are disjoint trees \(§3.5.1\)"):
        load_mesh_file(_chain(tmp_path, 23, twice=True), textures=False)


def test_the_node_tree_is_held_to_the_memory_budget(tmp_path, monkeypatch):
    from vdmbake.bundle import budget

    monkeypatch.setattr(budget, "BUDGET", 3 * 4 * 1024 - 1)   # three copies of the quad's 4 vertices, less a byte
    with pytest.raises(InputError, match="quad.gltf: its node tree places 3 meshes of 12 vertices in all, which needs "
                                         "about .* GiB of memory"):
        load_mesh_file(_instanced(tmp_path), textures=False)


# --- extensions and GLB headers ----------------------------------------------------------------------------------

def _instanced(tmp_path: Path, required: bool = True, count: int = 3) -> Path:
    """The quad drawn by one node with EXT_mesh_gpu_instancing: three copies at x = 0, 10, 20 (the third turned
    half a turn about z)."""
    gltf_asset(tmp_path)
    extra = (np.array([[0, 0, 0], [10, 0, 0], [20, 0, 0]], "<f4").tobytes()
             + np.array([[0, 0, 0, 1], [0, 0, 0, 1], [0, 0, 1, 0]], "<f4").tobytes())
    with open(tmp_path / "quad.bin", "ab") as f:
        f.write(extra)

    def edit(tree):
        tree["buffers"][0]["byteLength"] += len(extra)
        tree["bufferViews"] += [{"buffer": 0, "byteOffset": 92, "byteLength": 36},
                                {"buffer": 0, "byteOffset": 128, "byteLength": 48}]
        tree["accessors"] += [{"bufferView": 3, "componentType": 5126, "count": count, "type": "VEC3"},
                              {"bufferView": 4, "componentType": 5126, "count": 3, "type": "VEC4"}]
        tree["nodes"][0]["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 3,
                                                                                      "ROTATION": 4}}}
        tree["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
        if required:
            tree["extensionsRequired"] = ["EXT_mesh_gpu_instancing"]
    return _with(tmp_path / "quad.gltf", edit)


def test_gpu_instancing_places_every_copy(tmp_path):
    """Failed before: EXT_mesh_gpu_instancing required, 1 copy baked instead of 3, exit 0."""
    m = load_mesh_file(_instanced(tmp_path), textures=False)
    quad = np.asarray(QUAD_V, float)
    turned = quad * [-1, -1, 1]
    want = np.r_[quad, quad + [10, 0, 0], turned + [20, 0, 0]]
    got = np.round(m.vertices, 6)
    assert len(got) == 12 and {tuple(v) for v in got} == {tuple(v) for v in np.round(want, 6)}


def test_copies_are_bounded_before_they_are_made(tmp_path, monkeypatch):
    """Nodes and EXT_mesh_gpu_instancing's copies together are held to MAX_COPIES, before a matrix is made."""
    from vdmbake.assets import gltf

    monkeypatch.setattr(gltf, "MAX_COPIES", 2)
    with pytest.raises(InputError, match="node 0 places 3 copies of its mesh where 2 more fit the 2 a file may "
                                         "place"):
        load_mesh_file(_instanced(tmp_path), textures=False)
    _with(tmp_path / "quad.gltf", lambda tree: tree.update(nodes=[{"mesh": 0}] * 3, scenes=[{"nodes": [0, 1, 2]}]))
    with pytest.raises(InputError, match="node 2 places 1 copies of its mesh where 0 more fit the 2 a file may place"):
        load_mesh_file(tmp_path / "quad.gltf", textures=False)


@pytest.mark.parametrize("required, match", [
    (["KHR_materials_pbrSpecularGlossiness"], r"it requires the extension KHR_materials_pbrSpecularGlossiness "
                                              r"\(extensionsRequired\), which this reader does not apply; glTF 2.0 "
                                              r"§3.12 says to refuse such a file"),
    (["KHR_meshopt_compression"], r"requires the extension KHR_meshopt_compression"),   # Draco, meshopt: read
    ("x", r"extensionsRequired is 'x'"),
])
def test_required_extensions_are_honoured_or_refused(tmp_path, required, match):
    """Failed before: an unknown required extension baked without a word; Draco listed only in extensionsRequired
    gave 'the mesh has no area'."""
    gltf_asset(tmp_path)
    _with(tmp_path / "quad.gltf", lambda tree: tree.update(extensionsRequired=required))
    with pytest.raises(InputError, match=match):
        load_mesh_file(tmp_path / "quad.gltf")


def test_compression_on_a_primitive_is_named(tmp_path):
    """Compressed geometry is decoded (issue 43); a primitive whose Draco data is not in the file is refused by name."""
    gltf_asset(tmp_path)
    _with(tmp_path / "quad.gltf", lambda tree: tree["meshes"][0]["primitives"][0].update(
        extensions={"KHR_draco_mesh_compression": {"bufferView": 99, "attributes": {}}}))
    with pytest.raises(InputError, match=r"mesh 0 primitive 0: bufferView 99 does not exist"):
        load_mesh_file(tmp_path / "quad.gltf")


def _glb(tmp_path: Path) -> bytes:
    """The quad as a GLB: its JSON chunk (padded with spaces) and its BIN chunk."""
    gltf_asset(tmp_path)
    tree = json.loads((tmp_path / "quad.gltf").read_text())
    data = (tmp_path / "quad.bin").read_bytes()
    del tree["buffers"][0]["uri"], tree["materials"], tree["textures"], tree["images"]
    del tree["meshes"][0]["primitives"][0]["material"]
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    data += b"\0" * (-len(data) % 4)
    body = (len(text).to_bytes(4, "little") + b"JSON" + text + len(data).to_bytes(4, "little") + b"BIN\0" + data)
    return b"glTF" + (2).to_bytes(4, "little") + (12 + len(body)).to_bytes(4, "little") + body


@pytest.mark.parametrize("spoil, match", [
    (lambda b: b"gltf" + b[4:], r"magic b'gltf'"),
    (lambda b: b[:4] + (1).to_bytes(4, "little") + b[8:], "version 1"),
    (lambda b: b + b"\0\0\0\0", r"a length of \d+ bytes where the file has \d+"),
    (lambda b: b[:-4], r"a length of \d+ bytes where the file has \d+"),
    (lambda b: b[:8] + (len(b) - 4).to_bytes(4, "little") + b[12:-4], r"GLB chunk 1 of \d+ bytes at byte \d+ reaches "
                                                                       "past the file's"),
    (lambda b: b[:16] + b"JSOX" + b[20:], r"GLB chunks \[b'JSOX', b'BIN\\x00'\]"),
])
def test_glb_headers_are_checked(tmp_path, spoil, match):
    """Failed before: magic, version and chunk lengths were not read (a GLB of version 1 baked)."""
    good = _glb(tmp_path)
    (tmp_path / "q.glb").write_bytes(good)
    assert len(load_mesh_file(tmp_path / "q.glb").faces) == 2
    (tmp_path / "q.glb").write_bytes(spoil(good))
    with pytest.raises(InputError, match=match):
        load_mesh_file(tmp_path / "q.glb")


# --- GL limits ----------------------------------------------------------------------------------------------------

def test_a_picture_wider_than_gl_reads_is_refused_at_bake(tmp_path):
    """Failed before: a 16385-wide albedo map baked, and rendered black with exit 0 (mean ΔLuv 115-121)."""
    from PIL import Image

    obj_asset(tmp_path)
    Image.new("RGB", (16385, 1), (200, 40, 40)).save(tmp_path / "tex.png")
    with pytest.raises(InputError, match=r"tex.png \(the texture named by .*m.mtl\) is a picture of 16385 x 1 pixels; "
                                         r"accepted: at least 1 and at most \d+ pixels, 16384 a side"):
        load_mesh_file(tmp_path / "quad.obj")


def test_an_atlas_is_built_within_the_side_gl_reads(tmp_path):
    """Failed before: two 16384-wide pictures made an atlas 16386 wide, which rendered black."""
    import gltf_files as G

    wide = [np.full((1, 16384, 3), c, np.uint8) for c in (50, 200)]
    with pytest.raises(InputError, match=r"laid out as 16386 x 3 texels, over the 16384 a side"):   # with its gutter
        load_mesh_file(G.texture_coordinate_test(tmp_path / "wide.gltf", wide))


def test_a_supersampled_target_over_the_device_limit_is_refused(ctx):
    """Failed before: --antialias ssaa4 --resolution 8192x16 gave a moderngl traceback (a target 32768 wide)."""
    from vdmrender.measuring import antialias

    most = ctx.info["GL_MAX_TEXTURE_SIZE"]
    with pytest.raises(InputError, match=rf"--antialias ssaa4 at {most // 2} x 16: the supersampled target of "
                                         rf"{2 * most} x 64 is over .*'s GL_MAX_RENDERBUFFER_SIZE of \d+; choose a "
                                         r"smaller K or resolution"):
        antialias.target(ctx, most // 2, 16, "ssaa4")
    antialias.target(ctx, most // 4, 4, "ssaa4").release()   # at the limit: made


def test_an_albedo_texture_over_the_device_limit_is_refused(ctx):
    """A bundle baked elsewhere (or edited) can hold a map wider than this device reads: refused, not drawn black."""
    from vdmrender.gpu import gl

    most = ctx.info["GL_MAX_TEXTURE_SIZE"]
    with pytest.raises(InputError, match=rf"the albedo map of {most + 1} x 1 is over .*'s GL_MAX_TEXTURE_SIZE of "
                                         rf"{most}; re-bake it with a smaller picture"):
        gl.albedo_texture(ctx, np.zeros((1, most + 1, 3), np.uint8))


def test_vdmrender_refuses_the_supersampled_target_cleanly(tmp_path, gl_context_ok):
    """The finding's command: vdmrender --antialias ssaa4 --resolution 8192x16 (a moderngl traceback before)."""
    from scenes import bake_and_render

    gltf_asset(tmp_path)
    result, out = bake_and_render(tmp_path, scene("quad.gltf"), "--antialias", "ssaa4", "--resolution", "8192x16")
    assert_input_error(result, ["--antialias ssaa4 at 8192 x 16: the supersampled target of 32768 x 64 is over",
                                "choose a smaller K or resolution"], out)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]   # no staging folder left either


# --- reports ------------------------------------------------------------------------------------------------------

NAME = "<img src=x onerror=alert(1)>|x"


def test_runs_md_escapes_what_it_prints():
    """Failed before: runs.md carried a bundle's name as raw HTML (report.html escaped it)."""
    from vdmrender import many

    table = many.table([{"scene": NAME, "status": "failed", "rows": 0, "seconds": 1.0, "reason": "<b>bad</b>\x1b"}])
    assert "<img" not in table and "<b>" not in table, table
    assert "| &lt;img src=x onerror=alert(1)&gt;\\|x | failed | 0 | 1.0 | &lt;b&gt;bad&lt;/b&gt;\\x1b |" in table


def test_baseline_md_escapes_what_it_prints():
    from vdmrender.reporting.report import baseline_table

    row = {k: None for k in ("old_mean_dluv", "new_mean_dluv", "d_mean_dluv", "old_p95_dluv", "new_p95_dluv",
                             "d_p95_dluv", "d_flip", "old_ms", "new_ms", "time_ratio", "noise_ms")}
    block = {"thresholds": {"max_error_increase": None, "max_slowdown": None}, "notes": [f"note {NAME}"],
             "rows": [{**row, "object": NAME, "label": "<i>mesh</i>", "exceeds": [], "status": "new"}]}
    table = baseline_table(block)
    assert "<img" not in table and "<i>" not in table, table
    assert "note: note &lt;img src=x onerror=alert(1)&gt;\\|x" in table
    assert "| &lt;img src=x onerror=alert(1)&gt;\\|x | &lt;i&gt;mesh&lt;/i&gt; |" in table


# --- vdmexport's lod.json ------------------------------------------------------------------------------------------

def _entries(*bands, **entry) -> list[dict]:
    return [{"variant": "mesh", "technique": "mesh", "min_px": lo, "max_px": hi, "meets": True,
             "screen_coverage": [hi / 32, lo / 32], "measured": [], **entry} for hi, lo in bands]


@pytest.mark.parametrize("entries, message", [
    (_entries((8, 4), (4, 0), screen_coverage=[]),          # an IndexError traceback before
     "key 'chains[0].objects.ball.entries[0].screen_coverage' has value []; allowed: a list of 2 finite numbers in "
     "[0, 32768]"),
    (_entries((8, 0), screen_coverage=[0.9, 0.5]),
     "screen_coverage' has value [0.9, 0.5]; allowed: [max_px, min_px] over the frame's height 32: [0.25, 0]"),
    (_entries((8, 0), technique="billboards"),              # exported as an impostor of no parts before
     "chain 'a' object 'ball' gives variant 'mesh' the technique 'billboards', where the bundle's scene makes it a "
     "'mesh' variant"),
])
def test_lod_json_types_are_checked(tmp_path, bundles, entries, message):
    from exports import export, lod_of_one

    lod = lod_of_one(bundles[0].identity)
    lod["chains"][0]["objects"]["ball"] = {"entries": entries, "meshes_only": {"entries": _entries((8, 0))}}
    r = export(bundles[0], lod, tmp_path / "x")
    assert r.exit_code == 2 and message in r.output and "Traceback" not in r.output, r.output
    assert not (tmp_path / "x").exists()


# --- no warning before a clean error ----------------------------------------------------------------------------

@pytest.mark.parametrize("node", [{"scale": [1e308] * 3, "rotation": [1, 1, 1, 1]}, {"matrix": [1e308] * 16},
                                  {"translation": [1e308, 0, 0], "scale": [1e308, 1, 1]}])
def test_a_glTF_overflowing_float64_is_refused_without_a_warning(tmp_path, node):
    """Failed before: numpy's RuntimeWarning (overflow encountered in multiply) and its source line were printed
    before the clean error."""
    gltf_asset(tmp_path)
    _with(tmp_path / "quad.gltf", lambda tree: tree["nodes"][0].update(node))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError, match="its transform has a non-finite number|NaN or Inf coordinates"):
            load_mesh_file(tmp_path / "quad.gltf")


# --- a lone copy far from the origin ------------------------------------------------------------------------------

def test_one_copy_far_from_the_origin_is_refused(tmp_path):
    """Left from issue 32: one copy placed at [1e20, 0, 0] baked with exit 0 (only copies far from each other were
    refused), and the reference, placed in float64, held nothing of it: IoU 0."""
    from vdmbake.common import instances

    one = np.eye(4)[None].copy()
    one[0, 0, 3] = 1e20
    with pytest.raises(InputError, match=r"o: copy 0 lies 1e\+20 from the origin \(at \[1e\+20, 0.0, 0.0\]\) with a "
                                         r"radius of 1, 1e-20 of that distance, less than 5.68e-14"):
        instances.check(one, np.zeros(3), 1.0, "o")
    one[0, 0, 3] = 1e12                      # 1e-12 of its distance: kept to 1/256 of its radius in float64
    instances.check(one, np.zeros(3), 1.0, "o")
    lone = FAR_COPIES.replace("[[objects.instances.placements]]\ntranslate = [0, 0, 0]\n", "")
    out = tmp_path / "b"
    assert_input_error(bake(write_scene(tmp_path, lone.replace("FAR", "1e20")), "-o", out),
                       "object 'b': copy 0 lies 1e+20 from the origin", out)


def test_a_mesh_at_1e308_is_refused_without_a_warning(tmp_path):
    """The finding as found: a node translated to 1e308 printed numpy's RuntimeWarning (overflow encountered in add)
    and its source line (meshes.validate) before the clean error."""
    gltf_asset(tmp_path)
    _with(tmp_path / "quad.gltf", lambda tree: tree["nodes"][0].update(translation=[1e308, 0, 0]))
    out = tmp_path / "out"
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        result = bake(write_scene(tmp_path, scene("quad.gltf")), "-o", out)
    assert_input_error(result, "the bounding sphere (centre [1e+308, 0.5, 0.05], radius 0.5", out)
    assert not said, [str(w.message) for w in said]
