"""Many bundles per call (`vdmrender BUNDLE... -o OUTDIR`, issue 24): each bundle rendered as alone into
OUTDIR/<bundle name without .bundle>/ (its own atomic output folder and reference cache), one after another on the
one GL device; a bundle that fails is a row of the closing table and never stops the others. OUTDIR/report.json
combines every run's rows, each keyed by scene, object and variant (`object` spelled SCENE/OBJECT, so that
`--baseline` compares a combined report with an earlier one row by row), beside report.csv, error_vs_time.png and
runs.md (scene, status, rows, seconds, reason). OUTDIR is staged whole as every output folder is
(vdmbake.bundle.staging): the runs go to its staging folder, each starting from a hard-linked copy of its previous
folder (so its cached references are found), and the previous OUTDIR stays as it was until the swap."""
from __future__ import annotations

import dataclasses
import os
import shutil
import time
from pathlib import Path

from vdmbake import __version__
from vdmbake.bundle.staging import StagedDir
from vdmbake.errors import InputError, paragraph

from . import baseline, html, report
from .markdown import cell
from .render import run


def bundles(args) -> tuple[list[Path], bool]:
    """The bundles the arguments name, without repeats, and whether they ask for many: more than one argument, or a
    folder that is not itself a bundle (its sub-folders that are, sorted)."""
    out, many = [], len(args) > 1
    for a in map(Path, args):
        if a.is_dir() and not (a / "manifest.json").is_file():
            found, many = sorted(p for p in a.iterdir() if (p / "manifest.json").is_file()), True
            if not found:
                raise InputError(f"{a}: not a bundle (no manifest.json), nor a folder holding bundles; make them "
                                 "with vdmbake.")
        else:
            found = [a]
        out += [b for b in found if b not in out]
    stems = [b.name.removesuffix(".bundle") for b in out]
    twice = sorted({s for s in stems if stems.count(s) > 1})
    if twice:
        raise InputError(f"several bundles are named {twice[0]!r} (without .bundle); their renders would share "
                         "one folder: rename one, or render them with separate -o folders.")
    return out, many


def run_many(paths: list[Path], out: Path, opts, log=lambda m: None) -> dict:
    """Every bundle into OUT/<name>/, then the combined report (with opts.baseline, its comparison)."""
    if (out / "manifest.json").is_file():
        raise InputError(f"{out}: is a bundle; -o names the folder the renders go to.")
    old = baseline.load(opts.baseline) if opts.baseline else None
    staged = StagedDir(out, "runs.md", "vdmrender output folder of many bundles")
    try:
        combined = _render_each(paths, staged, opts, old, log)
        staged.commit()
    except BaseException:
        staged.abort()
        raise
    return combined


def _render_each(paths: list[Path], staged: StagedDir, opts, old, log) -> dict:
    each = dataclasses.replace(opts, baseline=None, max_error_increase=None, max_slowdown=None)
    runs, rows, devices, filterings = [], [], [], []
    for k, path in enumerate(paths, 1):
        scene = path.name.removesuffix(".bundle")
        log(f"[{k}/{len(paths)}] {path} -> {staged.path / scene}")
        if staged.previous(scene).is_dir():   # its cached references, without touching the folder in place
            shutil.copytree(staged.previous(scene), staged.tmp / scene, symlinks=True, copy_function=os.link)
        t0 = time.perf_counter()
        try:
            result = run(path, staged.tmp / scene, each, log)
        except Exception as e:   # a GL, library or OS error of one bundle too: the others still render
            why = paragraph(str(e) if isinstance(e, InputError) else f"{type(e).__name__}: {e}")
            runs.append({"scene": scene, "bundle": str(path), "status": "failed", "rows": 0,
                         "seconds": round(time.perf_counter() - t0, 2), "reason": why})
            log(f"{scene}: failed: {why}")
            shutil.rmtree(staged.tmp / scene, ignore_errors=True)   # no folder of a failed run
            continue
        filterings.append(result["filtering"])
        mine = [{**r, "scene": scene, "object": f"{scene}/{r['object']}"} for r in result["rows"]]
        rows += mine
        devices.append(result["device"])
        runs.append({"scene": scene, "bundle": str(path), "status": "rendered", "rows": len(mine),
                     "seconds": round(time.perf_counter() - t0, 2), "reason": "", "resolution": result["resolution"]})
    combined = {"tool_version": __version__, "device": devices[0] if devices else None, "time": "gpu",
                "resolution": runs_resolution(runs), "runs": runs, "rows": rows,
                "how": __doc__.split("\n\n")[0].replace("\n", " ")}
    if filterings and all(f == filterings[0] for f in filterings):   # what every run's errors are against
        combined["filtering"] = filterings[0]
    if old is not None:
        combined["baseline"] = {"report": str(opts.baseline),
                                **baseline.compare(old, combined, opts.max_error_increase, opts.max_slowdown,
                                                   opts.compare_devices)}
    combined = report.finite(combined)
    report.write(staged.tmp, combined)
    (staged.tmp / "runs.md").write_text(table(runs))
    html.write(staged.tmp, combined)
    return combined


def runs_resolution(runs) -> list:
    """The first rendered run's frame size (each run's own is in `runs`)."""
    return next((r["resolution"] for r in runs if r["status"] == "rendered"), [0, 0])


def table(runs) -> str:
    lines = ["| scene | status | rows | seconds | reason |", "|---|---|---:|---:|---|"]
    lines += [f"| {cell(r['scene'])} | {cell(r['status'])} | {r['rows']} | {r['seconds']:.1f} | {cell(r['reason'])} |"
              for r in runs]
    return "\n".join(lines) + "\n"
