"""The plumbing of the processes ``shiptrial plan`` forks to draw its figures (:mod:`cli.drawer`): a
forked child's guarded life (:func:`run_child`: its work, then ``os._exit`` with the error worded for the
parent through a pipe), its end when cancelled (:func:`end_child`: SIGTERM, which :func:`on_sigterm` turns into
an unwinding :class:`Cancelled`; SIGKILL after a grace) and its reaping (:func:`reap_child`), and the writers
run in order with their errors named by file (:func:`run_jobs`). No drawing here."""

from __future__ import annotations

import os
import select
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any


def run_jobs(jobs: list[tuple[Path, str, Callable[[], object]]]) -> None:
    for path, what, job in jobs:
        try:
            job()
        except Failed:  # a nested writer's, worded already
            raise
        except OSError as exc:  # a full disk, no permission: the OS's reason, not a traceback's wording
            raise Failed(f"{path.name}: writing {what} failed: {exc.strerror or exc}; nothing was written") from exc
        except BaseException as exc:  # noqa: BLE001 - everything goes back to the parent, naming the file
            raise Failed(f"{path.name}: writing {what} failed: {type(exc).__name__}: {exc}") from exc


class Failed(Exception):
    """A writer's error, already worded for the parent."""


class Cancelled(BaseException):
    """Raised in the drawer by SIGTERM (the parent cancelled it). It unwinds rather than dies:
    ``finally`` blocks and context managers run on the way out, so a drawer ended while importing
    matplotlib on a machine without its font cache removes the cache's lock file (killed, it left
    the lock behind and every later import waited 5 s for it, then did without the cache; the
    half-written cache is rebuilt by the next import). A BaseException: no ``except Exception``
    of a writer or library swallows it."""


def on_sigterm(signum: int, frame: Any) -> None:
    raise Cancelled


def run_child(report: int, work: Callable[[], None]) -> None:
    """Run ``work`` in a forked child and exit (never return): status 0, or 1 with the error
    written to the ``report`` pipe."""
    code = 1
    try:
        # never write to a stream another thread of the parent may hold a lock on; the old streams
        # are never flushed here (os._exit): what they buffered is the parent's to write
        sys.stdout = sys.stderr = open(os.devnull, "w")
        work()
        code = 0
    except Cancelled:  # the parent asked for it and reads no report
        pass
    except BaseException as exc:  # noqa: BLE001 - everything goes back to the parent
        from maps.export import ExportError

        worded = isinstance(exc, (Failed, ExportError))  # ExportError: a grandchild's (beside), already worded
        msg = str(exc) if worded else f"drawing the figures failed: {type(exc).__name__}: {exc}"
        try:
            os.write(report, msg.encode(errors="replace")[:4000])
        except OSError:
            pass
    finally:
        os._exit(code)


def end_child(pid: int, report: int, grace_s: float = 5.0) -> None:
    """End the unreaped child ``pid`` whose ``report`` pipe is still open: SIGTERM, and SIGKILL
    when it has not exited within ``grace_s`` (a Python handler runs only between bytecodes: a
    child stuck in C code, e.g. on a lock another thread of the parent held when it forked, never
    runs it). The pid cannot be reused before it is reaped, so the second signal is safe. 5 s, not
    1 s: on a loaded machine a child that unwinds at once may not be scheduled within a second, and
    killed it leaves matplotlib's lock file behind (seen twice in full-suite runs at load 15-20);
    the wait is paid only by a child that does not exit."""
    try:
        os.kill(pid, signal.SIGTERM)
        if not select.select([report], [], [], grace_s)[0]:  # readable at its exit: the pipe's end closes
            os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def reap_child(pid: int, report: int) -> str | None:
    """Wait for child ``pid``: None when it succeeded, else its error message ('' if none)."""
    with os.fdopen(report, "rb") as fh:
        msg = fh.read().decode(errors="replace")
    _, status = os.waitpid(pid, 0)
    return None if os.waitstatus_to_exitcode(status) == 0 else msg
