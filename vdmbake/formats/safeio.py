"""Reading input files without trusting them: regular files only (a FIFO or device would block or never
end), the size checked before a byte is read, and the bytes read once so that what is checked is what
is parsed."""
from __future__ import annotations

import os
import stat
from pathlib import Path

from ..errors import InputError, escaped


def read_regular(path: Path, what: str, size: int | None = None, limit: int | None = None,
                 follow: bool = True) -> bytes:
    """The bytes of the regular file at `path`; `size`: the exact size expected; `limit`: the most
    accepted; `follow=False`: a symbolic link at `path` is refused too. Raises InputError naming `path`
    and `what` it is; FileNotFoundError passes through."""
    shown = escaped(str(path))
    if "\x00" in str(path):   # no file system has such a name (os.open would raise ValueError)
        raise InputError(f"{shown}: a path with a NUL character names no file; refusing the {what}.")
    try:
        # O_NONBLOCK: opening a FIFO for reading returns at once instead of waiting for a writer.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | (0 if follow else os.O_NOFOLLOW))
    except FileNotFoundError:
        raise
    except OSError as e:
        raise InputError(f"{shown}: cannot read the {what} ({e.strerror or e}).") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):   # before fdopen, which refuses a directory with an error of its own
        os.close(fd)
        raise InputError(f"{shown}: the {what} is not a regular file (a FIFO, device or directory); refusing "
                         "to read it.")
    with os.fdopen(fd, "rb") as f:
        if size is not None and st.st_size != size:
            raise InputError(f"{shown}: the {what} has {st.st_size} bytes where the manifest records {size} (the "
                             "bundle is damaged or being rewritten); re-bake with vdmbake --force.")
        if limit is not None and st.st_size > limit:
            raise InputError(f"{shown}: the {what} has {st.st_size} bytes, more than the {limit} accepted.")
        try:
            data = f.read(st.st_size + 1)       # one byte more: a file still growing is noticed
        except OSError as e:
            raise InputError(f"{shown}: cannot read the {what} ({e.strerror or e}).") from None
    if len(data) != st.st_size:
        raise InputError(f"{shown}: the {what} changed size while it was read; try again.")
    return data
