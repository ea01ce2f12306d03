"""vdmrender: render a bundle with each technique and the reference; report error against time."""
from __future__ import annotations

import dataclasses
import json
import sys
import uuid
from pathlib import Path

import click

from vdmbake import __version__
from vdmbake.errors import InputError, escaped, fail, guarded
from vdmbake.cluster import check_address
from vdmbake.scene import REGISTRY
from vdmbake.schema import Invalid, default_text, flag_name

from . import many as many_bundles
from .gpu import gl
from .measuring.timing import Budget
from .render import OVERRIDES, Options, run
from .reporting.report import baseline_table
from .tracing.refcache import Shared


class Setting(click.ParamType):
    """A scene setting's value on the command line, read by the setting's own type (vdmbake.schema): the option
    refuses what the scene file refuses, with the same words."""

    def __init__(self, field):
        self.type, self.name = field.metadata["type"], field.metadata["flag"]

    def convert(self, value, param, ctx):
        try:
            return self.type.parse(self.type.from_text(value))
        except Invalid:
            self.fail(f"{value!r}: expected {self.name}; allowed: {self.type.text}", param, ctx)


def overrides(command):
    """One option per scene setting a run overrides (render.OVERRIDES), its help the setting's own description,
    allowed values and default, as docs/scenes.md gives them."""
    for key, f in reversed(OVERRIDES):
        doc, t = f.metadata["doc"], f.metadata["type"]
        default = "" if f.default is dataclasses.MISSING else f"; default {default_text(f)}"
        command = click.option(flag_name(f), f.name, type=Setting(f), metavar=f.metadata["flag"],
                               help=f"{doc[0].upper()}{doc[1:]}. Overrides the scene's {key}. Allowed: {t.text}"
                                    f"{default}.")(command)
    return command


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("bundles", nargs=-1, required=True, metavar="BUNDLE...", type=click.Path(path_type=Path))
@click.option("-o", "--output", "out", required=True, type=click.Path(path_type=Path),
              help="Output folder (frames, reference, heat maps, report); replaced atomically. Several bundles (or a "
                   "folder of them): OUTPUT/<bundle name>/ each, and the combined report in OUTPUT.")
@click.option("-t", "--technique", "techniques", multiple=True,
              help=f"Render only this technique (repeatable; {', '.join(REGISTRY)}); default: every technique "
                   "the scene names.")
@overrides
@click.option("--warmup-s", type=click.FloatRange(0, 600), metavar="SECONDS",
              help=f"Warm up at least this long, then until successive windows of GPU times agree within "
                   f"{Budget.tolerance:.0%} (default {Budget.warmup_s:g}; on a GPU give 2: its clocks need about a "
                   "second of sustained work).")
@click.option("--sample-s", type=click.FloatRange(0, 600), metavar="SECONDS",
              help=f"Time at least this long (and at least --repeats renders per frame; default {Budget.sample_s:g}).")
@click.option("--device", help="The GPU: an EGL device index N, or cuda:N for the GPU CUDA numbers N (NVIDIA, "
                               "EGL_NV_device_cuda); or set VDM_GL_DEVICE.")
@click.option("--max-error", type=click.FloatRange(min=0), help="Exit 1 if any technique's mean ΔLuv exceeds this.")
@click.option("--baseline", type=click.Path(path_type=Path),
              help="An earlier run's report.json: report per object and variant the change in mean ΔLuv, p95, "
                   "FLIP and time (a table on stderr; OUTPUT/baseline.md, baseline.csv and report.json's "
                   "'baseline' block).")
@click.option("--max-error-increase", type=click.FloatRange(min=0),
              help="With --baseline: exit 1 if a variant's mean ΔLuv grew by more than this (absolute ΔLuv).")
@click.option("--max-slowdown", type=click.FloatRange(min=0, min_open=True),
              help="With --baseline: exit 1 if a variant's median GPU time per frame grew by more than this ratio "
                   "(1.25: 25% slower) and by more than both runs' spreads together (noise).")
@click.option("--compare-devices", is_flag=True,
              help="With --baseline: compare times even when the baseline ran on another GL device (refused "
                   "otherwise: --max-slowdown exits 2, and the table leaves times out).")
@click.option("--counters/--no-counters", default=Options.counters, show_default=True,
              help="Count each variant's work per frame, device-independent (fragments shaded, texture fetches, "
                   "search steps, primitives, draws, instances, GPU bytes held: report.json's counters, "
                   "per_pixel, counters_per_pass) from one more frame per camera of an instrumented build.")
@click.option("--flip/--no-flip", default=Options.flip, show_default=True,
              help="Also score every frame with NVIDIA FLIP (flip_mean in the report; about 2 s per 512x512 "
                   "frame on 2 CPU cores).")
@click.option("--heat-max", type=click.FloatRange(min=1e-3), default=Options.heat_max, show_default=True,
              help="ΔLuv at the top of the heat maps' colour scale.")
@click.option("--scheduler", metavar="ADDRESS",
              help="Render on a Dask cluster: tcp://HOST:8786 (a running `dask scheduler`, its workers each with their "
                   "own GL device), or local:N for N worker processes here: every reference a task on any worker, "
                   "then one task per bundle (all its timed GL work on one device), every file but the timings as "
                   "on one machine. Needs the `cluster` extra (docs/cluster.md).")
@click.option("--workers-wait", type=click.FloatRange(0, 86400), default=60.0, show_default=True, metavar="SECONDS",
              help="With --scheduler: how long the scheduler may have no worker (before the first bundle or later) "
                   "before the run stops (exit 2, naming the scheduler and what finished).")
@click.option("--reference-cache", type=click.Path(file_okay=False, path_type=Path), metavar="DIR",
              help="Keep references by content key (bundle parts, light, material, cameras, samples, tracer code) in "
                   "DIR, found there by any later run, on any machine that sees DIR; with --scheduler every worker "
                   "needs it (default there: a hidden sibling of OUTPUT, removed after the run).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON on stdout.")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-paragraph errors.")
@click.version_option(__version__)
def main(bundles, out, techniques, warmup_s, sample_s, device, max_error, baseline, max_error_increase, max_slowdown,
         compare_devices, counters, flip, heat_max, scheduler, workers_wait, reference_cache, as_json, debug,
         **overridden):
    """Render each BUNDLE (made by vdmbake) into OUTPUT and report error against run time.

    For every object, each technique variant (a technique at one value of its quality
    knob, e.g. coarse@0.1) renders the scene's camera frames on the GPU (OpenGL through
    EGL: a real GPU where there is one, Mesa llvmpipe where there is not), and an
    independent reference is traced on the CPU with Embree. Each frame's error is the
    mean CIE-Luv distance to the reference over the union of both coverage masks (the
    enhanced-billboards thesis's eq. 2.2), with NVIDIA FLIP over the same pixels beside
    it. With --reference-spp N the reference is each pixel's mean over N samples, and with
    --antialias the variants are anti-aliased, so the error is what a viewer sees, and it
    falls with screen size where detail goes below a pixel; the point-sampled error stays
    beside it (aliased_mean_dluv). Time is the GPU's: per frame the sum of its passes' GL timer queries, after a
    warm-up that lasts until the times are steady, median over every timed frame, with
    the spread, wall time and CPU submit time beside it (the harness's own clear of the
    target is timed apart). A frame where neither the variant nor the reference covers a
    pixel is reported as empty (no error), never as a perfect score.

    \b
    OUTPUT/frames/OBJECT/VARIANT/NNN.png     rendered frames
    OUTPUT/reference/OBJECT/NNN.png (.exr)   the reference (cached by content and code hash);
                                             with --reference-spp, the pixel centres' in point/
    OUTPUT/heatmaps/OBJECT/VARIANT/NNN.png   per-pixel ΔLuv, 0 to --heat-max
    OUTPUT/overview/OBJECT.png               everything on one sheet
    OUTPUT/composite/                        with render.composite: every object in one frame per
                                             variant set (frames/SET/, heatmaps/SET/, reference/,
                                             overview.png) and OUTPUT/composite.md
    OUTPUT/report.json, report.csv, error_vs_time.png
    OUTPUT/report.html                       all of it on one offline page (plots, table, frames)
    OUTPUT/baseline.md, baseline.csv         with --baseline: the change per variant
    DIR/KEY/                                 with --reference-cache: each reference by its key
    OUTPUT/sizes/NNNpx/...                   with --sizes or render.sweep: frames, heat maps,
                                             reference and overviews at each screen size
    OUTPUT/sweep.csv, error_vs_size.png, cost_vs_size.png   the same, against screen size
    OUTPUT/lod.json, lod.md, lod.png         with [[render.sweep.lod]]: per object the cheapest
                                             variant within the limits per band of screen sizes
                                             (decided on interleaved frames), its pops and
                                             hysteresis; for copies, priced on their field

    Several bundles, or a folder of them: each into OUTPUT/<bundle name without .bundle>/ as
    alone, one after another on the GPU (or with --scheduler each on a cluster worker, with its
    own GPU); OUTPUT/report.json, report.csv and error_vs_time.png
    combine their rows (object spelled SCENE/OBJECT, so --baseline compares combined reports),
    OUTPUT/runs.md lists each bundle's status; a bundle that fails does not stop the others.

    Exit codes: 0 done; 1 done but a threshold was exceeded (--max-error, --max-error-increase,
    --max-slowdown) or some of several bundles failed (each named); 2 bad usage or bad input, or a variant or composite set with no covered pixel in
    any frame (unless its objects set expect_empty = true), also under --debug, which adds the traceback,
    or a --scheduler run stopped by its cluster (the scheduler lost, or no worker for --workers-wait:
    the closing table says what finished); 128 + N stopped by signal N (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP). --debug also makes GL strict: a uniform or
    vertex attribute a shader does not have is an error instead of being skipped.

    \b
    Examples:
      vdmrender out/default.bundle -o out/default --max-error 2.0
      vdmrender out/default.bundle -o out/new --baseline out/default/report.json \\
          --max-error-increase 0.05 --max-slowdown 1.25 --sample-s 1.5
      vdmrender out/default.bundle -o out/gpu --device cuda:0 --warmup-s 2 --sample-s 1
      vdmrender out/lod-bunny.bundle -o out/lod-bunny --sizes 512,256,128,64,32,16 \\
          --reference-spp 16 --antialias ssaa2
      vdmrender out/library/bundles -o out/library/renders --baseline old/report.json --max-error-increase 0.1
      vdmrender out/library/bundles -o /shared/renders --scheduler tcp://farm-head:8786
    """
    if (max_error_increase is not None or max_slowdown is not None) and baseline is None:
        fail(InputError("--max-error-increase and --max-slowdown compare with an earlier run; give its "
                        "report.json with --baseline OLD/report.json."), debug)
    log = (lambda m: None) if as_json else (lambda m: click.echo(escaped(m), err=True))   # paths are raw input
    opts = Options(techniques=techniques or None, warmup_s=warmup_s, sample_s=sample_s, device=device,
                   heat_max=heat_max, flip=flip, baseline=baseline, max_error_increase=max_error_increase,
                   max_slowdown=max_slowdown, compare_devices=compare_devices, counters=counters,
                   reference_cache=reference_cache and Shared(str(reference_cache.absolute()), uuid.uuid4().hex),
                   **overridden)
    if debug:
        gl.STRICT = True
    found, many = guarded(lambda: many_bundles.bundles(bundles), debug)
    if scheduler is not None:
        from . import cluster
        guarded(lambda: check_address(scheduler), debug)
    if many:
        result = guarded(lambda: many_bundles.run_many(found, out, opts, log) if scheduler is None else
                         cluster.run_many(found, out, opts, log, scheduler, workers_wait), debug)
        click.echo(many_bundles.table(result["runs"]), err=True)
    else:
        result = guarded(lambda: run(found[0], out, opts, log) if scheduler is None else
                         cluster.run_one(found[0], out, opts, log, scheduler, workers_wait), debug)
    if as_json:
        click.echo(json.dumps(result, indent=1, allow_nan=False))
    elif many:
        click.echo(escaped(f"combined report: {out / 'report.html'} (open it in a browser; report.json, runs.md "
                           f"beside it)  ({result['device']})"))
    else:
        beside = "report.json, lod.md, error_vs_time.png" if (out / "lod.md").exists() else "report.json, error_vs_time.png"
        click.echo(escaped(f"report: {out / 'report.html'} (open it in a browser; {beside} beside it)  "
                           f"({result['device']})"))
    rows = result["rows"]
    worst = [r for r in rows if max_error is not None and r["mean_dluv"] is not None and r["mean_dluv"] > max_error]
    for r in worst:
        click.echo(f"{r['object']}: {r['label']} mean ΔLuv {r['mean_dluv']} exceeds --max-error {max_error}", err=True)
    block = result.get("baseline")
    if block is not None:
        click.echo(baseline_table(block), err=True)
        for name in block["failed"]:
            click.echo(f"{name}: exceeds the baseline thresholds", err=True)
    drawn = ("neither the variant nor the reference draws anything, or every pixel drawn sees an open border or "
             "the surface from inside, which are scored apart")
    empty = [(f"{r['object']}: {r['label']}", drawn, "aim the cameras at the object, or set expect_empty = true on it")
             for r in rows if r["empty_frames"] == r["frames"] and not r["expect_empty"]]
    empty += [(f"composite set {r['set']} ({r['label']})", "neither its variants nor the reference draw anything",
               "aim the cameras at the objects, or set expect_empty = true on every object")
              for r in result.get("composite", []) if r["empty_frames"] == r["frames"] and not r["expect_empty"]]
    for name, why, advice in empty:
        click.echo(f"error: {name}: no frame has a pixel to score ({why}), so there is nothing to measure; "
                   f"{advice} if that is the point.", err=True)
    failed = [r["scene"] for r in result.get("runs", []) if r["status"] == "failed"]
    if failed:
        click.echo(escaped(f"{len(failed)} of {len(result['runs'])} bundles failed: {', '.join(failed)}"), err=True)
    if result.get("stopped"):
        click.echo(escaped(f"error: the run stopped: {result['stopped']}"), err=True)
    sys.exit(2 if empty or result.get("stopped") else 1 if worst or failed or (block and block["failed"]) else 0)


if __name__ == "__main__":
    main()
