"""glTF accessors checked against each other and their buffer views before a byte is read (issue 32): a COLOR_0
shorter than POSITION (a ValueError traceback before), a byteStride smaller than the element (read from
overlapping bytes, exit 0 before), offsets and counts past the view or the buffer. Each is an InputError (exit 2)
naming the file, the accessor and what is wrong."""
from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from gltf_files import Gltf
from vdmbake.assets.meshes import load_mesh_file
from vdmbake.cli import main as bake_main
from vdmbake.errors import InputError

RED = np.full((4, 3), 0.5, np.float32)


def _colour_view(g: Gltf, p: dict) -> dict:
    return g.tree["bufferViews"][g.tree["accessors"][p["attributes"]["COLOR_0"]]["bufferView"]]


def _short_colour(g, p):
    g.tree["accessors"][p["attributes"]["COLOR_0"]]["count"] = 3


def _narrow_stride(g, p):
    _colour_view(g, p)["byteStride"] = 4


def _past_the_view(g, p):
    g.tree["accessors"][p["attributes"]["COLOR_0"]]["byteOffset"] = 8


def _past_the_buffer(g, p):
    _colour_view(g, p)["byteOffset"] += 1 << 20


def _misaligned(g, p):
    g.tree["accessors"][p["attributes"]["POSITION"]]["byteOffset"] = 2


def _no_such_view(g, p):
    g.tree["accessors"][p["indices"]]["bufferView"] = 99


CASES = [(_short_colour, r"attributes have different counts \(\{'POSITION': 4, 'COLOR_0': 3\}\)"),
         (_narrow_stride, r"COLOR_0 \(accessor 2\): bufferView 2's byteStride 4 is smaller than one element"),
         (_past_the_view, r"COLOR_0 \(accessor 2\): 4 elements from byteOffset 8 .* past bufferView 2's byteLength"),
         (_past_the_buffer, r"COLOR_0 \(accessor 2\): bufferView 2 ends at byte \d+, past its buffer 0"),
         (_misaligned, r"POSITION \(accessor 0\): byteOffset 2 .* not a multiple of its component's 4 bytes"),
         (_no_such_view, r"indices \(accessor 1\): bufferView 99 does not exist")]


def _file(tmp_path, spoil):
    g = Gltf()
    p = g.primitive(RED)
    spoil(g, p)
    g.node(mesh=g.mesh(p))
    return g.write(tmp_path / "quad.gltf")


@pytest.mark.parametrize("spoil, match", CASES, ids=[c[0].__name__ for c in CASES])
def test_accessor_out_of_layout_is_refused(tmp_path, spoil, match):
    with pytest.raises(InputError, match=match) as e:
        load_mesh_file(_file(tmp_path, spoil))
    assert "quad.gltf: mesh 0 primitive 0" in str(e.value)


def test_the_tool_exits_2_naming_file_and_accessor(tmp_path):
    """Failed before the fix: a ValueError traceback (merge_vertices), exit 1."""
    _file(tmp_path, _short_colour)
    (tmp_path / "s.toml").write_text('[[objects]]\nname = "q"\nmesh = "quad.gltf"\ntechniques = { mesh = {} }\n')
    r = CliRunner().invoke(bake_main, [str(tmp_path / "s.toml"), "-o", str(tmp_path / "s.bundle")],
                           env={"VDM_CACHE": None})
    assert r.exit_code == 2 and "Traceback" not in r.output, r.output
    assert "quad.gltf: mesh 0 primitive 0: its attributes have different counts" in r.output


def test_a_valid_file_still_loads(tmp_path):
    assert len(load_mesh_file(_file(tmp_path, lambda g, p: None)).vertices) == 4


def test_damaged_json_is_refused_in_one_line(tmp_path):
    """Found by test_fuzz_textured_gltf: the accessor check read the JSON before trimesh and let its
    JSONDecodeError through (exit 1)."""
    (tmp_path / "quad.gltf").write_text('{"asset": 1} trailing')
    with pytest.raises(InputError, match=r"quad.gltf: not readable glTF JSON \(JSONDecodeError: Extra data"):
        load_mesh_file(tmp_path / "quad.gltf")
