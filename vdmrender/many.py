"""Many bundles per call (`vdmrender BUNDLE... -o OUTDIR`, issue 24): each bundle rendered as alone into
OUTDIR/<bundle name without .bundle>/ (its own atomic output folder and reference cache), one after another on the
one GL device or each on a worker of a Dask cluster with its own (--scheduler, vdmrender.cluster); a bundle that fails is a row of the closing table and never stops the others. OUTDIR/report.json
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
from vdmbake.bundle import staging
from vdmbake.bundle.staging import StagedDir
from vdmbake.errors import InputError, paragraph
from vdmbake.cluster import handed_back

from .common import markdown
from .common.markdown import cell
from .deciding import baseline
from .render import run
from .reporting import html, report


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


def run_many(paths: list[Path], out: Path, opts, log=lambda m: None, on=None) -> dict:
    """Every bundle into OUT/<name>/, then the combined report (with opts.baseline, its comparison). `on(jobs,
    staged)`: the runs of `jobs` elsewhere (vdmrender.cluster), with why they stopped early; here by default."""
    if (out / "manifest.json").is_file():
        raise InputError(f"{out}: is a bundle; -o names the folder the renders go to.")
    old = baseline.load(opts.baseline) if opts.baseline else None
    staged = StagedDir(out, "runs.md", "vdmrender output folder of many bundles")
    try:
        each = dataclasses.replace(opts, baseline=None, max_error_increase=None, max_slowdown=None)
        jobs = [Job(str(path), str(staged.tmp / name(path)), str(staged.previous(name(path))), each) for path in paths]
        if on is None:
            done, stopped = [], None
            for k, job in enumerate(jobs, 1):
                log(f"[{k}/{len(jobs)}] {job.bundle} -> {staged.path / name(Path(job.bundle))}")
                done.append(render_one(job, log))
        else:
            done, stopped = on(jobs, staged)
        for job in jobs:            # whatever a killed or runaway writer left beside a run's folder
            staging.clear(Path(job.out))
        combined = _combine(done, staged, opts, old)
        if stopped:
            combined["stopped"] = stopped
        staged.commit()
    except BaseException:
        staged.abort()
        raise
    return combined


def name(path: Path) -> str:
    """A bundle's run folder's name: the bundle's without .bundle."""
    return Path(path).name.removesuffix(".bundle")


@dataclasses.dataclass(frozen=True)
class Job:
    bundle: str        # the bundle to render
    out: str           # its run's folder (inside OUT's staging folder)
    previous: str      # the same folder in the OUT being replaced: its cached references
    opts: object       # vdmrender.render.Options, without the comparison with a baseline (done on the combined)


def render_one(job: Job, log=None) -> dict:
    """One bundle into job.out as alone, starting from a hard-linked copy of its previous folder (its cached
    references): {"run": its runs.md entry, "rows": its report rows as combined, "device", "filtering"}. Never
    raises for the bundle's own failure (a GL, library or OS error too: the others still render); its entry says
    `failed` and why, and it leaves no folder."""
    scene, out, lines = name(Path(job.bundle)), Path(job.out), []
    shutil.rmtree(out, ignore_errors=True)          # a run killed before (on a cluster, this task's first try)
    if Path(job.previous).is_dir():                 # its cached references, without touching the folder in place
        shutil.copytree(job.previous, out, symlinks=True, copy_function=os.link)
    t0 = time.perf_counter()
    try:
        result = run(Path(job.bundle), out, job.opts, log or lines.append)
    except Exception as e:
        why = paragraph(str(e) if isinstance(e, InputError) else f"{type(e).__name__}: {e}")
        (log or lines.append)(f"{scene}: failed: {why}")
        shutil.rmtree(out, ignore_errors=True)      # no folder of a failed run
        return {"run": {"scene": scene, "bundle": job.bundle, "status": "failed", "rows": 0,
                        "seconds": round(time.perf_counter() - t0, 2), "reason": why}, "rows": [], "log": lines[-20:]}
    rows = [{**r, "scene": scene, "object": f"{scene}/{r['object']}"} for r in result["rows"]]
    return {"run": {"scene": scene, "bundle": job.bundle, "status": "rendered", "rows": len(rows),
                    "seconds": round(time.perf_counter() - t0, 2), "reason": "", "resolution": result["resolution"],
                    "device": result["device"]},
            "rows": rows, "device": result["device"], "filtering": result["filtering"]}


def _combine(done: list[dict], staged: StagedDir, opts, old) -> dict:
    """The combined report of the runs `done` (render_one's, in the bundles' order), written into OUT's staging
    folder with runs.md and the page."""
    runs = [d["run"] for d in done]
    rows = [r for d in done for r in d["rows"]]
    filterings = [d["filtering"] for d in done if "filtering" in d]
    combined = {"tool_version": __version__, "device": device([d["device"] for d in done if "device" in d]), "time": "gpu",
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


def device(devices: list[str]) -> str | None:
    """The combined report's device: the runs' one, or, for runs on several (a cluster's workers), every one named,
    so that --baseline compares no times across devices unless --compare-devices
    (vdmrender.deciding.baseline.times_comparable)."""
    devices = list(dict.fromkeys(devices))
    return devices[0] if len(devices) == 1 else f"several devices: {'; '.join(devices)}" if devices else None


def runs_resolution(runs) -> list:
    """The first rendered run's frame size (each run's own is in `runs`)."""
    return next((r["resolution"] for r in runs if r["status"] == "rendered"), [0, 0])


def table(runs) -> str:
    """runs.md, and the closing table on stderr; on a cluster (vdmrender.cluster) with the worker each ran on,
    and those that handed it back."""
    where = any("worker" in r or "handed_back" in r for r in runs)
    return markdown.table(["scene", "status", "rows", "seconds", *(["worker"] * where), "reason"],
                          "llrr" + "l" * where + "l",
                          [[cell(r["scene"]), cell(r["status"]), str(r["rows"]), f"{r['seconds']:.1f}",
                            *([cell(r.get("worker") or "")] * where), cell(r["reason"] or handed_back(r))]
                           for r in runs]) + "\n"
