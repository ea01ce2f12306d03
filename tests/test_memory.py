"""The render's one memory rule (vdmbake.bundle.budget.render_parts and check_render): its estimate bounds what a
run really holds, and a run over it is refused before anything is traced, with exit 2."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from vdmbake.bundle import budget
from vdmbake.bundle.directory import Bundle
from vdmbake.errors import InputError
from vdmbake.scene import ANTIALIAS

from helpers import assert_input_error, bake, render, write_scene
from scenes import BALL, BRICK_PLANE, TINY_HEAD

ROOT = Path(__file__).resolve().parent.parent

# The estimate is at least the measured peak and at most FACTOR times it: the constants are measured peaks rounded
# up about 2x (budget.py says each measurement), and one case of each kind lands between 1.5x and 2.7x.
FACTOR = 4


GL = pytest.mark.gl   # the case draws (llvmpipe), in its own process


@pytest.mark.slow
@pytest.mark.parametrize("case", [
    pytest.param("mesh 400 256 16 2 2", marks=GL),   # a 160k-face torus drawn and traced at 256^2, 16 spp, 2 threads
    pytest.param("mesh 400 256 1 2 2", marks=GL),    # the same at 1 spp (2 cameras' frames kept in both)
    pytest.param("displaced 64", marks=GL),          # a torus under 64^2 bricks tiled 2 x 2: 590k faces, twice
    "quadrics 40000 128",                            # 40k spheres' reference, a 128^2 frame
    *(pytest.param(f"targets 512 {mode}", marks=GL) for mode in ("none", "msaa4", "ssaa2", "ssaa4")),
])
def test_estimate_bounds_the_measured_peak(case):
    """Each kind in a process of its own (tests/memory_peaks.py: the growth of its peak resident set, Embree's and
    llvmpipe's allocations included)."""
    r = subprocess.run([sys.executable, str(ROOT / "tests" / "memory_peaks.py"), *case.split()], capture_output=True,
                       text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    got = json.loads(r.stdout.splitlines()[-1])
    assert got["measured"] <= got["estimate"] <= FACTOR * got["measured"], got


def _parts():
    return budget.Render(640, 480, 4, spp=16, threads=3, antialias=ANTIALIAS["ssaa2"],
                         objects=(budget.Geometry("a", faces=10_000), budget.Geometry("b", quadrics=2_000),
                                  budget.Geometry("c", faces=100, displaced=1_000)))


def test_the_parts_and_their_sum():
    """Every part a render holds, summed: the largest object's geometry and displaced reference (one object's
    reference at a time), or every object's when a composite holds them together."""
    r = _parts()
    parts = budget.render_parts(r)
    assert parts["reference"][0] == 640 * 480 * (budget.FILTERED_BYTES_PER_PIXEL
                                                 + 2 * budget.FILTERED_BYTES_PER_THREAD_PIXEL
                                                 + 4 * budget.HELD_BYTES_PER_CAMERA_PIXEL)
    assert parts["targets"][0] == 640 * 480 * (2 * budget.TARGET_BYTES_PER_PIXEL + 4 * budget.BYTES_PER_SAMPLE)
    assert parts["geometry"][0] == 2_000 * budget.BYTES_PER_QUADRIC and "'b'" in parts["geometry"][1]
    assert parts["displaced reference"][0] == 0        # object b is the largest; c's reference is not held with it
    assert budget.render_bytes(r) == sum(p[0] for p in parts.values())
    together = budget.render_parts(budget.Render(640, 480, 4, objects=r.objects, together=True))
    assert together["geometry"][0] == 10_100 * budget.BYTES_PER_FACE + 2_000 * budget.BYTES_PER_QUADRIC
    assert together["displaced reference"][0] == 1_000 * budget.DISPLACED_BYTES_PER_FACE


def test_one_message_names_the_parts_the_sum_the_limit_and_the_setting():
    r = _parts()
    need = budget.render_bytes(r)
    with pytest.raises(InputError) as e:
        budget.check_render(r, free=need - 1)
    message = str(e.value)
    assert message.startswith("the render (reference ")
    for needle in ("640x480 at 16 spp on 3 threads, 4 cameras", f"geometry {2_000 * 8192 / 2**30:.3g} GiB: object 'b'",
                   "targets", "ssaa2", f"needs about {need / 2**30:.1f} GiB", "memory available now",
                   "lower the reference: render.resolution (--resolution), render.reference_spp"):
        assert needle in message, (needle, message)
    assert "displaced reference" not in message        # a part of nothing is left out
    assert budget.check_render(r, free=need) is None


def test_held_to_the_budget_however_much_is_free(monkeypatch):
    """One rule for every job: the render is held to the bake's BUDGET too."""
    r = _parts()
    monkeypatch.setattr(budget, "BUDGET", budget.render_bytes(r) - 1)
    with pytest.raises(InputError, match=r"the render .*vdmbake.bundle.budget.BUDGET"):
        budget.check_render(r, free=1 << 50)


def _no_tracing(monkeypatch):
    """Fail the test if the run reaches a reference or a GL context."""
    from vdmrender.gpu import gl
    from vdmrender.tracing import refcache

    def reached(*args, **kwargs):
        raise AssertionError("the run started work before its memory was checked")

    monkeypatch.setattr(refcache, "_object_reference", reached)
    monkeypatch.setattr(gl, "create_context", reached)


def test_render_over_the_budget_refused_before_tracing(tmp_path, monkeypatch):
    """vdmrender with a budget smaller than what this scene needs: exit 2, one message, no output, nothing traced."""
    from vdmrender.render import Options, memory_need

    bundle = tmp_path / "b.bundle"
    assert bake(write_scene(tmp_path, TINY_HEAD + BALL), "-o", bundle).exit_code == 0
    need = budget.render_bytes(memory_need(Bundle(bundle), 32, 32, Options(reference_spp=1, antialias="none")))
    monkeypatch.setattr(budget, "BUDGET", need - 1)
    _no_tracing(monkeypatch)
    out = tmp_path / "r"
    assert_input_error(render(bundle, "-o", out), ["the render (reference", "32x32", "object 'ball'",
                                                  "vdmbake.bundle.budget.BUDGET", "lower the"], out)
    monkeypatch.setattr(budget, "BUDGET", need)
    assert "memory was checked" in str(render(bundle, "-o", out).exception)   # at the budget, it goes on to work


@pytest.mark.parametrize("technique", ["relief = { iterations = [4] }", "displaced = { levels = [0] }"])
def test_displaced_reference_beyond_the_budget_refused(tmp_path, monkeypatch, technique):
    """A mesostructure tiled 10000 x 10000 on a plane: its reference (every edge under half a texel) would be
    8 * 4^19 faces. The bake makes what its techniques need; the render refuses, naming the displaced reference
    and the settings that lower it, before anything is built."""
    scene = TINY_HEAD + BRICK_PLANE.replace("tiling = [2, 2]", "tiling = [10000, 10000]").replace(
        "techniques = { pom = { steps = [8] }, bump = {} }", f"techniques = {{ {technique} }}")
    bundle = tmp_path / "b.bundle"
    assert bake(write_scene(tmp_path, scene), "-o", bundle).exit_code == 0
    _no_tracing(monkeypatch)
    out = tmp_path / "r"
    assert_input_error(render(bundle, "-o", out), ["displaced reference", "object 'p'", "faces",
                                                  "lower the displaced reference: the object's mesostructure.tiling "
                                                  "or size"], out)
