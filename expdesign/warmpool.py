"""A process pool started before its work is known and reused by later maps (issue 30): the
workers' forks and their warm-up leave the critical path of the map that needs them.

:func:`expdesign.forkpool.fork_map` forks its workers when the map starts, from the parent as it is
then (the benchmark's parent: 6.5 ms CPU a fork, the last of 16 workers starting ~0.15-0.3 s after
the map; Stop 56, docs/kernel-speed.md). A :class:`WarmPool` forks them when the caller knows it
will need them (e.g. before other work that precedes the map), and each worker runs
``warm`` (loading the compiled passes) while the parent goes on; the map then only ships its
function, items and shared inputs: pickled once in the parent, the same bytes written to each
worker, which unpickles them in parallel with the others. Results are those of a fresh pool: a
task's result depends only on its item and the shared inputs, never on the process that ran it.

Behaviour kept from :mod:`expdesign.forkpool` (whose fork, kill, worker start-up and task loop it uses): a task
that raises is its own error; a worker that dies loses only the task it held, reported with its exit
code, and leaves the pool; a Ctrl-C in the parent during a map stops every worker at once and
propagates (the pool is then closed). A pool never used ends on :meth:`WarmPool.close`, on the
parent's exit (each worker reads EOF on its pipe) or on the garbage collector's finaliser.
:meth:`WarmPool.close` waits at most ``timeout`` seconds for the workers to finish their warm-up
and exit, then kills the rest. A failed warm-up is not silent: each distinct error is issued once as
a :class:`WarmUpFailed` warning when the worker reports it, and :meth:`WarmPool.warm_up_errors` lists them.
A map's function, items or shared inputs that cannot be pickled (in the parent) or unpickled (in a worker:
a function defined after the fork) raise one RuntimeError naming the part; the workers stay in the pool.

No command uses this pool: ``shiptrial design --monte-carlo`` was measured slower with it on 2 cores
(docs/kernel-speed.md, Stop 57). ``benchmarks/bench_design.py --scaling`` measures it (``warm xW``).
"""

from __future__ import annotations

import multiprocessing
import time
import warnings
import weakref
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from multiprocessing.reduction import ForkingPickler
from typing import Any

from expdesign.forkpool import NOT_LOADED, PAYLOAD_PARTS, fork_worker, kill_workers, serve, start_worker
from primitives.heap import release_freed_memory

READY = "ready"  # a worker's first message: its warm-up is done (with the error text if it failed)
NO_WORKER = "the warm pool has no worker left (closed, or every worker was lost): start a new WarmPool"
CLOSE_TIMEOUT_S = 10.0  # close(): seconds the workers get to finish their warm-up and exit before they are killed


class WarmUpFailed(RuntimeWarning):
    """A worker's warm-up raised: its tasks still run (they load what they need), at the cost the
    warm-up was to save. Issued once for each distinct error text."""


def _worker(conn: Connection, others: list[Connection], warm: Callable[[], None] | None) -> None:
    """A pool worker: warm up, say so, then for each map take (function, items, shared) and run
    the task indices the parent sends, answering (index, ok, result or error text), until the
    parent sends None or goes away (:func:`expdesign.forkpool.serve`)."""
    start_worker(others)
    err = None
    if warm is not None:
        try:
            warm()
        except Exception as e:  # noqa: BLE001 - a failed warm-up is said; the tasks load what they need
            err = f"{type(e).__name__}: {e}"
    try:
        conn.send((READY, err))
    except OSError:  # the parent is gone: serve reads its EOF and returns
        pass
    serve(conn)


def _payload(fn: Callable, items: Sequence[Any], shared: Any) -> bytes:
    """A map's (function, items, shared inputs), each pickled on its own (a worker then names the part it
    cannot unpickle) and the three sent as one message. A part that cannot be pickled raises RuntimeError
    naming it, before anything is sent: the workers are untouched and the pool stays usable. An object held by two
    parts (an item and the shared inputs) is sent twice and is two objects in a worker."""
    parts = []
    for name, part in zip(PAYLOAD_PARTS, (fn, items, shared)):
        try:
            parts.append(bytes(ForkingPickler.dumps(part)))
        except Exception as e:  # noqa: BLE001 - PicklingError, TypeError, AttributeError (a local object)...
            raise RuntimeError(
                f"warm pool: the map's {name} cannot be pickled ({type(e).__name__}: {e}); "
                "pass a module-level function and picklable data"
            ) from e
    return bytes(ForkingPickler.dumps(tuple(parts)))


class WarmPool:
    """``workers`` processes forked now, each running ``warm()`` (inherited through the fork, never
    pickled) and then waiting for maps (:meth:`map`). Use as a context manager or call :meth:`close`."""

    def __init__(self, workers: int, warm: Callable[[], None] | None = None):
        ctx = multiprocessing.get_context("fork")
        self.procs: dict[Connection, multiprocessing.process.BaseProcess] = {}
        self.ready: dict[Connection, str | None] = {}  # a worker's warm-up error (None: fine), once it said
        self._warned: set[str] = set()  # warm-up errors already issued as WarmUpFailed
        self._not_loaded: str | None = None  # the current map's payload part a worker could not unpickle, and why
        from expdesign.parallel import one_thread_while_forking

        release_freed_memory()
        try:
            with one_thread_while_forking():  # each worker inherits one BLAS thread (expdesign.parallel)
                self._fork_all(ctx, workers, warm)
        except BaseException:
            kill_workers(self.procs)
            raise
        self._finalizer = weakref.finalize(self, kill_workers, self.procs)

    def _fork_all(self, ctx: Any, workers: int, warm: Callable[[], None] | None) -> None:
        for _ in range(max(1, workers)):
            mine, theirs = ctx.Pipe(duplex=True)
            p = ctx.Process(target=_worker, args=(theirs, [*self.procs, mine], warm), daemon=True)
            try:
                fork_worker(p)
            except OSError:  # no fork: the pool is the workers already made
                mine.close()
                theirs.close()
                if not self.procs:
                    raise
                return
            self.procs[mine] = p
            theirs.close()

    @property
    def size(self) -> int:
        """Workers alive (a lost worker leaves the pool)."""
        return len(self.procs)

    def workers_left(self) -> int:
        """:attr:`size`, for a caller about to use the pool: a pool with none (closed, or every
        worker lost) raises RuntimeError instead of letting the caller run its work elsewhere."""
        if not self.procs:
            raise RuntimeError(NO_WORKER)
        return len(self.procs)

    def wait_ready(self, timeout: float | None = None) -> dict[Connection, str | None]:
        """Block until every worker has finished its warm-up (or ``timeout`` seconds); returns the
        warm-up errors by worker."""
        pending = [c for c in self.procs if c not in self.ready]
        while pending:
            got = wait(pending, timeout)
            if not got:
                break
            for c in got:
                self._read_ready(c)
            pending = [c for c in self.procs if c not in self.ready]
        return dict(self.ready)

    def _read_ready(self, conn: Connection) -> None:
        try:
            tag, err = conn.recv()
        except (EOFError, OSError):
            self._lose(conn)
            return
        assert tag == READY
        self._note_ready(conn, err)

    def _note_ready(self, conn: Connection, err: str | None) -> None:
        self.ready[conn] = err
        if err is not None and err not in self._warned:
            self._warned.add(err)
            warnings.warn(f"warm pool: a worker's warm-up failed: {err}", WarmUpFailed, stacklevel=3)

    def warm_up_errors(self) -> list[str]:
        """The distinct warm-up errors reported so far (by any worker, lost or not), sorted."""
        return sorted(self._warned)

    def _lose(self, conn: Connection) -> int | None:
        p = self.procs.pop(conn)
        self.ready.pop(conn, None)
        p.join(timeout=5)
        conn.close()
        return p.exitcode

    def map(self, fn: Callable, items: Sequence[Any], shared: Any, on_result: Callable[[int, bool, Any], None]) -> None:
        """As :func:`expdesign.forkpool.fork_map` on this pool's workers: ``on_result(index, ok,
        result or error text)`` as each task finishes, tasks handed out in order, one at a time per
        worker; (``fn``, ``items``, ``shared``) pickled once and sent to each worker before its first
        task. A KeyboardInterrupt (or any error here) stops every worker and closes the pool."""
        for conn in [c for c, p in self.procs.items() if not p.is_alive()]:  # died while idle: no task lost
            self._lose(conn)
        self.workers_left()
        payload = _payload(fn, items, shared)
        held: dict[Connection, int | None] = {}
        nxt = 0
        self._not_loaded = None
        try:
            for conn in list(self.procs):
                if nxt >= len(items):
                    break
                try:
                    conn.send_bytes(payload)
                    conn.send(nxt)
                except OSError:  # died while idle: its EOF is read below, its task then lost
                    pass
                held[conn], nxt = nxt, nxt + 1
            while any(i is not None for i in held.values()):
                for conn in wait([c for c, i in held.items() if i is not None]):
                    nxt = self._answer(conn, held, nxt, items, on_result)
            for i in range(nxt, len(items)):
                on_result(i, False, "not run: every worker of the pool was lost")
        except BaseException:
            self.close(now=True)
            raise
        if self._not_loaded is not None:  # every worker is idle again, in step with the parent: the pool stays usable
            raise RuntimeError(f"warm pool: a worker could not unpickle the map's {self._not_loaded}")

    def _answer(
        self, conn: Connection, held: dict[Connection, int | None], nxt: int, items: Sequence[Any], on_result: Callable
    ) -> int:
        """One message from a worker: its warm-up note, a result (the worker then gets the next
        task), or its death (its task an error, the worker dropped). Returns the next task index."""
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            code = self._lose(conn)
            on_result(held.pop(conn), False, f"worker lost: exit code {code}")
            return nxt
        except Exception as e:  # noqa: BLE001 - a result read whole that does not unpickle here
            msg = (held[conn], False, f"result not received: {type(e).__name__}: {e}")
        if msg[0] == READY:
            self._note_ready(conn, msg[1])
            return nxt
        held[conn] = None
        if msg[0] == NOT_LOADED:  # no task of this map can run: none handed out from now on (map raises once all are back)
            self._not_loaded = self._not_loaded or msg[2]
            return len(items)
        on_result(*msg)
        if nxt < len(items):
            held[conn], nxt = nxt, nxt + 1
            try:
                conn.send(nxt - 1)
            except OSError:  # the worker died: its EOF makes the task an error
                pass
        return nxt

    def close(self, now: bool = False, timeout: float = CLOSE_TIMEOUT_S) -> None:
        """Stop the workers: each is told to exit after its warm-up and joined, for at most
        ``timeout`` seconds in all; a worker still alive then (a warm-up stuck or slow, e.g. on a
        cold cache) is killed (SIGTERM, then SIGKILL after a grace, as
        :func:`expdesign.forkpool.kill_workers`). ``now``: kill them all at once."""
        if now:
            kill_workers(self.procs)
        else:
            for conn in self.procs:
                try:
                    conn.send(None)
                except OSError:
                    pass
            end = time.monotonic() + max(0.0, timeout)
            for p in self.procs.values():
                p.join(max(0.0, end - time.monotonic()))
            kill_workers({c: p for c, p in self.procs.items() if p.exitcode is None})
            for conn in self.procs:
                conn.close()
        self.procs.clear()
        self._finalizer.detach()

    def __enter__(self) -> WarmPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close(now=exc[0] is not None)
