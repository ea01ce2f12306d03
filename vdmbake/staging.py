"""Folders written atomically: work goes to a hidden temporary sibling that replaces the target
only when complete. Used for bundles (manifest last) and for vdmrender's output folders; the
previous folder stays readable until the swap, so its contents (cached references) can be reused."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

from .errors import InputError


class StagedDir:
    def __init__(self, path: Path, marker: str, what: str):
        """`marker` is the file that identifies a folder this tool may replace; `what` names it in errors."""
        self.path = Path(path)
        if self.path.exists() and (not self.path.is_dir() or (
                not (self.path / marker).is_file() and any(self.path.iterdir()))):
            raise InputError(f"{self.path}: exists and is not a {what} (no {marker}); refusing to replace it. "
                             "Choose another -o path or remove it.")
        if self.path.parent.exists() and not self.path.parent.is_dir():
            raise InputError(f"{self.path}: cannot write the {what} there ({self.path.parent} is not a directory).")
        self.tmp = self.path.parent / f".{self.path.name}.tmp-{os.getpid()}"
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            shutil.rmtree(self.tmp, ignore_errors=True)
            self.tmp.mkdir()
        except OSError as e:
            raise InputError(f"{self.path}: cannot write the {what} there ({e.strerror or e}).") from None

    def file(self, rel: str) -> Path:
        """A path to write, inside the staging folder (parents created)."""
        p = self.tmp / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def previous(self, rel: str) -> Path:
        """The same path in the folder being replaced (may not exist)."""
        return self.path / rel

    def commit(self) -> None:
        old = self.path.parent / f".{self.path.name}.old-{os.getpid()}"
        if self.path.exists():
            self.path.rename(old)
        self.tmp.rename(self.path)
        shutil.rmtree(old, ignore_errors=True)

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)
