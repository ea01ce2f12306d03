"""A bench's result published as docs/results/NAME.json (`--publish DIR`), what tools/make_docs.py renders into
the docs: the bench's own JSON beside its provenance, so a figure in the docs names the run that made it.

Provenance: the exact command, the commit and whether the worktree had uncommitted changes, the date (UTC), the
device (the GL context's renderer string, as the report rows carry it), the load average (1, 5, 15 min) when the
run started and when it ended, and its wall time. On a shared machine the load says how far wall times are
inflated; CPU times and errors do not depend on it."""
from __future__ import annotations

import datetime
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

import click

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
FIELDS = ("command", "commit", "dirty", "date", "device", "load_start", "load_end", "wall_s")


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


class Run:
    """Started when bench `module` starts (its command line, commit, date, load); `publish` ends it."""

    def __init__(self, module: str):
        self.command = shlex.join(["python", "-m", module, *sys.argv[1:]])
        self.commit = _git("rev-parse", "HEAD")
        self.dirty = bool(_git("status", "--porcelain", "--untracked-files=no"))
        self.date = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
        self.load_start = _load()
        self.t0 = time.perf_counter()

    def provenance(self, device: str) -> dict:
        return {"command": self.command, "commit": self.commit, "dirty": self.dirty, "date": self.date,
                "device": device, "load_start": self.load_start, "load_end": _load(),
                "wall_s": round(time.perf_counter() - self.t0, 1)}

    def publish(self, folder: Path, name: str, doc: dict) -> Path:
        """`doc` (the bench's JSON, with its "device") written as FOLDER/NAME.json under its provenance."""
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{name}.json"
        path.write_text(json.dumps({"provenance": self.provenance(doc["device"]), **doc}, indent=1) + "\n")
        return path


def option(name: str):
    """The benches' `--publish DIR` click option (DIR/NAME.json; docs/results for make docs)."""
    return click.option("--publish", "publish_dir", type=click.Path(path_type=Path, file_okay=False), default=None,
                        help=f"Also write DIR/{name}.json: the JSON with its provenance (command, commit, date, "
                             f"device, load average, wall time); DIR = docs/results publishes it for make docs.")
