"""The output folder, written atomically: everything goes to a hidden temporary sibling that
replaces OUTDIR only when the run has finished. The previous OUTDIR stays readable meanwhile,
so its cached reference frames can be reused."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

from vdmbake.errors import InputError

MARKER = "report.json"


class OutputDir:
    def __init__(self, path: Path):
        self.path = Path(path)
        if self.path.exists() and (not self.path.is_dir() or (
                any(self.path.iterdir()) and not (self.path / MARKER).is_file())):
            raise InputError(f"{self.path}: exists and is not a vdmrender output folder (no {MARKER}); "
                             "refusing to replace it. Choose another -o path or remove it.")
        self.tmp = self.path.parent / f".{self.path.name}.tmp-{os.getpid()}"
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            shutil.rmtree(self.tmp, ignore_errors=True)
            self.tmp.mkdir()
        except OSError as e:
            raise InputError(f"{self.path}: cannot write the output there ({e.strerror or e}).") from None

    def file(self, rel: str) -> Path:
        """A path to write, inside the staging folder (parents created)."""
        p = self.tmp / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def previous(self, rel: str) -> Path:
        """The same path in the previous run's output (may not exist)."""
        return self.path / rel

    def commit(self) -> None:
        old = self.path.parent / f".{self.path.name}.old-{os.getpid()}"
        if self.path.exists():
            self.path.rename(old)
        self.tmp.rename(self.path)
        shutil.rmtree(old, ignore_errors=True)

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)
