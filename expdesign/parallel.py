"""Where independent work runs: in this process and its cores, or on a Dask cluster.

Monte Carlo chunks, sweep cells and primitive simulations are independent tasks whose
randomness comes only from seeds derived from (root seed, task index) with
``numpy.random.SeedSequence``. So a task computes the same numbers wherever it runs, and the
results are reassembled in task order: local and cluster runs agree exactly.

Select the engine with ``scheduler``: None or "local" (default; a process pool over all cores,
no server), "inline" (this process, one task at a time), or a Dask scheduler address such as
"tcp://10.0.0.5:8786" (also read from the environment variable SHIPTRIAL_SCHEDULER).

``Engine.capacity()`` says how many workers and threads per worker the engine has (so callers
can cut enough tasks; a Dask engine first waits briefly for workers still (re)starting, see
:meth:`DaskEngine.capacity`); ``map(fn, items, shared=obj)`` ships ``obj`` once per worker (process-pool
initializer, ``Client.scatter(broadcast=True)`` on Dask) and calls ``fn(item, obj)``.
Ctrl-C stops cleanly: unfinished tasks are cancelled, local workers terminated, and the finished
results kept (``MapResult.interrupted``); a task that fails or a lost worker is recorded in
``MapResult.errors`` and the other tasks still finish.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from primitives.errors import UserError
from primitives.heap import keep_freed_memory
from primitives.threads import thread_controller

ENV_SCHEDULER = "SHIPTRIAL_SCHEDULER"


@dataclass
class MapResult:
    """Results in task order; ``None`` where a task did not finish (interrupted or failed)."""

    results: list[Any]
    done: list[bool]
    interrupted: bool = False
    errors: dict[int, str] = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        return all(self.done)

    def finished(self) -> list[Any]:
        return [r for r, d in zip(self.results, self.done) if d]


def task_seeds(seed: int, n: int) -> list[int]:
    """One independent 63-bit seed per task from the root seed (same on every engine)."""
    return [int(s.generate_state(1, dtype=np.uint64)[0] >> np.uint64(1)) for s in np.random.SeedSequence(seed).spawn(n)]


class _Progress:
    """A rich progress bar on stderr when it is a terminal (silent otherwise): units done of
    the total (e.g. Monte Carlo runs, each task weighted by its runs) and units per second."""

    def __init__(self, weights: Sequence[float], desc: str, enabled: bool, unit: str = "tasks"):
        self.bar = None
        self.weights, self.unit, self.done, self.t0 = list(weights), unit, 0.0, time.perf_counter()
        if enabled and len(self.weights) > 1:
            import sys

            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

            if sys.stderr.isatty():
                from rich.console import Console

                self.bar = Progress(
                    TextColumn("{task.description}"),
                    BarColumn(),
                    TextColumn("{task.completed:.0f}/{task.total:.0f} " + unit),
                    TextColumn("{task.fields[rate]}"),
                    TimeRemainingColumn(),
                    console=Console(stderr=True),
                    transient=True,
                )
                self.bar.start()
                self.task = self.bar.add_task(desc, total=sum(self.weights), rate="")

    def advance(self, i: int) -> None:
        self.done += self.weights[i]
        if self.bar is not None:
            rate = self.done / max(1e-9, time.perf_counter() - self.t0)
            self.bar.update(self.task, advance=self.weights[i], rate=f"{rate:.1f} {self.unit}/s")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


def call_with_shared(fn: Callable, item: Any, shared: Any) -> Any:
    return fn(item) if shared is None else fn(item, shared)


class Engine:
    """Runs ``fn(item)`` (or ``fn(item, shared)``) for every item, in this process."""

    name = "inline"

    def capacity(self) -> tuple[int, int]:
        """(workers, threads per worker) available to tasks."""
        return 1, 1

    def map(
        self,
        fn: Callable[..., Any],
        items: Sequence[Any],
        desc: str = "working",
        progress: bool = True,
        shared: Any = None,
        weights: Sequence[float] | None = None,
        unit: str = "tasks",
    ) -> MapResult:
        res, done = [None] * len(items), [False] * len(items)
        bar = _Progress(weights or [1] * len(items), desc, progress, unit)
        try:
            for i, it in enumerate(items):
                res[i] = call_with_shared(fn, it, shared)
                done[i] = True
                bar.advance(i)
        except KeyboardInterrupt:
            return MapResult(res, done, interrupted=True)
        finally:
            bar.close()
        return MapResult(res, done)

    def close(self) -> None:
        pass

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


_SHARED: Any = None
# thread pools of the numerical libraries a worker process may load (BLAS, OpenMP)
THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)
_ONE_THREAD = False


def one_thread_per_worker(inherited: bool = False) -> None:
    """One BLAS / OpenMP thread in this worker process: the engines run one task per core, so a
    library's own threads would only compete with the other workers for the same cores (CPU
    spent spinning and switching, not computing). The libraries already loaded are limited with
    threadpoolctl (unless ``inherited``: a worker forked while the parent held them at one thread,
    :func:`one_thread_while_forking`), those loaded later by the environment variables; once per
    process."""
    global _ONE_THREAD
    if _ONE_THREAD:
        return
    for var in THREAD_VARS:
        os.environ[var] = "1"
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency; without it only later-loaded libraries are limited
        pass
    else:
        if not inherited:
            threadpool_limits(1)
    _ONE_THREAD = True


def one_thread_while_forking() -> contextlib.AbstractContextManager:
    """The parent's BLAS / OpenMP libraries held at one thread while it forks the pool's workers,
    then restored: each worker inherits the limit instead of finding and limiting the libraries
    itself. Measured with 16 workers forked from the benchmark's parent (2 loaded cores, no-op
    tasks, median of 5): a worker's CPU before its first task 25-27 -> 3 ms, the parent's +4-8 ms
    (limit and restore), once per command +10 ms (finding the libraries: the controller is kept,
    :func:`primitives.threads.thread_controller`)."""
    try:
        controller = thread_controller()
    except ImportError:  # pragma: no cover - a dependency; the workers then limit what they can
        return contextlib.nullcontext()
    return controller.limit(limits=1)


def _init_worker(shared: Any) -> None:
    """Process-pool initializer (start methods other than fork): keep the shared inputs; one
    BLAS/OpenMP thread (:func:`one_thread_per_worker`); leave Ctrl-C to the parent, which cancels
    and terminates the pool (workers would otherwise each print a traceback)."""
    global _SHARED
    _SHARED = shared
    one_thread_per_worker()
    keep_freed_memory(always=True)  # this process is the pool's own (primitives.heap)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _pool_call(fn: Callable, item: Any, use_shared: bool) -> Any:
    return call_with_shared(fn, item, _SHARED if use_shared else None)


class LocalEngine(Engine):
    """A process pool over the machine's cores (no server to start): where processes fork,
    :mod:`expdesign.forkpool` (each worker fed as soon as it is forked; a lost worker costs only its
    own task), elsewhere Python's ``ProcessPoolExecutor``."""

    name = "local"

    def __init__(self, workers: int | None = None, pool: Any = None):
        self.pool = pool  # an expdesign.warmpool.WarmPool started earlier: its workers run the maps
        self.workers = pool.workers_left() if pool is not None else workers or os.cpu_count() or 1
        self.times = None  # the last forked map's expdesign.forkpool.PoolTimes (benchmarks/scaling_model.py)

    def capacity(self) -> tuple[int, int]:
        return (self.pool.workers_left() if self.pool is not None else self.workers), 1

    def map(
        self,
        fn: Callable[..., Any],
        items: Sequence[Any],
        desc: str = "working",
        progress: bool = True,
        shared: Any = None,
        weights: Sequence[float] | None = None,
        unit: str = "tasks",
    ) -> MapResult:
        if self.pool is not None:
            self.pool.workers_left()  # a closed or emptied pool raises, whatever the items: never replaced by a fresh one
        if self.pool is not None and len(items) > 1:
            # expdesign.warmpool.WarmPool.map on the pool given: no fork here, so the progress bar
            # starts at once. Any error raised during the map (a Ctrl-C, but also a bug in the progress
            # bar or in gathering a result) kills every worker and closes the pool, as a fresh pool's
            # map does; only a KeyboardInterrupt becomes a partial result (marked interrupted), any
            # other error propagates. A task's own error is only that task's.
            bars = [_Progress(weights or [1] * len(items), desc, progress, unit)]
            return _run_map(lambda on: self.pool.map(fn, items, shared, on), len(items), bars)
        if self.workers <= 1 or len(items) <= 1:
            return super().map(fn, items, desc, progress, shared, weights, unit)
        ctx = multiprocessing.get_context()
        if ctx.get_start_method() == "fork":
            return self._fork_map(fn, items, desc, progress, shared, weights, unit)
        res, done, errors = [None] * len(items), [False] * len(items), {}
        bar = _Progress(weights or [1] * len(items), desc, progress, unit)
        pool = ProcessPoolExecutor(
            max_workers=min(self.workers, len(items)), mp_context=ctx, initializer=_init_worker, initargs=(shared,)
        )
        futures = {pool.submit(_pool_call, fn, it, shared is not None): i for i, it in enumerate(items)}
        pending = set(futures)
        try:
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    i = futures[f]
                    try:
                        res[i] = f.result()
                        done[i] = True
                        bar.advance(i)
                    except BrokenProcessPool as e:  # a worker died (killed, out of memory)
                        errors[i] = f"worker lost: {e}"
                    except Exception as e:  # noqa: BLE001 - recorded per task, the others still run
                        errors[i] = f"{type(e).__name__}: {e}"
        except KeyboardInterrupt:
            for f in pending:
                f.cancel()
            _terminate(pool)
            bar.close()
            return MapResult(res, done, interrupted=True, errors=errors)
        bar.close()
        pool.shutdown()
        return MapResult(res, done, errors=errors)

    def _fork_map(
        self,
        fn: Callable[..., Any],
        items: Sequence[Any],
        desc: str,
        progress: bool,
        shared: Any,
        weights: Sequence[float] | None,
        unit: str,
    ) -> MapResult:
        """:func:`expdesign.forkpool.fork_map`: each worker fed as soon as it is forked, inheriting one
        BLAS thread (:func:`one_thread_while_forking`, held while the workers are forked). The progress
        bar (whose refresh thread could hold the terminal's lock at a fork, and the child would then
        hang at its first write to stderr) starts after the last fork."""
        from expdesign.forkpool import PoolTimes, fork_map

        bars: list[_Progress] = []

        @contextlib.contextmanager
        def forking() -> Iterator[None]:
            t0 = time.perf_counter()
            with one_thread_while_forking():
                yield
            bars.append(_Progress(weights or [1] * len(items), desc, progress, unit))
            bars[0].t0 = t0

        self.times = PoolTimes()
        return _run_map(lambda on: fork_map(fn, items, self.workers, shared, on, self.times, forking()), len(items), bars)


def _run_map(run: Callable[[Callable[[int, bool, Any], None]], None], n: int, bars: list[_Progress]) -> MapResult:
    """``run(on_result)`` (a pool's map) gathered into a MapResult, its progress in ``bars[0]`` (made
    by the time the first result comes); a Ctrl-C gives the partial result, marked interrupted."""
    res, done, errors = [None] * n, [False] * n, {}

    def on_result(i: int, ok: bool, out: Any) -> None:
        if ok:
            res[i], done[i] = out, True
            bars[0].advance(i)
        else:
            errors[i] = out

    try:
        run(on_result)
    except KeyboardInterrupt:
        return MapResult(res, done, interrupted=True, errors=errors)
    finally:
        for bar in bars:
            bar.close()
    return MapResult(res, done, errors=errors)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop the pool's worker processes now (a running chunk would otherwise finish first)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        p.terminate()
    for p in procs:
        p.join(timeout=5)


CONNECT_TIMEOUT_S = 10  # an unreachable scheduler is a user error, said within seconds
WORKER_WAIT_S = 10.0  # how long capacity() waits for the cluster's workers to (re)connect


class DaskEngine(Engine):
    """Tasks on a Dask distributed cluster (an address, or a Client / LocalCluster object)."""

    name = "dask"

    def __init__(self, address_or_cluster: Any):
        _CALLER_PIDS.add(os.getpid())
        try:
            from distributed import Client
        except ImportError:  # pragma: no cover - depends on the environment
            raise RuntimeError(
                "a Dask scheduler was given but the 'distributed' package is not installed: pip install 'shiptrial[dask]'"
            ) from None
        if isinstance(address_or_cluster, Client):
            self.client, self._own = address_or_cluster, False
            return
        try:
            self.client = Client(address_or_cluster, set_as_default=False, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError, TypeError) as exc:  # unreachable, refused or malformed address
            raise UserError(
                f"--scheduler {address_or_cluster!r}: no Dask scheduler answered within {CONNECT_TIMEOUT_S} s "
                f"({type(exc).__name__}); check the address (tcp://HOST:8786) or use --scheduler local"
            ) from None
        self._own = True

    def capacity(self) -> tuple[int, int]:
        """Workers and threads per worker to cut the tasks for. Workers still starting or being
        restarted by their nanny are not connected yet: the engine waits up to WORKER_WAIT_S for
        the workers the cluster is configured for (a cluster object: its worker spec), or for a
        first worker when only an address is known; then it counts what is connected (with none,
        one: the tasks wait at the scheduler for the first worker)."""
        want = max(1, self.expected_workers())
        workers = self._workers()
        if len(workers) < want:
            try:
                self.client.wait_for_workers(want, timeout=WORKER_WAIT_S)
            except (TimeoutError, OSError):  # not all came: cut for those that did
                pass
            workers = self._workers()
        if not workers:
            return 1, 1
        threads = [int(w.get("nthreads", 1)) for w in workers.values()]
        return len(threads), max(1, round(sum(threads) / len(threads)))

    def expected_workers(self) -> int:
        """How many workers the cluster is configured for (a LocalCluster or other SpecCluster
        given as an object, including workers not yet or not again connected); 0 when unknown
        (a scheduler address: it does not know the workers that will connect)."""
        spec = getattr(getattr(self.client, "cluster", None), "worker_spec", None)
        return len(spec) if spec else 0

    def _workers(self) -> dict:
        return (
            self.client.scheduler_info(n_workers=-1)["workers"]
            if _takes_n_workers(self.client)
            else self.client.scheduler_info()["workers"]
        )

    def map(
        self,
        fn: Callable[..., Any],
        items: Sequence[Any],
        desc: str = "working",
        progress: bool = True,
        shared: Any = None,
        weights: Sequence[float] | None = None,
        unit: str = "tasks",
    ) -> MapResult:
        from distributed import as_completed

        res, done, errors = [None] * len(items), [False] * len(items), {}
        kw = {} if shared is None else {"shared": self.client.scatter(shared, broadcast=True, hash=False)}
        futures = self.client.map(_dask_call, list(items), fn=fn, pure=False, **kw)
        index = {f.key: i for i, f in enumerate(futures)}
        bar = _Progress(weights or [1] * len(items), f"{desc} (dask)", progress, unit)
        try:
            for f in as_completed(futures, loop=self.client.loop):
                i = index[f.key]
                try:
                    res[i] = f.result()
                    done[i] = True
                    bar.advance(i)
                except Exception as e:  # noqa: BLE001 - KilledWorker (lost worker) or a task error
                    errors[i] = f"{type(e).__name__}: {e}"
        except KeyboardInterrupt:
            self.client.cancel([f for f in futures if not f.done()])
            bar.close()
            return MapResult(res, done, interrupted=True, errors=errors)
        bar.close()
        return MapResult(res, done, errors=_name_the_lost_worker(errors))

    def close(self) -> None:
        if self._own:
            self.client.close()


def _name_the_lost_worker(errors: dict[int, str]) -> dict[int, str]:
    """Tasks Dask cancelled because a worker died (it may forget their futures before it reports the
    KilledWorker on another task) say so, so that whichever failed task is listed first names the cause."""
    killed = next((e for e in errors.values() if e.startswith("KilledWorker")), None)
    if killed is None:
        return errors
    return {
        i: (f"{killed} (this task cancelled with it: {e})" if "Cancelled" in e.split(":", 1)[0] else e) for i, e in errors.items()
    }


def _dask_call(item: Any, fn: Callable, shared: Any = None) -> Any:
    if os.getpid() not in _CALLER_PIDS:  # a worker process (an in-process cluster leaves the caller's libraries alone)
        one_thread_per_worker()  # a Dask worker's threads each run a task: no BLAS threads on top
        keep_freed_memory()
    return call_with_shared(fn, item, shared)


_CALLER_PIDS: set[int] = set()  # processes that made a DaskEngine


def _takes_n_workers(client: Any) -> bool:
    import inspect

    return "n_workers" in inspect.signature(client.scheduler_info).parameters


def get_engine(scheduler: Any = None, workers: int | None = None) -> Engine:
    """The engine for ``scheduler`` (see the module docstring); SHIPTRIAL_SCHEDULER is the default."""
    if scheduler is None:
        scheduler = os.environ.get(ENV_SCHEDULER) or "local"
    if isinstance(scheduler, Engine):
        return scheduler
    if scheduler == "inline":
        return Engine()
    if scheduler == "local":
        return LocalEngine(workers)
    return DaskEngine(scheduler)
