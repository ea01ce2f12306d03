"""Signals as shells expect them: SIGINT, SIGTERM and SIGHUP stop the tool with exit 128 + N (130, 143,
129) after the staging folder is removed, never 0 (done) or 1 (a threshold exceeded).

The handlers raise an exception (KeyboardInterrupt for SIGINT, Interrupted for the others), so the
cleanup written for errors (`except BaseException: abort()`) runs. Some libraries swallow it (trimesh's
optional imports catch BaseException); the signal is therefore also recorded, and `check()`, called
before an output is committed and when the command returns, raises it again.

Once the interpreter exits, the command's outcome is decided (its output committed or removed, its exit code
chosen): the signals are then ignored (`_ignored_while_exiting`). Python's finalisation would otherwise put
back their default action before its C-level teardown (about 0.2 s with llvmpipe loaded), where SIGTERM would kill
a finished render: its output complete, its exit status that of a run stopped before writing anything."""
from __future__ import annotations

import atexit
import signal
import threading

HANDLED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
received: int | None = None


class Interrupted(BaseException):
    """A signal asked the tool to stop (BaseException: no `except Exception` catches it)."""

    def __init__(self, signum: int):
        super().__init__(f"interrupted by {signal.Signals(signum).name}")
        self.signum = signum


def _handler(signum, frame):
    global received
    received = received or signum
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Interrupted(signum)


def install() -> None:
    """Handle SIGINT, SIGTERM and SIGHUP (a command-line entry point calls this first)."""
    global received
    received = None
    if threading.current_thread() is not threading.main_thread():
        return                                            # only the main thread may set handlers
    for s in HANDLED:
        if signal.getsignal(s) is not signal.SIG_IGN:     # nohup's ignored SIGHUP stays ignored
            signal.signal(s, _handler)


@atexit.register
def _ignored_while_exiting() -> None:
    for s in HANDLED:
        if signal.getsignal(s) is _handler:              # installed by this process's command, in its main thread
            signal.signal(s, signal.SIG_IGN)


def check() -> None:
    """Raise again a signal that was received (and perhaps swallowed) since install()."""
    if received is not None:
        raise Interrupted(received)


def exit_code(e: BaseException) -> int:
    """128 + the signal's number for KeyboardInterrupt (SIGINT) and Interrupted."""
    return 128 + (e.signum if isinstance(e, Interrupted) else received or signal.SIGINT)
