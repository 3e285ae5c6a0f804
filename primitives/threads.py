"""How many threads a process's own independent work runs on, and running it on them.

For work whose heavy parts are compiled loops that release the GIL (:mod:`primitives.jitloop`
compiles every loop ``nogil``): the inline Monte Carlo's chunks (:func:`expdesign.montecarlo.evaluate_designs`)
run two at a time on two cores. The count follows the setting the engines' workers set to one
(``OMP_NUM_THREADS``, :func:`expdesign.parallel.one_thread_per_worker`): a pool or Dask worker
process runs one task per core and starts no threads of its own.

No thread outlives the call that started it (:func:`map_in_threads`): a process with other
threads running does not fork (:func:`maps.forked.map_halves`), so a pool kept alive would cost
every later forked computation of the process its child.

And the other way round: BLAS held at one thread while inside :func:`one_blas_thread` (narrow products, and
work whose bits must not depend on the thread count: the design's SLSQP).
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

T = TypeVar("T")
R = TypeVar("R")

SETTING = "OMP_NUM_THREADS"
# Most threads one process's work is run on: the inline Monte Carlo holds the GIL for about a tenth
# of its CPU (py-spy --gil, 2,000 x 2, stop 44: 133 of 1,444 samples), so threads past a few only
# queue for it; more cores are the process pools' (expdesign.parallel).
MAX_THREADS = 4


def count() -> int:
    """Threads for this process's own independent work: ``OMP_NUM_THREADS`` where it is set to a
    positive integer (its first entry: OpenMP allows a list for nested levels), else the CPUs this
    process may run on; at most :data:`MAX_THREADS`. A value that is not a positive integer is
    ignored, as OpenMP ignores it."""
    try:
        n = int(os.environ.get(SETTING, "").split(",")[0])
    except ValueError:  # unset, empty or not a number ("²" passes str.isdigit but not int)
        n = 0
    return max(1, min(n if n > 0 else usable_cpus(), MAX_THREADS))


def usable_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        return os.cpu_count() or 1


def map_in_threads(fn: Callable[[T], R], items: Sequence[T], threads: int | None = None) -> list[R]:
    """``[fn(x) for x in items]`` on up to ``threads`` threads (default :func:`count`), this one
    among them: each thread takes the next item not yet taken, so the items run in order but which
    thread runs one depends on timing (``fn`` must give an item's result whatever ran beside it).
    Each thread runs in a copy of the caller's context (numpy's error state, a
    :func:`primitives.jitloop.job` hint). The extra threads are started here and joined before this
    returns, also on an error: then no thread takes a further item and the error of the first
    failed item is raised (a Ctrl-C in this thread stops it the same way)."""
    n = len(items)
    k = min(count() if threads is None else max(1, threads), n)
    if k <= 1:
        return [fn(x) for x in items]
    out: list[Any] = [None] * n
    errors: dict[int, BaseException] = {}
    lock = threading.Lock()
    state = {"next": 0, "stop": False}

    def take() -> int | None:
        with lock:
            i = state["next"]
            if state["stop"] or i >= n:
                return None
            state["next"] = i + 1
            return i

    def work() -> None:
        while (i := take()) is not None:
            try:
                out[i] = fn(items[i])
            except BaseException as e:  # noqa: BLE001 - raised by the caller once every thread stopped
                with lock:
                    errors[i] = e
                    state["stop"] = True
                return

    others = [threading.Thread(target=contextvars.copy_context().run, args=(work,), daemon=True) for _ in range(k - 1)]
    try:
        for t in others:
            t.start()
        work()
    finally:
        with lock:
            state["stop"] = True  # (a failed start, a Ctrl-C while starting): the others take no more
        _join(others, errors)
    if errors:  # a Ctrl-C (or exit) before any item's own error
        raise next((e for e in errors.values() if not isinstance(e, Exception)), errors[min(errors)])
    return out


def _join(threads: list[threading.Thread], errors: dict[int, BaseException]) -> None:
    """Wait for every started thread, also through a Ctrl-C (kept in ``errors`` to be raised
    after): a thread left running would still write the caller's results."""
    for t in threads:
        while t.ident is not None and t.is_alive():
            try:
                t.join()
            except KeyboardInterrupt as e:
                errors[-1] = e


_CONTROLLER: list = []  # [modules loaded when made, threadpoolctl controller] (:func:`thread_controller`)
#: callers inside :func:`one_blas_thread` and the limiter that restores BLAS's own thread count when the last
#: leaves: the limit is process-wide, so threads inside at once share one limiter (each its own would record
#: another's limit of 1 as the original and leave BLAS at one thread for good)
_HELD: list = [0, None]
_HELD_LOCK = threading.Lock()


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Every BLAS library loaded (numpy's, and scipy's own OpenBLAS once scipy.linalg or scipy.optimize is
    imported) limited to one thread while inside; their counts restored when the last caller leaves. Callers:
    work whose products are too narrow to gain from a second thread (:mod:`primitives.iir`), and work whose
    bits must not depend on the thread count (scipy's SLSQP rounds differently on one and two OpenBLAS threads:
    :func:`expdesign.constraints.minimize_slsqp`). A library loaded while a caller is inside is not limited: import
    what the work calls before entering."""
    with _HELD_LOCK:
        if _HELD[0] == 0:
            _HELD[1] = _limit_blas()
        _HELD[0] += 1
    try:
        yield
    finally:
        with _HELD_LOCK:
            _HELD[0] -= 1
            if _HELD[0] == 0 and _HELD[1] is not None:
                _HELD[1].restore_original_limits()
                _HELD[1] = None


def thread_controller() -> Any:
    """threadpoolctl's controller of the process's BLAS / OpenMP libraries. Its scan of the loaded libraries
    (5-15 ms) is kept, and made again when modules were imported since, which may have loaded another
    library (scipy's own OpenBLAS). Raises ImportError without threadpoolctl."""
    from threadpoolctl import ThreadpoolController

    if not _CONTROLLER or _CONTROLLER[0] != len(sys.modules):
        _CONTROLLER[:] = [len(sys.modules), ThreadpoolController()]
    return _CONTROLLER[1]


def _limit_blas() -> Any:
    """threadpoolctl's limiter of BLAS to one thread (it restores the counts it found), None when
    threadpoolctl cannot read this BLAS: the products then run as they are."""
    try:
        return thread_controller().limit(limits=1, user_api="blas")
    except Exception:  # noqa: BLE001 - any failure to read or set the BLAS leaves the products as they are
        return None
