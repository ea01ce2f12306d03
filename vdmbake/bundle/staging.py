"""Folders written atomically: work goes to a hidden temporary sibling that replaces the target
only when complete. Used for bundles (manifest last) and for vdmrender's output folders; the
previous folder stays readable until the swap, so its contents (cached references) can be reused.

The swap exchanges the two folders in one step where the system can (Linux renameat2
RENAME_EXCHANGE), so a valid folder is at the target at every instant and concurrent writers end
with one of their folders there; elsewhere it is two renames, and a run that finds the target
missing restores it from what an interrupted swap left. Hidden siblings (`.NAME.tmp-PID`,
`.NAME.old-PID`) of processes that no longer run are removed by the next run at the same target."""
from __future__ import annotations

import ctypes
import errno
import os
import re
import shutil
from pathlib import Path

from .. import signals
from ..errors import InputError


def alive(pid: int) -> bool:
    """Whether process `pid` runs (another user's counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:       # another user's process
        return True
    return True


_libc = ctypes.CDLL(None, use_errno=True)
_RENAME_EXCHANGE, _AT_FDCWD = 2, -100


def exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically; False where the system or file system cannot."""
    fn = getattr(_libc, "renameat2", None)
    if fn is None:
        return False
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _siblings(path: Path) -> list[tuple[str, int, Path]]:
    """(tmp or old, pid, path) of the hidden siblings at this target."""
    pattern = re.compile(rf"\.{re.escape(path.name)}\.(tmp|old)-(\d+)")
    if not path.parent.is_dir():
        return []
    return [(m[1], int(m[2]), p) for p in path.parent.iterdir() if (m := pattern.fullmatch(p.name))]


def recover(path: Path, marker: str) -> list[tuple[str, str, int, str]]:
    """Hidden siblings of dead processes at `path`: a target lost between the two renames of a swap comes
    back (the complete new folder if there is one, else the old one); the rest is removed. Returns what it did,
    per sibling: ("put back" or "removed", "tmp" or "old", the dead process's pid, the sibling's name)."""
    path = Path(path)
    if path.name in ("", ".", ".."):
        return []
    dead = [(k, pid, p) for k, pid, p in _siblings(path) if pid != os.getpid() and not alive(pid)]
    restored = None
    if not path.exists() and not path.is_symlink():
        complete = [p for k, _, p in dead if k == "tmp" and (p / marker).is_file()]
        old = [p for k, _, p in dead if k == "old" and (p / marker).is_file()]
        for p in complete + old:
            try:
                p.rename(path)
                restored = p
                break
            except OSError:
                pass
    for _, _, p in dead:
        shutil.rmtree(p, ignore_errors=True)
    return [("put back" if p == restored else "removed", k, pid, p.name) for k, pid, p in dead
            if p == restored or not p.exists()]


class StagedDir:
    def __init__(self, path: Path, marker: str, what: str):
        """`marker` is the file that identifies a folder this tool may replace; `what` names it in errors."""
        self.path, self.marker, self.what = Path(path), marker, what
        if self.path.name in ("", ".", "..") or self.path.resolve() == Path(self.path.resolve().anchor):
            raise InputError(f"{path}: give the {what} a folder name of its own (e.g. out/NAME), not '.', '..' "
                             "or a root; the folder is replaced as a whole.")
        if self.path.is_symlink():
            raise InputError(f"{self.path}: is a symbolic link (to {os.readlink(self.path)}); the {what} replaces "
                             "the folder as a whole, so give the real path instead of the link.")
        if self.path.parent.exists() and not self.path.parent.is_dir():
            raise InputError(f"{self.path}: cannot write the {what} there ({self.path.parent} is not a directory).")
        recover(self.path, marker)
        if self.path.exists() and (not self.path.is_dir() or (
                not (self.path / marker).is_file() and any(self.path.iterdir()))):
            raise InputError(f"{self.path}: exists and is not a {what} (no {marker}); refusing to replace it. "
                             "Choose another -o path or remove it.")
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
        signals.check()          # a signal swallowed on the way (see vdmbake.signals) stops the commit
        old = self.path.parent / f".{self.path.name}.old-{os.getpid()}"
        moved = False
        try:
            if self.path.exists() and exchange(self.tmp, self.path):
                shutil.rmtree(self.tmp, ignore_errors=True)     # now the previous folder
                return
            if self.path.exists():
                self.path.rename(old)
                moved = True
            self.tmp.rename(self.path)
            shutil.rmtree(old, ignore_errors=True)
        except OSError as e:
            if moved:
                try:
                    old.rename(self.path)
                except OSError:
                    pass              # the next run restores it (recover)
            raise InputError(f"{self.path}: cannot put the {self.what} in place ({e.strerror or e}); another "
                             "process may be writing the same path, or the folder is not ours to replace "
                             "(read-only, or another user's in a sticky directory). Nothing was changed there.") from None

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)
