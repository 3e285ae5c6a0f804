"""Process helpers shared by the tests of forked work (Linux /proc)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys


def children() -> set[int]:
    """Live (or unreaped) child processes of this process."""
    kids: set[int] = set()
    for task in os.listdir("/proc/self/task"):
        with open(f"/proc/self/task/{task}/children") as fh:
            kids.update(int(p) for p in fh.read().split())
    return kids


_KILLED = """
import os, signal, sys
import {module} as mod
out, mode = sys.argv[1], sys.argv[2]
if mode == "{swap_mode}":  # killed between moving the previous file aside and moving the new one in
    real = os.replace
    def replace(src, dst):
        real(src, dst)
        os.kill(os.getpid(), signal.SIGKILL)
    mod.os.replace = replace
with mod.{context}(out) as tmp:
    (tmp / "{file_name}").write_text({text})
    if mode == "writing":
        os.kill(os.getpid(), signal.SIGKILL)
    if mode == "running":  # a run still writing into this destination
        print("ready", flush=True)
        sys.stdin.read()
"""


def killable_writer(
    module: str, context: str, file_name: str, swap_mode: str, out, mode: str, text: str = "mode", **kw
) -> subprocess.Popen:
    """A child process writing ``file_name`` through ``module.context(out)``: SIGKILLed while
    writing (``mode`` "writing"), mid-swap (``mode`` == ``swap_mode``), or left running until its
    stdin closes ("running", after printing "ready"). ``text`` is the Python expression written."""
    script = _KILLED.format(module=module, context=context, file_name=file_name, swap_mode=swap_mode, text=text)
    return subprocess.Popen([sys.executable, "-c", script, str(out), mode], text=True, **kw)


class Hung(Exception):
    """Raised by :func:`deadline` when its time is up."""


@contextlib.contextmanager
def deadline(seconds: int):
    """A pool map that hangs raises :class:`Hung` after ``seconds`` (its workers killed by the pool) instead of holding
    the suite (SIGALRM: the main thread only)."""

    def hung(*_):
        raise Hung

    old = signal.signal(signal.SIGALRM, hung)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
