"""Folders written atomically: work goes to a hidden temporary sibling that replaces the target
only when complete. Used for bundles (manifest last) and for vdmrender's output folders; the
previous folder stays readable until the swap, so its contents (cached references) can be reused.

The swap exchanges the two folders in one step where the system can (Linux renameat2
RENAME_EXCHANGE), so a valid folder is at the target at every instant and concurrent writers end
with one of their folders there; elsewhere it is two renames, and a run that finds the target
missing restores it from what an interrupted swap left.

Hidden siblings are named after their writer, `.NAME.tmp-HOST-PID` and `.NAME.old-HOST-PID`, so writers
on several machines sharing one folder never pick the same name, and each holds a lease, the file
`.NAME.lease-HOST-PID` that it touches every LEASE_BEAT_S while it works. The next run at the same target
removes a sibling whose writer is gone: on its own machine (the same host name, boot and PID namespace,
which the lease records) when that process no longer runs; of another machine only when the lease has
not been touched for LEASE_STALE_S, measured by the shared file system's own clock, since another
machine's processes cannot be asked. A sibling of the old form `.NAME.tmp-PID` is judged as this
machine's. The host name is socket.gethostname(); VDM_TEST_HOSTNAME replaces it, for tests that play
two machines on one (tests/test_staging_hosts.py)."""
from __future__ import annotations

import ctypes
import errno
import functools
import json
import os
import re
import shutil
import socket
import threading
import time
from pathlib import Path

from .. import signals
from ..errors import InputError

LEASE_BEAT_S = 10.0       # a writer touches its lease this often
LEASE_STALE_S = 600.0     # another machine's sibling is removed after its lease went untouched this long


def host() -> str:
    """This machine's name as sibling names carry it (characters other than letters, digits, '.', '_' and
    '-' replaced)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", os.environ.get("VDM_TEST_HOSTNAME") or socket.gethostname()) or "host"


def _identity() -> dict:
    """What makes a PID meaningful: the host, its boot and the PID namespace (containers on one host share
    its name but not their PIDs)."""
    def read(path):
        try:
            return os.readlink(path) if path.startswith("/proc/self/ns") else Path(path).read_text().strip()
        except OSError:
            return None
    return {"host": host(), "boot": read("/proc/sys/kernel/random/boot_id"), "pidns": read("/proc/self/ns/pid")}


def alive(pid: int) -> bool:
    """Whether process `pid` runs (another user's counts; a zombie, dead but not yet reaped by its parent, does not:
    a killed worker's staging folder is debris before its parent waits for it)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:       # another user's process
        return True
    try:   # the state follows the command's closing parenthesis (the command may hold spaces and parentheses)
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0] != "Z"
    except (OSError, IndexError):
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


def sibling(path: Path, kind: str, pid: int | None = None, on: str | None = None) -> Path:
    """The hidden sibling of `path` of a writer (this process by default): where it stages the new folder
    (`tmp`), where the swap moves the previous one (`old`), its lease (`lease`)."""
    path = Path(path)
    return path.parent / f".{path.name}.{kind}-{on or host()}-{pid or os.getpid()}"


def target(folder: Path) -> Path:
    """The folder a staging sibling (`.NAME.tmp-HOST-PID`) becomes; any other folder is its own."""
    m = re.fullmatch(r"\.(.+)\.tmp-(?:.+-)?\d+", Path(folder).name)
    return Path(folder).parent / m[1] if m else Path(folder)


def _siblings(path: Path) -> list[tuple[str, str | None, int, Path]]:
    """(tmp, old or lease; the writer's host, None in the old form; its pid; the path) of the hidden siblings at
    this target."""
    pattern = re.compile(rf"\.{re.escape(path.name)}\.(tmp|old|lease)-(?:(.+)-)?(\d+)")
    if not path.parent.is_dir():
        return []
    return [(m[1], m[2], int(m[3]), p) for p in path.parent.iterdir() if (m := pattern.fullmatch(p.name))]


# ------------------------------------------------------------------------------------------------ leases

_held: set[Path] = set()
_beating: threading.Thread | None = None
_lock = threading.Lock()


def _beat() -> None:
    while True:
        time.sleep(LEASE_BEAT_S)
        for lease in list(_held):
            try:
                os.utime(lease)
            except OSError:
                pass                # gone (released meanwhile) or the share away for a moment: the next beat


def hold(path: Path) -> Path:
    """Take this process's lease at target `path`: the file, touched every LEASE_BEAT_S until release()."""
    global _beating
    lease = sibling(path, "lease")
    lease.write_text(json.dumps({**_identity(), "pid": os.getpid()}))
    with _lock:
        _held.add(lease)
        if _beating is None or not _beating.is_alive():
            _beating = threading.Thread(target=_beat, name="vdm-lease", daemon=True)
            _beating.start()
    return lease


def release(lease: Path) -> None:
    with _lock:
        _held.discard(lease)
    try:
        lease.unlink()
    except OSError:
        pass


def _fs_now(folder: Path) -> float:
    """The shared file system's clock (the mtime of a file written there now), so that leases are aged by
    the clock that stamped them, whatever this machine's clock says; this machine's where it cannot write."""
    probe = folder / f".vdm-clock-{host()}-{os.getpid()}-{threading.get_ident()}"
    try:
        probe.write_bytes(b"")
        try:
            return probe.stat().st_mtime
        finally:
            probe.unlink()
    except OSError:
        return time.time()


def _gone(path: Path, on: str | None, pid: int, p: Path, mine: dict, now) -> str | None:
    """Why the writer of sibling `p` (host `on`, process `pid`) is gone, or None while it may still work."""
    lease = sibling(path, "lease", pid, on) if on else None
    try:
        held = json.loads(lease.read_text()) if lease else {}
    except (OSError, ValueError):
        held = {}
    same = [held.get(k) in (None, mine[k]) for k in ("boot", "pidns")]
    if on is None or (on == mine["host"] and all(same)):        # this machine's: ask it
        return None if pid == os.getpid() or alive(pid) else f"process {pid} no longer runs"
    try:
        touched = (lease if lease.exists() else p).stat().st_mtime
    except OSError:
        return None                                                 # removed meanwhile by its writer
    age = now() - touched
    return (f"process {pid} on {on} has not touched its lease for {age:.0f} s" if age > LEASE_STALE_S else None)


def recover(path: Path, marker: str) -> list[tuple[str, str, int, str, str]]:
    """Hidden siblings at `path` whose writer is gone: a target lost between the two renames of a swap comes
    back (the complete new folder if there is one, else the old one); the rest is removed, leases too. Returns
    what it did, per folder: ("put back" or "removed", "tmp" or "old", the writer's pid, the sibling's name,
    why its writer is gone)."""
    path = Path(path)
    if path.name in ("", ".", ".."):
        return []
    mine = _identity()
    now = functools.cache(lambda: _fs_now(path.parent))    # once, and only if a sibling of another machine asks
    dead = [(k, pid, p, why) for k, on, pid, p in _siblings(path) if (why := _gone(path, on, pid, p, mine, now))]
    restored = None
    if not path.exists() and not path.is_symlink():
        complete = [p for k, _, p, _ in dead if k == "tmp" and (p / marker).is_file()]
        old = [p for k, _, p, _ in dead if k == "old" and (p / marker).is_file()]
        for p in complete + old:
            try:
                p.rename(path)
                restored = p
                break
            except OSError:
                pass
    for k, _, p, _ in dead:
        if k == "lease":
            try:
                p.unlink()
            except OSError:
                pass
        else:
            shutil.rmtree(p, ignore_errors=True)
    return [("put back" if p == restored else "removed", k, pid, p.name, why) for k, pid, p, why in dead
            if k != "lease" and (p == restored or not p.exists())]


def clear(path: Path) -> None:
    """Remove every hidden sibling at `path`, whoever wrote it and whether or not it still runs: for the owner
    of the folder they are in (its own staging folder), once every writer it started there has finished."""
    for _, _, _, p in _siblings(Path(path)):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)


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
        self.tmp, self.lease = sibling(self.path, "tmp"), None
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.lease = hold(self.path)          # first: no staging folder of a live writer without its lease
            shutil.rmtree(self.tmp, ignore_errors=True)
            self.tmp.mkdir()
        except OSError as e:
            self._release()
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
        old = sibling(self.path, "old")
        moved = False
        try:
            if self.path.exists() and exchange(self.tmp, self.path):
                shutil.rmtree(self.tmp, ignore_errors=True)     # now the previous folder
                self._release()
                return
            if self.path.exists():
                self.path.rename(old)
                moved = True
            self.tmp.rename(self.path)
            shutil.rmtree(old, ignore_errors=True)
            self._release()
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
        self._release()

    def _release(self) -> None:
        if self.lease is not None:
            release(self.lease)
            self.lease = None
