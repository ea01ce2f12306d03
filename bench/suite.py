"""What the test suite costs: `make test`'s command (or the suite of another commit, `--at`) run once, its CPU
seconds (user + sys of every process it started, as the kernel counts reaped children), wall time and outcome, and
each test's own CPU seconds (bench/suite_costs.py), summed by file, by the `slow` marker, and over the tests another
commit had (`--ids-of`: the same tests then and now, whatever was added since). Writes OUT/suite.json and
OUT/suite.md; `--publish docs/results` writes docs/results/NAME.json for make docs (docs/testing.md).

CPU seconds are the figure to compare between runs: wall time moves with the other sessions' load on a shared
machine (the provenance gives the load average), CPU time much less."""
from __future__ import annotations

import collections
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import click

from bench import publish, tables

ROOT = Path(__file__).resolve().parents[1]
OUTCOMES = ("passed", "failed", "skipped", "xfailed", "xpassed", "errors")


def pytest_command(workers: str, args: tuple[str, ...]) -> list[str]:
    """`make test`'s pytest command (the Makefile's test target) with `workers` xdist workers; "0": one process."""
    spread = [] if workers == "0" else ["-n", workers, "--maxprocesses", "8", "--dist", "loadfile",
                                        "--no-loadscope-reorder"]
    return [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *spread, *args]


@contextmanager
def checkout(commit: str | None):
    """The repository as it was at `commit` (a temporary git worktree, removed after), or this one."""
    if commit is None:
        yield ROOT
        return
    with tempfile.TemporaryDirectory(prefix="vdm-suite-") as tmp:
        tree = Path(tmp) / "tree"
        subprocess.run(["git", "worktree", "add", "--detach", "-q", str(tree), commit], cwd=ROOT, check=True)
        try:
            yield tree
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=ROOT, check=True)


def _env(tree: Path, plugin_dir: Path | None = None) -> dict:
    """The environment a suite runs in: `tree`'s packages first on the path (before the editable install of this
    checkout), and the cost plugin where pytest finds it."""
    path = [str(tree)] + ([str(plugin_dir)] if plugin_dir else []) + [os.environ.get("PYTHONPATH", "")]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in path if p)}


def collected_ids(commit: str, args: tuple[str, ...]) -> list[str]:
    """The test ids the suite at `commit` collects (restricted to `args`' paths, as the run is)."""
    with checkout(commit) as tree:
        done = subprocess.run([sys.executable, "-m", "pytest", "-q", "--collect-only", "-p", "no:cacheprovider",
                               *args], cwd=tree, env=_env(tree), capture_output=True, text=True)
    ids = [line.strip() for line in done.stdout.splitlines() if "::" in line]
    if not ids:
        raise click.ClickException(f"the suite at {commit} collected nothing:\n{done.stdout[-2000:]}{done.stderr[-2000:]}")
    return ids


def outcome(text: str) -> dict:
    """pytest's summary line ("1378 passed, 2 skipped, 1 xfailed in 258.64s") as counts."""
    line = next((ln for ln in reversed(text.splitlines()) if re.search(r"\d+ (passed|failed)", ln)), "")
    counts = {k: 0 for k in OUTCOMES}
    for n, word in re.findall(r"(\d+) (passed|failed|skipped|xfailed|xpassed|errors?)\b", line):
        counts["errors" if word.startswith("error") else word] += int(n)
    return counts


def run_suite(commit: str | None, workers: str, args: tuple[str, ...]) -> tuple[dict, list[dict], str]:
    """The suite run once: its totals, each test's row (suite_costs), and pytest's output."""
    with checkout(commit) as tree, tempfile.TemporaryDirectory(prefix="vdm-costs-") as costs:
        plugins = Path(costs) / "plugin"
        plugins.mkdir()
        (plugins / "vdm_suite_costs.py").write_text((ROOT / "bench" / "suite_costs.py").read_text())
        rows_dir = Path(costs) / "rows"
        rows_dir.mkdir()
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=tree, capture_output=True, text=True).stdout.strip()
        before, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
        done = subprocess.run(pytest_command(workers, ("-p", "vdm_suite_costs", *args)), cwd=tree,
                              env={**_env(tree, plugins), "VDM_SUITE_COSTS": str(rows_dir)},
                              capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        rows = [json.loads(line) for f in sorted(rows_dir.glob("*.jsonl")) for line in f.read_text().splitlines()]
    user, sys_ = after.ru_utime - before.ru_utime, after.ru_stime - before.ru_stime
    totals = {"commit": head, "workers": workers, "exit_code": done.returncode,
              **outcome(done.stdout), "tests": len(rows), "cpu_s": round(user + sys_, 1), "user_s": round(user, 1),
              "sys_s": round(sys_, 1), "wall_s": round(wall, 1), "tests_cpu_s": round(sum(r["cpu_s"] for r in rows), 1),
              "slow_cpu_s": round(sum(r["cpu_s"] for r in rows if r["slow"]), 1),
              "slow_tests": sum(r["slow"] for r in rows),
              "failed_tests": sorted(r["id"] for r in rows if r["failed"])}
    return totals, rows, done.stdout + done.stderr


def by_file(rows: list[dict]) -> list[dict]:
    """Each test file's tests and CPU seconds (its slow tests' share), the costliest first."""
    files = collections.defaultdict(lambda: {"tests": 0, "cpu_s": 0.0, "slow_cpu_s": 0.0})
    for r in rows:
        f = files[r["id"].split("::")[0]]
        f["tests"] += 1
        f["cpu_s"] += r["cpu_s"]
        f["slow_cpu_s"] += r["cpu_s"] if r["slow"] else 0.0
    return sorted(({"file": k, "tests": v["tests"], "cpu_s": round(v["cpu_s"], 1),
                    "slow_cpu_s": round(v["slow_cpu_s"], 1)} for k, v in files.items()), key=lambda f: -f["cpu_s"])


def subset(rows: list[dict], commit: str, ids: list[str]) -> dict:
    """The tests `commit` had, in this run: how many are here, their CPU seconds now; the ones gone or renamed; and
    the tests added since, with theirs (by file)."""
    then, cost = set(ids), {r["id"]: r["cpu_s"] for r in rows}
    here = [i for i in ids if i in cost]
    added = [r for r in rows if r["id"] not in then]
    return {"commit": commit, "tests_then": len(ids), "here": len(here),
            "cpu_s": round(sum(cost[i] for i in here), 1), "gone": sorted(then - cost.keys()),
            "added": len(added), "added_cpu_s": round(sum(r["cpu_s"] for r in added), 1),
            "added_by_file": by_file(added)}


def _device() -> str:
    """The cores and the GL renderer the suite's GL tests draw with."""
    from vdmrender.gpu import gl

    ctx = gl.create_context()
    try:
        return f"{len(os.sched_getaffinity(0))} CPU cores, {gl.renderer_name(ctx)}"
    finally:
        ctx.release()


def _markdown(doc: dict) -> str:
    parts = [f"# The test suite's cost ({doc['device']})\n", tables.suite(doc)]
    if doc["subsets"]:
        parts.append(tables.suite_subsets(doc))
    parts += [tables.suite_files(doc), tables.suite_tests(doc)]
    return "\n".join(parts)


@click.command(context_settings={"ignore_unknown_options": True})
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"), show_default=True)
@click.option("--workers", default="auto", show_default=True,
              help="pytest-xdist workers, as `make test TEST_WORKERS=N`; 0 runs the suite in one process (as make test "
                   "did before pytest-xdist).")
@click.option("--at", "commit", metavar="COMMIT", default=None,
              help="Run the suite of COMMIT (a temporary git worktree of it, its code first on the path) instead of "
                   "this checkout's.")
@click.option("--ids-of", "ids_of", metavar="COMMIT", multiple=True,
              help="Also sum the CPU seconds of the tests COMMIT had (collected there): the same tests then and now, "
                   "apart from those added since. Repeatable.")
@click.option("--name", default="suite", show_default=True,
              help="The published file's name (DIR/NAME.json), e.g. suite-COMMIT for a run of --at COMMIT.")
@publish.option("NAME")
@click.argument("pytest_args", nargs=-1, type=click.UNPROCESSED)
def main(out: Path, workers: str, commit: str | None, ids_of: tuple[str, ...], name: str, publish_dir: Path | None,
         pytest_args: tuple[str, ...]):
    """Run the test suite once as `make test` runs it and write what it cost: OUT/suite.json and OUT/suite.md.
    PYTEST_ARGS after `--` restrict it (test files, -k, -m).

    \b
    Examples:
      python -m bench.suite --ids-of 62f9cd8 --publish docs/results
      python -m bench.suite --at 62f9cd8 --workers 0 --name suite-62f9cd8 --publish docs/results
      python -m bench.suite -o /tmp/suite --workers 0 -- tests/test_markdown.py
    """
    started = publish.Run("bench.suite")
    subsets = {c: collected_ids(c, pytest_args) for c in ids_of}
    click.echo(f"running the suite{f' of {commit}' if commit else ''} ({' '.join(pytest_command(workers, pytest_args)[1:])})",
               err=True)
    totals, rows, said = run_suite(commit, workers, pytest_args)
    click.echo(said.strip().splitlines()[-1] if said.strip() else "(pytest printed nothing)", err=True)
    doc = {"device": _device(), "run": totals, "subsets": [subset(rows, c, ids) for c, ids in subsets.items()],
           "files": by_file(rows), "tests": sorted(rows, key=lambda r: -r["cpu_s"])}
    out.mkdir(parents=True, exist_ok=True)
    (out / "suite.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "suite.md").write_text(_markdown(doc))
    (out / "pytest.log").write_text(said)   # what a failure said: the tables keep only that it failed
    click.echo(f"{totals['tests']} tests, {totals['cpu_s']} CPU s, {totals['wall_s']} s wall; wrote {out / 'suite.json'}, "
               f"{out / 'suite.md'}, {out / 'pytest.log'}")
    if publish_dir:
        click.echo(f"published {started.publish(publish_dir, name, doc)}")
    if totals["exit_code"]:                 # 1: tests failed (in the tables); 2: pytest did not run the suite
        raise SystemExit(1 if totals["exit_code"] == 1 else 2)


if __name__ == "__main__":
    main()
