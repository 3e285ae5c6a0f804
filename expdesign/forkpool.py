"""A process pool that feeds each worker as soon as it is forked (the local engine on platforms
that fork: :class:`expdesign.parallel.LocalEngine`).

``concurrent.futures.ProcessPoolExecutor`` forks every worker before any starts a task (its first
submit starts them all, cpython#90622), and each fork of a large parent costs the parent a few
milliseconds (copying its page tables): 16 workers forked from the benchmark's ~250 MB parent
waited ~50 ms for the last fork, and the pool's machinery (a call queue with a feeder thread, a
manager thread, every result passed through both) added its own CPU in the parent. Here worker k
gets its first task the moment it exists and computes while the parent forks worker k + 1, so the
forks overlap the work; each worker has one duplex pipe to the parent, which sends it a task index
whenever it returns a result (no queue of tasks sits in a busy worker while another idles at the
end). The function, the items and the shared inputs are inherited through the fork, never pickled;
only task indices and results cross the pipes.

A worker that dies (killed, out of memory) loses only the task it held: that task is recorded as an
error and the others still run on the remaining workers.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import signal
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from typing import Any

from primitives.heap import release_freed_memory


@dataclass
class PoolTimes:
    """The CPU seconds each fork took in the parent in one map: worker k starts its first task
    after k + 1 of them (read by ``benchmarks/scaling_model.py``)."""

    forks: list[float] = field(default_factory=list)


def _worker(conn: Connection, others: list[Connection], fn: Callable, items: Sequence[Any], shared: Any) -> None:
    """A forked worker: run the task whose index the parent sends, send back (index, ok, result or
    error text), until the parent sends None or goes away (:func:`serve`)."""
    start_worker(others)
    serve(conn, fn, items, shared)


def start_worker(others: list[Connection]) -> None:
    """A forked worker's first steps (this pool's and :mod:`expdesign.warmpool`'s). Ctrl-C is the
    parent's to handle; SIGTERM (the parent's :meth:`terminate`) kills, whatever handler the parent
    had installed. ``others``: the parent's ends of this worker's pipe and of earlier workers'."""
    from expdesign.parallel import one_thread_per_worker
    from primitives.heap import keep_freed_memory

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a Ctrl-C pending since the fork is discarded here
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _HELD)  # blocked from the fork (fork_worker): a SIGTERM sent since kills now
    for c in others:  # EOFs must not wait for this process
        c.close()
    one_thread_per_worker(inherited=True)
    keep_freed_memory(always=True)  # each task reuses the heap the last one grew (primitives.heap)


NOT_LOADED = "not loaded"  # a worker's answer to a task of a map whose payload it could not unpickle
PAYLOAD_PARTS = ("function", "items", "shared inputs")  # a warm pool map's payload (expdesign.warmpool._payload)


def serve(conn: Connection, fn: Callable | None = None, items: Sequence[Any] = (), shared: Any = None) -> None:
    """Answer the parent until it sends None or goes away (then return quietly: no traceback from an
    orphan): a task index runs ``fn(items[index][, shared])`` and sends back (index, ok, result or
    error text); a tuple of the pickled (fn, items, shared) is a new map's
    (:class:`expdesign.warmpool.WarmPool`). A map whose payload does not unpickle here (a function
    the parent defined after the fork, a class whose rebuild raises) leaves the worker serving: each
    of its tasks is answered (:data:`NOT_LOADED`, index, the part and the error) and the next map's
    payload replaces it."""
    from expdesign.parallel import call_with_shared

    not_loaded = None
    with contextlib.suppress(EOFError, OSError):
        while (msg := conn.recv()) is not None:
            if isinstance(msg, tuple):
                (fn, items, shared), not_loaded = _load(msg)
                continue
            if not_loaded is not None:
                conn.send((NOT_LOADED, msg, not_loaded))
                continue
            try:
                out = (msg, True, call_with_shared(fn, items[msg], shared))
            except Exception as e:  # noqa: BLE001 - recorded per task, the worker takes the next
                out = (msg, False, f"{type(e).__name__}: {e}")
            try:
                conn.send(out)
            except (EOFError, OSError):  # the parent is gone: the suppress above ends the worker
                raise
            except Exception as e:  # noqa: BLE001 - a result that cannot be pickled
                conn.send((msg, False, f"result not sent: {type(e).__name__}: {e}"))


def _load(parts: tuple[bytes, ...]) -> tuple[tuple[Any, Any, Any], str | None]:
    """A warm pool map's (fn, items, shared) unpickled part by part, and the first part that failed with
    its error (None when all loaded)."""
    from multiprocessing.reduction import ForkingPickler

    out = []
    for name, b in zip(PAYLOAD_PARTS, parts):
        try:
            out.append(ForkingPickler.loads(b))
        except Exception as e:  # noqa: BLE001 - said to the parent, which raises it once for the map
            return (None, (), None), f"{name} ({type(e).__name__}: {e})"
    return (out[0], out[1], out[2]), None


def fork_map(
    fn: Callable,
    items: Sequence[Any],
    workers: int,
    shared: Any,
    on_result: Callable[[int, bool, Any], None],
    times: PoolTimes | None = None,
    forking: contextlib.AbstractContextManager | None = None,
) -> None:
    """Run ``fn(item[, shared])`` for every item on ``workers`` forked processes, calling
    ``on_result(index, ok, result or error text)`` in the parent as each finishes; tasks are handed
    out in order, one at a time per worker. A KeyboardInterrupt in the parent stops the workers at
    once and propagates. ``times`` receives the parent's CPU per fork (:class:`PoolTimes`);
    ``forking`` is held from the first fork to the last (the parent's state the workers inherit)."""
    ctx = multiprocessing.get_context("fork")
    times = times if times is not None else PoolTimes()
    nxt = 0
    held: dict[Connection, int | None] = {}  # a worker's pipe -> the task it is running
    procs: dict[Connection, multiprocessing.process.BaseProcess] = {}

    def feed(conn: Connection) -> None:
        nonlocal nxt
        if nxt < len(items):
            held[conn], nxt = nxt, nxt + 1
            try:
                conn.send(held[conn])
            except OSError:  # the worker died: its pipe's EOF makes the task an error (_collect)
                pass
        else:
            held[conn] = None

    release_freed_memory()  # fewer pages to copy at each fork (primitives.heap)
    pending: tuple[Connection, Connection, BaseProcess] | None = None  # the fork in flight until procs records it
    try:
        with forking or contextlib.nullcontext():
            for _ in range(min(workers, len(items))):
                c = time.process_time()
                mine, theirs = ctx.Pipe(duplex=True)
                p = ctx.Process(target=_worker, args=(theirs, [*procs, mine], fn, items, shared))
                pending = (mine, theirs, p)  # a Ctrl-C can land between the fork and its record (_stop_forked)
                try:
                    fork_worker(p)
                except OSError:  # no fork (out of memory, process limit): run on the workers already made
                    pending = None
                    mine.close()
                    theirs.close()
                    if not procs:
                        raise
                    break
                procs[mine] = p
                pending = None
                theirs.close()
                times.forks.append(time.process_time() - c)
                feed(mine)
        _collect(held, procs, feed, on_result)
        for i in range(nxt, len(items)):  # never handed out: every worker was lost
            on_result(i, False, "not run: every worker of the pool was lost")
        _stop(procs, held)
    except BaseException:
        try:  # a second Ctrl-C inside _stop_forked must not skip kill_workers (the workers ignore SIGINT)
            _stop_forked(pending, procs)
        finally:
            kill_workers(procs)
        raise


def _stop_forked(pending: tuple[Connection, Connection, BaseProcess] | None, procs: dict[Connection, BaseProcess]) -> None:
    """The worker forked when the map was interrupted, before it was recorded: stopped with the others when its
    process has started, and in any case its pipe closed at once, so that a worker whose pid was never known
    ends on the EOF (it takes no task before one is sent) instead of living as long as the interrupted frame."""
    if pending is None:
        return
    mine, theirs, p = pending
    if p.pid is not None:
        procs[mine] = p  # kill_workers terminates, reaps and closes it: recorded first, before anything can raise
    else:
        mine.close()  # the worker's only peer: it reads EOF
    theirs.close()


_HELD = {signal.SIGTERM, signal.SIGINT}  # blocked in a new worker until it has its own handlers


def fork_worker(p: multiprocessing.process.BaseProcess) -> None:
    """Start worker ``p`` with SIGTERM and SIGINT blocked from the fork until the worker has put in
    its own actions (:func:`start_worker`; the mask is inherited by the fork, and only this thread's is
    changed). A SIGTERM that came before would otherwise run the handler the parent had installed
    (as the map drawer's child has), and the worker would live on, orphaned, computing: seen under
    load (30 on 2 cores), the pool's terminate reached a worker just forked, which then held the
    pool for its SIGKILL grace. A Ctrl-C (sent to the whole foreground process group) would raise
    KeyboardInterrupt in the worker and print its traceback. The parent's own signals wait for the
    fork, no longer: its mask is put back as it was."""
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
    try:
        p.start()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


KILL_GRACE_S = 2.0  # a worker SIGTERM has not stopped by then is killed


def kill_workers(procs: dict) -> None:
    """Stop every worker now and reap it: SIGTERM, then SIGKILL for one still alive after a grace
    period (no zombie, no orphan left computing)."""
    for p in procs.values():
        p.terminate()
    for p in procs.values():
        p.join(timeout=KILL_GRACE_S)
        if p.exitcode is None:
            p.kill()
            p.join()
    for conn in procs:
        conn.close()


def _collect(
    held: dict[Connection, int | None],
    procs: dict,
    feed: Callable[[Connection], None],
    on_result: Callable[[int, bool, Any], None],
) -> None:
    """Results as they come, each worker fed its next task; a lost worker's task is an error and
    the worker is dropped. Returns when no worker holds a task."""
    while any(i is not None for i in held.values()):
        for conn in wait([c for c, i in held.items() if i is not None]):
            try:
                i, ok, out = conn.recv()
            except (EOFError, OSError):  # the worker died
                p = procs[conn]
                p.join(timeout=5)
                on_result(held.pop(conn), False, f"worker lost: exit code {p.exitcode}")
                continue
            except Exception as e:  # noqa: BLE001 - a result read whole that does not unpickle here
                i, ok, out = held[conn], False, f"result not received: {type(e).__name__}: {e}"
            on_result(i, ok, out)
            feed(conn)


def _stop(procs: dict, held: dict) -> None:
    for conn in procs:
        if conn in held:
            try:
                conn.send(None)
            except OSError:
                pass
        conn.close()
    for p in procs.values():
        p.join()
