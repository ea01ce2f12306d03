"""The scene settings vdmrender overrides (--resolution, --repeats, --warmup, --sizes, --reference-spp,
--antialias) are declared once, in vdmbake.scene: the scene reader, docs/scenes.md, render.Options and the
click options are made from that declaration, so they accept, refuse, describe and default alike."""
from __future__ import annotations

import dataclasses
import json
import pickle
import re
from pathlib import Path

import pytest

from vdmbake.scene import MAX_SIDE, MAX_SPP, parse_scene_dict
from vdmbake.schema import default_text, flag_name
from vdmrender.cli import main as render_main
from vdmrender.render import OVERRIDES, Options

from helpers import bake, render

ROOT = Path(__file__).resolve().parents[1]
OBJECT = {"name": "s", "primitive": "sphere", "techniques": {"mesh": {}}}

# Per option: values the scene file and the flag both accept, then values both refuse, each as (TOML value, flag text).
CASES = {
    "resolution": ([([512, 256], "512x256"), ([1, MAX_SIDE], f"1x{MAX_SIDE}")],
                   [([0, 10], "0x10"), ([MAX_SIDE + 1, 8], f"{MAX_SIDE + 1}x8"), ([8, 8, 8], "8x8x8"),
                    ([8.5, 8], "8.5x8")]),
    "repeats": ([(1, "1"), (1000, "1000")], [(0, "0"), (1001, "1001"), (1.5, "1.5")]),
    "warmup": ([(0, "0"), (100, "100")], [(-1, "-1"), (101, "101")]),
    "sizes": ([([512, 32], "512,32"), ([4 * MAX_SIDE], str(4 * MAX_SIDE))],
              [([64, 64], "64,64"), ([1], "1"), ([4 * MAX_SIDE + 1], str(4 * MAX_SIDE + 1))]),
    "reference_spp": ([(16, "16"), (MAX_SPP, str(MAX_SPP))], [(5, "5"), (0, "0"), (289, "289")]),
    "antialias": ([("ssaa3", "ssaa3"), ("none", "none")], [("msaa3", "msaa3"), ("", ""), ("SSAA2", "SSAA2")]),
}


def options() -> dict:
    return {p.name: p for p in render_main.params}


def nested(key: str, value) -> dict:
    """{"render": {"sweep": {"sizes": value}}} for key render.sweep.sizes."""
    for part in reversed(key.split(".")):
        value = {part: value}
    return value


def scene_value(key: str, value):
    """The value the scene reader makes of `value` at `key`."""
    obj = parse_scene_dict({**nested(key, value), "objects": [OBJECT]}, "s.toml")
    for part in key.split("."):
        obj = getattr(obj, part)
    return obj


def test_every_override_has_one_declaration_and_three_views(tmp_path):
    """Each setting declared with flag= is an Options field and an option, both None (the scene's) unless given;
    the option reads with the setting's own type, its help is its description, allowed values and default as
    docs/scenes.md gives them."""
    assert [f.name for _, f in OVERRIDES] == list(CASES)
    fields = {f.name: f for f in dataclasses.fields(Options)}
    given = render_main.make_context("vdmrender", [str(tmp_path), "-o", str(tmp_path / "o")]).params
    scenes_md = (ROOT / "docs" / "scenes.md").read_text()
    for key, f in OVERRIDES:
        t, doc = f.metadata["type"], f.metadata["doc"]
        assert fields[f.name].default is None and given[f.name] is None
        option = options()[f.name]
        assert option.opts == [flag_name(f)] and option.metavar == f.metadata["flag"]
        assert option.type.type is t
        assert doc[1:] in option.help and t.text in option.help and key in option.help
        if f.default is not dataclasses.MISSING:
            assert f"default {default_text(f)}" in option.help
        row = next(line for line in scenes_md.splitlines() if line.startswith(f"| `{f.name}` |"))
        assert row == f"| `{f.name}` | {t.text} | {default_text(f)} | {doc}; `vdmrender {flag_name(f)}` |"


def test_options_travel_to_a_cluster_worker():
    """Options (with the fields made from the scene) pickle as a Dask task's argument does."""
    opts = Options(resolution=(8, 8), sizes=(32,), antialias="ssaa2", flip=False)
    assert pickle.loads(pickle.dumps(opts)) == opts


@pytest.mark.parametrize("key,name", [(k, f.name) for k, f in OVERRIDES])
def test_scene_file_and_flag_accept_the_same_values(key, name, tmp_path):
    for value, text in CASES[name][0]:
        ctx = render_main.make_context("vdmrender", [str(tmp_path), "-o", str(tmp_path / "o"),
                                                     flag_name(dict(OVERRIDES)[key]), text])
        assert ctx.params[name] == scene_value(key, value), (name, text)


@pytest.mark.parametrize("key,name", [(k, f.name) for k, f in OVERRIDES])
def test_scene_file_and_flag_refuse_the_same_values_with_exit_2(key, name, tmp_path):
    f = dict(OVERRIDES)[key]
    allowed = f"allowed: {f.metadata['type'].text}"
    for i, (value, text) in enumerate(CASES[name][1]):
        table, leaf = key.rsplit(".", 1)
        scene = tmp_path / f"s{i}.toml"
        scene.write_text(f"[{table}]\n{leaf} = {json.dumps(value)}\n\n[[objects]]\nname = \"s\"\n"
                         "primitive = \"sphere\"\n[objects.techniques.mesh]\n")
        r = bake(scene, "-o", tmp_path / f"b{i}.bundle")
        assert r.exit_code == 2 and f"key '{key}'" in r.output and allowed in r.output, (value, r.output)
        r = render(tmp_path, "-o", tmp_path / "o", flag_name(f), text)
        assert r.exit_code == 2 and re.search(rf"'{re.escape(flag_name(f))}'", r.output), (text, r.output)
        assert allowed in r.output, (text, r.output)
