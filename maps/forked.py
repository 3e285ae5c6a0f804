"""Half of a list of independent computations in a forked child (Linux), the other half here.

For CPU-bound work of the planner that no outer process runs beside it (``plan-trial``'s drawer
is otherwise idle, or importing, while the parent plans). The results are those of computing
every item here: the child runs the same function on the same data (a forked copy), and when
the child fails, or cannot be started, the items are computed here.
"""

from __future__ import annotations

import gc
import os
import pickle
import sys
import threading
from collections.abc import Callable, Sequence
from typing import Any

CAN_FORK = sys.platform.startswith("linux")


def map_halves(fn: Callable[[Any], Any], items: Sequence[Any], min_items: int = 8) -> list[Any]:
    """``[fn(x) for x in items]``, the odd-indexed items computed in a forked child.

    Not forked with fewer than ``min_items`` items, on platforms without fork, or in a process
    running other threads (a forked copy of a lock another thread holds would never be released).
    """
    n = len(items)
    if not CAN_FORK or n < min_items or threading.active_count() > 1:
        return [fn(x) for x in items]
    read, write = os.pipe()
    try:
        pid = os.fork()
    except OSError:
        os.close(read)
        os.close(write)
        return [fn(x) for x in items]
    if pid == 0:  # the child: never returns, whatever is raised (a Ctrl-C reaches it too)
        code = 1
        try:
            os.close(read)
            # the parent's objects out of the collector's sight: a collection would write to every
            # object's header and so copy the whole shared heap page by page
            gc.freeze()
            data = pickle.dumps([fn(items[i]) for i in range(1, n, 2)], protocol=pickle.HIGHEST_PROTOCOL)
            with os.fdopen(write, "wb") as fh:
                fh.write(data)
            code = 0
        except BaseException:  # noqa: BLE001 - the parent computes these items itself
            pass
        finally:
            os._exit(code)
    os.close(write)
    out: list[Any] = [None] * n
    try:
        for i in range(0, n, 2):
            out[i] = fn(items[i])
    finally:
        with os.fdopen(read, "rb") as fh:  # read to the end before reaping: the child may block on a full pipe
            data = fh.read()
        _, status = os.waitpid(pid, 0)
    odd = None
    if os.waitstatus_to_exitcode(status) == 0:
        try:
            odd = pickle.loads(data)
        except Exception:  # noqa: BLE001 - computed here instead
            odd = None
    for k, i in enumerate(range(1, n, 2)):
        out[i] = odd[k] if odd is not None and len(odd) == len(range(1, n, 2)) else fn(items[i])
    return out
