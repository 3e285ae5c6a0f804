"""Dask worker preload: ``dask worker tcp://HOST:8786 --nthreads 1 --preload expdesign.dask_preload``.

A Monte Carlo task on a new Dask worker first pays the worker's own start: importing the package
and numba, loading the compiled passes from numba's disk cache (about a second of CPU a process,
16 times over on 16 workers, all inside the first command's wall time) — where a local pool's
workers, forked from a parent that loaded them once (:func:`expdesign.montecarlo.warm_compiled`),
pay nothing. Preloaded, each worker does this while it starts, before any command:

- one BLAS / OpenMP thread (:func:`expdesign.parallel.one_thread_per_worker`) set before the
  package loads its numerical libraries, and freed memory kept for the next batch
  (:func:`primitives.heap.keep_freed_memory`: the nanny's MALLOC_TRIM_THRESHOLD_ undone);
- the package imported and the compiled passes of one Monte Carlo run of the model-ship profile
  loaded (run 0 of a random design, its result dropped; a profile whose runs take other passes
  loads those at its first task);
- the heap grown to a full task's working set (:func:`grow_heap`: a batch of MAX_CHUNK runs, kept
  by :func:`primitives.heap.keep_freed_memory`), so that the worker's first task does not pay
  the page faults a new process's first large batch pays (measured by ``python
  benchmarks/bench_design.py --scaling --dask-local 2 4``: "a Dask worker's first task");
- the worker's statistical profiler off (:func:`quiet_profiler`): it samples every thread's stack
  every 10 ms for the dashboard's profile page, CPU taken from the tasks.

A failure here (no numba, an unwritable cache) is printed and the worker starts anyway: its
tasks then load what they need as they would without the preload.
"""

from __future__ import annotations

import time
from collections.abc import Callable


def warm(run_in: Callable[[Callable[[], None]], None] = lambda f: f()) -> float:
    """Load what a Monte Carlo task needs in this process and, where freed memory is kept, grow its
    heap to a task's working set (:func:`grow_heap`, called through ``run_in``: in the thread the
    tasks will run in); CPU seconds it took."""
    from expdesign.parallel import one_thread_per_worker
    from primitives.heap import keep_freed_memory

    one_thread_per_worker()
    grow = keep_freed_memory()
    t = time.process_time()
    from expdesign.montecarlo import MAX_CHUNK, MCConfig, prepare, warm_compiled
    from primitives.ship import load_profile

    sh = prepare(load_profile("model-ship"), {"random": "random"}, MCConfig(runs=MAX_CHUNK))
    warm_compiled(sh)
    if grow:
        run_in(lambda: grow_heap(sh))
    return time.process_time() - t


def grow_heap(sh: object) -> None:
    """One batch of MAX_CHUNK runs (the largest task the engines cut), its result dropped: the
    memory it freed stays with this process (:func:`primitives.heap.keep_freed_memory`, which
    must be in effect; a Dask nanny's default would hand it back to the system), so tasks after
    it reuse pages already faulted in. Costs about MAX_CHUNK runs' CPU once, as the worker starts."""
    from expdesign.montecarlo import MAX_CHUNK, run_chunk

    run_chunk(sh, "random", range(MAX_CHUNK))


WARM_CPU: float | None = None  # CPU seconds this worker's preload took (read by benchmarks/scaling_dask.py)

PROFILER_CALLBACKS = ("profile", "profile-cycle")  # distributed.Worker's periodic callbacks of its profiler


def quiet_profiler(worker: object) -> list[str]:
    """Drop the worker's statistical profiler (the callbacks start after the preloads, so they never
    run); the names dropped. Measured, a local cluster of 2 preloaded workers, 500 runs x 2 designs,
    3 pairs alternated at load 11-17: the workers' CPU 2.44 / 2.49 / 2.72 -> 2.40 / 2.17 / 2.66 ms a
    run (3 of 3 lower, the pairs' median change -2.2 %: within the noise of that load). The
    dashboard's profile page stays empty; a worker started without this preload keeps its profiler."""
    callbacks = getattr(worker, "periodic_callbacks", None)
    if not isinstance(callbacks, dict):
        return []
    return [name for name in PROFILER_CALLBACKS if callbacks.pop(name, None) is not None]


def dask_setup(worker: object = None) -> None:
    """Dask's preload hook (called once as the worker starts, before its periodic callbacks)."""
    quiet_profiler(worker)
    try:
        cpu = warm(_in_task_thread(worker))
    except Exception as e:  # noqa: BLE001 - the worker still serves tasks, which load what they need
        print(f"expdesign.dask_preload: not warmed ({type(e).__name__}: {e})", flush=True)
        return
    global WARM_CPU
    WARM_CPU = cpu
    print(f"expdesign.dask_preload: Monte Carlo passes loaded ({cpu:.1f} s CPU)", flush=True)


def _in_task_thread(worker: object) -> Callable[[Callable[[], None]], None]:
    """Run a function in the worker's task thread and wait for it (in this thread where the worker
    has no default executor). glibc gives each thread an arena of its own: a heap grown in the
    preload's thread stays unused by the tasks (measured, 2 preloaded workers, 125-run tasks: the
    first task 7,670 page faults, the second 8, with or without a heap grown in the preload's
    thread)."""
    executor = (getattr(worker, "executors", None) or {}).get("default")
    if executor is None:
        return lambda f: f()
    return lambda f: executor.submit(f).result()
