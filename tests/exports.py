"""vdmexport in the tests (a library module: it holds no tests): lod.json files of one object "ball" written and
exported, two bundles of two scenes to export from, and the engines' reports on exported files."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner

from scenes import BALL, RENDER
from vdmbake.bundle.directory import Bundle
from vdmbake.cli import main as bake_main
from vdmbake.export.cli import main as export_main

ROOT = Path(__file__).parent.parent
MODULES = ROOT / ".venv" / "node" / "node_modules"


def lod_of_levels(bundle: Bundle, levels, name="a") -> dict:
    """A lod.json of `bundle` whose chain `name` gives "ball" the (variant, min_px, max_px) `levels` at 512 px."""
    entries = [{"variant": v, "technique": v.split("@")[0], "min_px": lo, "max_px": hi, "meets": True,
                "screen_coverage": [hi / 512, lo / 512], "measured": []} for v, lo, hi in levels]
    return {"device": "d", "resolution": [512, 512], "bundle": {"manifest_sha256": bundle.identity},
            "chains": [{"name": name, "objects": {"ball": {"entries": entries, "meshes_only": {"entries": entries}}}}]}


def lod_of_one(identity, **entry) -> dict:
    """A lod.json at 32 px of one band (0, 8] of "ball"'s mesh, `entry` overriding its fields; of the bundle whose
    manifest hashes to `identity` (None: a lod.json that records no bundle)."""
    e = {"variant": "mesh", "technique": "mesh", "min_px": 0, "max_px": 8, "meets": True,
         "screen_coverage": [0.25, 0.0], "measured": [], **entry}
    lod = {"device": "d", "resolution": [32, 32], "chains": [{"name": "a", "objects": {"ball": {
        "entries": [e], "meshes_only": {"entries": [e]}}}}]}
    if identity is not None:
        lod["bundle"] = {"manifest_sha256": identity}
    return lod


def export(bundle: Bundle, lod: dict, out: Path):
    """vdmexport of `bundle` by `lod` (written beside `out`) into `out`: the CliRunner result."""
    out.parent.mkdir(parents=True, exist_ok=True)
    (out.parent / f"{out.name}.lod.json").write_text(json.dumps(lod))
    return CliRunner().invoke(export_main, [str(bundle.path), "--lod", str(out.parent / f"{out.name}.lod.json"),
                                            "-o", str(out)])


def two_bundles(folder: Path) -> list[Bundle]:
    """Two bundles of two scenes (the ball in two greys): (this one, another one)."""
    out = []
    for name, grey in (("b", 0.5), ("other", 0.7)):
        scene = folder / f"{name}.toml"
        scene.write_text(RENDER + BALL + f"material = {{ albedo = [{grey}, 0.5, 0.5] }}\n")
        assert CliRunner().invoke(bake_main, [str(scene), "-o", str(folder / name)]).exit_code == 0
        out.append(Bundle(folder / name))
    return out


def engines(script: str, files: tuple) -> list[dict]:
    """The engine's report on each file (tools/engine_*.cjs: one Node process for all of them)."""
    node = shutil.which("node")
    if node is None:
        pytest.skip("Node.js is missing (make test installs it): the engines run in Node")
    for package in ("babylonjs", "babylonjs-loaders", "three"):
        assert (MODULES / package).is_dir(), f"npm {package} is missing from {MODULES}: run the npm line of the " \
            "Makefile's set-up (rm .venv/.installed; make test)"
    r = subprocess.run([node, str(ROOT / "tools" / script), *map(str, files)], capture_output=True, text=True,
                       env={**os.environ, "NODE_PATH": str(MODULES)}, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout)
