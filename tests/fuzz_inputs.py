"""Fuzzing the two inputs a user hands the tools: scene files and bundle manifests (hypothesis).

Each example mutates a valid input (values replaced by arbitrary data: huge integers, NaN, Inf,
1e-200, strings with newlines, deep nesting; keys deleted or added; TOML text edited character-wise)
and checks the contract: the tool accepts it or refuses it with an InputError of one line (exit 2),
never another exception; what it accepts is usable: a scene round-trips through the manifest with
every number finite, a manifest's parts all read (or are refused), its cameras can be made.
`make test` runs a few hundred examples (tests/test_fuzz.py); `make fuzz` runs VDM_FUZZ_EXAMPLES
(1000) of each, randomised."""
from __future__ import annotations

import copy
import json
import math
import os
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from vdmbake.errors import InputError

EXAMPLES = int(os.environ.get("VDM_FUZZ_EXAMPLES", "150"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize="VDM_FUZZ_EXAMPLES" not in os.environ,
                    suppress_health_check=list(HealthCheck), database=None)


def _deep(n: int):
    out = []
    for _ in range(n):
        out = [out]
    return out


SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(), st.sampled_from([0, -1, 1, 2**31, 2**63, 10**400, -10**400]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e-200, -1e-200, 5e-324, 1e308, -0.0, 0.5, 1.0, 1e9, 1e-9]),
    st.text(max_size=12), st.sampled_from(["", "a\nb", "sphere", "bricks", "mesh", "all", "../x", "x" * 300]))
VALUES = st.one_of(
    st.recursive(SCALARS, lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=8), c, max_size=4),
                 max_leaves=8),
    st.builds(_deep, st.sampled_from([50, 400])))


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


@st.composite
def mutated(draw, base):
    """`base` with one to three edits: a value replaced, a key or item deleted, a key added."""
    data = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(data) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = data
        for k in path[:-1]:
            parent = parent[k]
        op = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
        if op == "replace":
            parent[path[-1]] = draw(VALUES)
        elif op == "delete":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[draw(st.text(max_size=8))] = draw(VALUES)
        else:
            parent.append(draw(VALUES))
    return data


def one_line(e: InputError) -> None:
    msg = str(e)
    assert msg and "\n" not in msg, repr(msg)


def _floats(node):
    if isinstance(node, float):
        yield node
    elif isinstance(node, dict):
        for v in node.values():
            yield from _floats(v)
    elif isinstance(node, (list, tuple)):
        for v in node:
            yield from _floats(v)


def check_scene_data(data) -> None:
    """A scene as parsed data: refused in one line, or accepted, finite, and round-tripping."""
    from vdmbake.scene import parse_scene_dict

    try:
        scene = parse_scene_dict(data, "fuzz.toml")
    except InputError as e:
        one_line(e)
        return
    resolved = scene.to_dict()
    assert all(math.isfinite(x) for x in _floats(resolved)), resolved
    assert all(math.isfinite(x) for x in scene.light.direction) and abs(sum(x * x for x in scene.light.direction) - 1) < 1e-9
    assert parse_scene_dict(json.loads(json.dumps(resolved)), "manifest") == scene


def check_scene_text(path: Path, text: str) -> None:
    from vdmbake.scene import load_scene

    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    try:
        load_scene(path)
    except InputError as e:
        one_line(e)


def check_manifest(bundle: Path, manifest) -> None:
    """A bundle with this manifest: refused in one line, or every part reads (or is refused in one
    line), and every object's cameras and the memory guard work from what was accepted."""
    from vdmbake.bundle.directory import Bundle
    from vdmbake.bundle.parts import KINDS
    from vdmrender.camera import cameras_for
    from vdmrender.render import geometry_bytes

    (bundle / "manifest.json").write_text(json.dumps(manifest))
    try:
        b = Bundle(bundle)
    except InputError as e:
        one_line(e)
        return
    for rel, meta in b.manifest["parts"].items():
        try:
            b.read(rel, KINDS[meta["kind"]])
        except InputError as e:
            one_line(e)
    geometry_bytes(b)
    for obj in b.scene.objects:
        entry = b.manifest["objects"][obj.name]
        for cam in cameras_for(b.scene.camera, entry["centre"], entry["radius"], 8, 8):
            eye, d = cam.pixel_rays()
            assert np.isfinite(d).all() and np.isfinite(eye).all() and 0 < cam.near < cam.far
