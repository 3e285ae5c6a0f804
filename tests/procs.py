"""Process helpers shared by the tests of forked work (Linux /proc)."""

from __future__ import annotations

import os


def children() -> set[int]:
    """Live (or unreaped) child processes of this process."""
    kids: set[int] = set()
    for task in os.listdir("/proc/self/task"):
        with open(f"/proc/self/task/{task}/children") as fh:
            kids.update(int(p) for p in fh.read().split())
    return kids
