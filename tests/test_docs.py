"""Docs that cannot drift: the scene reference (docs/scenes.md) and the CLIs' help come from the same
declarations the scene reader validates against (vdmbake.schema, the technique registry), and every
result table of README.md and docs/*.md is written from its committed result file (tools/make_docs.py,
`make docs`)."""
from __future__ import annotations

from pathlib import Path

import importlib.util
import json
import re
import subprocess
import sys

import pytest
from click.testing import CliRunner

from vdmbake import scenedoc
from vdmbake.cli import main as bake_main
from vdmbake.errors import InputError
from vdmbake.scene import REGISTRY, Render, parse_scene_dict
from vdmbake.schema import settings
from vdmrender.cli import main as render_main

from bench import publish
from helpers import make_docs

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
SCENES = ROOT / "docs" / "scenes.md"
RESULTS = ROOT / "docs" / "results.md"


def scene(**objects_extra) -> dict:
    obj = {"name": "s", "primitive": "sphere", "techniques": {"mesh": {}}, **objects_extra}
    return {"objects": [obj]}


def test_scene_reference_is_current():
    text = SCENES.read_text()
    assert scenedoc.block() in text, "the scene reference is stale: run python -m vdmbake.scenedoc docs/scenes.md"


def test_reference_names_every_key_and_technique_setting():
    ref = scenedoc.reference()
    for f in settings(Render):
        assert f"`{f.name}`" in ref
    for t in REGISTRY.values():
        assert f"`{t.name}`" in ref
        for f in settings(t.options):
            assert f"`{t.name}.{f.name}`" in ref


def test_help_lists_every_technique():
    bake_help = CliRunner().invoke(bake_main, ["--help"]).output
    render_help = CliRunner().invoke(render_main, ["--help"]).output
    for name in REGISTRY:
        assert f"  {name} " in bake_help and name in render_help


def test_unknown_key_lists_every_allowed_key():
    with pytest.raises(InputError) as e:
        parse_scene_dict({"render": {"bogus": 1}, **scene()}, "s.toml")
    for f in settings(Render):
        assert f.name in str(e.value)
    with pytest.raises(InputError) as e:
        parse_scene_dict(scene(techniques={"billboards": {"resolutoin": 64}}), "s.toml")
    assert all(k in str(e.value) for k in ("variants", "resolution", "coarse_ratio"))


@pytest.mark.parametrize("techniques,key", [
    ({"billboards": {"resolution": 100.5}}, "resolution"),    # an integer setting: no silent truncation
    ({"coarse": {"ratios": [1, 1.0]}}, "ratios"),             # the same ratio twice
    ({"coarse": {"ratios": [10 ** 400]}}, "ratios"),          # an integer beyond float's range
    ({"coarse": {"ratios": [True]}}, "ratios"),               # a boolean is not a number
])
def test_typed_settings_refuse_what_they_would_mangle(techniques, key):
    with pytest.raises(InputError, match=key):
        parse_scene_dict(scene(techniques=techniques), "s.toml")


def test_tiny_light_direction_normalises():
    s = parse_scene_dict({"light": {"direction": [1e-200, 0, 0]}, **scene()}, "s.toml")
    assert s.light.direction == (1.0, 0.0, 0.0)


def test_result_tables_match_their_result_files():
    """`make docs --check`: every marked table is what its result file renders (exit 0, nothing named)."""
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "make_docs.py"), "--check"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr


def test_a_hand_edited_figure_is_caught():
    """One figure typed into a generated table (the demo's first row's last figure) is found and written back."""
    docs = make_docs()
    text = RESULTS.read_text()
    block = re.search(r"<!-- table:demo:default -->.*?<!-- /table -->", text, re.S)[0]
    row = re.search(r"^\| [^-].*\|$", block.split("|---", 1)[1], re.M)[0]
    digit = re.search(r"(\d)(?=[^\d]*$)", row)
    typed = row[:digit.start()] + str((int(digit[1]) + 1) % 10) + row[digit.end():]
    edited = text.replace(block, block.replace(row, typed))
    assert edited != text
    assert docs.render(edited) == text


MEASURED = re.compile(r"ΔLuv|dLuv|\bms\b|\bMB\b|IoU|\bCPU\b|\bGPU\b|\bwall\b|RSS|\bbefore\b|\bafter\b")


def test_every_measured_table_is_generated():
    """Every table of README.md and docs/*.md whose header names a measured quantity (ΔLuv, IoU, ms, MB, CPU,
    GPU or wall time, RSS) or compares a before with an after, and every table of docs/results.md, lies between table markers; every
    marker names a result file that exists and every result file is used; a transcribed one says which
    command measured it, when and on what device."""
    docs = make_docs()
    for path in docs.documents():
        text = re.sub(r"<!-- table:.*?<!-- /table -->", "", path.read_text(), flags=re.S)
        for header in re.findall(r"^(\|.*\|)\n\|[-:| ]+\|$", text, re.M):
            assert not MEASURED.search(header), f"{path.name}: a measured table typed in ({header}): move it to docs/results/"
    measured = re.sub(r"<!-- table:.*?<!-- /table -->", "", RESULTS.read_text(), flags=re.S)
    assert not re.search(r"^\|---", measured, re.M), "a table of results.md is typed in: move it to docs/results/"
    names = {m[2] for path in docs.documents() for m in docs.BLOCK.finditer(path.read_text())}
    assert names == {p.stem for p in docs.RESULTS.glob("*.json")}, "a result file without a table, or a table without one"


# transcriptions that other work of issue 45 turns into their commands' own output (bench.cluster, the test loop)
def test_every_result_file_is_published_or_says_why_it_is_transcribed():
    """A result file is a bench's own output, published with its whole provenance by a full run (not --quick),
    or a command's own output that make_docs.UNPUBLISHED names with the reason it has no provenance, or a transcription
    that says which command measured it, when, on what device, and why it is transcribed."""
    docs = make_docs()
    for path in sorted(docs.RESULTS.glob("*.json")):
        name, doc = path.stem, json.loads(path.read_text())
        if "provenance" in doc:
            assert name in docs.VIEWS and "tables" not in doc, name
            assert set(doc["provenance"]) == set(publish.FIELDS), name
            assert "--quick" not in doc["provenance"]["command"], f"{name}: a smoke run published"
        elif name in docs.UNPUBLISHED:
            assert docs.UNPUBLISHED[name], name
        else:
            assert {"measured_by", "when", "device"} <= set(doc) and doc.get("transcribed"), \
                f"{name}: a transcription must say which command measured it, when, on what, and why it is transcribed"


def test_rooms_table_is_read_from_the_source():
    """docs/results/rooms.json (architecture.md's rooms table) is what tools/rooms.py reads from vdmrender/ now."""
    spec = importlib.util.spec_from_file_location("rooms", ROOT / "tools" / "rooms.py")
    rooms = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rooms)
    assert json.loads((ROOT / "docs" / "results" / "rooms.json").read_text()) == rooms.survey(ROOT / "vdmrender"), \
        "run python tools/rooms.py && make docs"
