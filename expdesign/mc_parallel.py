"""The Monte Carlo of :mod:`expdesign.montecarlo` cut into (design, runs) tasks and run on an engine
of :mod:`expdesign.parallel` (inline, a local process pool or a Dask cluster).

The engine is asked for its workers and threads and gets ``tasks_per_worker`` tasks per worker
slot where each holds at least MIN_TASK_RUNS runs (fewer, larger tasks otherwise), in near-equal
run ranges; the shared inputs (:class:`expdesign.montecarlo.MCShared`)
are computed once in the caller and shipped once per worker. A task's result depends only on
(seed, run index), so the merged per-run results are bit-identical to one in-process call
(:func:`expdesign.montecarlo.evaluate_designs`) whatever the engine or the cut.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from expdesign.mc_result import MCResult, merge_results
from expdesign.montecarlo import MAX_CHUNK, MCConfig, MCShared, prepare, run_chunk, warm_compiled
from primitives.library import Primitive
from primitives.ship import ShipProfile
from primitives.simulate import Disturbances


@dataclass
class MCEvaluation:
    """Results of :func:`evaluate_designs_parallel`. ``complete`` is False when it was interrupted
    (Ctrl-C) or a task failed (a lost worker): the results then hold the finished runs only and
    are marked partial. ``engine``: name, workers, threads, tasks, tasks per worker, runs per task."""

    results: dict[str, MCResult]
    config: MCConfig
    complete: bool
    interrupted: bool
    errors: list[str]
    elapsed_s: float
    engine: dict[str, Any]
    sample_time: float = 1.0
    profile: str = ""
    disturbances: dict[str, Any] = field(default_factory=dict)
    library: str = ""  # the profile's built-in manoeuvre dictionary (primitives.library), "" if none
    designs: tuple[str, ...] = ()  # every design evaluated, in order, also those without a finished run

    @property
    def runs_finished(self) -> dict[str, int]:
        """Runs finished per design, 0 for a design none of whose tasks finished (a partial result)."""
        done = {k: len(r.runs) for k, r in self.results.items()}
        return dict.fromkeys(self.designs, 0) | done


def _task(item: tuple[str, int, int], shared: MCShared) -> MCResult:
    design, a, b = item
    return run_chunk(shared, design, range(a, b))


# Fewest runs in a task cut for load balance: a task costs a fixed part F (the batch's setup and the
# kernel's time loops, paid whatever its size) plus p a run; measured F 8-39 ms, p 1.6-1.8 ms
# (`python benchmarks/bench_design.py --scaling`, 2 loaded cores), so a 100-run task spends at most
# about a fifth of its CPU on F where a 32-run one spent up to two fifths.
MIN_TASK_RUNS = 100


def plan_tasks(runs: int, n_designs: int, slots: int, tasks_per_worker: int = 4, chunk_runs: int | None = None) -> int:
    """Tasks per design, each of at most MAX_CHUNK runs (or ``chunk_runs``, which then alone decides);
    on several worker slots, ``tasks_per_worker`` per slot together (load balance and progress) when
    they hold at least MIN_TASK_RUNS runs each, else fewer, larger tasks, down to one per slot.

    Not more: a task's cost is a fixed part (paid once per batch whatever its size) plus a part per
    run, so every extra task adds the fixed part to the total; with the faster kernel the fixed part
    weighs more: 4 tasks per slot of a small study (500 runs x 4 designs on 16 workers: 32-run
    tasks) spent up to two fifths of their CPU on it. ``python benchmarks/bench_design.py --scaling`` measures
    both parts and predicts the efficiency per worker count."""
    cap = max(1, min(chunk_runs or MAX_CHUNK, MAX_CHUNK))
    n = -(-runs // cap)
    if slots > 1 and not chunk_runs:
        per_slot = runs * n_designs // slots
        k = max(1, min(tasks_per_worker, per_slot // MIN_TASK_RUNS))
        n = max(n, -(-k * slots // n_designs))
    return max(1, min(runs, n))


def cut_tasks(designs: Sequence[str], runs: int, n: int) -> list[tuple[str, int, int]]:
    """(design, first run, end run): ``n`` ranges per design whose sizes differ by at most one
    (no short tail task paying the fixed cost for a few runs), design by design as submitted."""
    return [(d, i * runs // n, (i + 1) * runs // n) for d in designs for i in range(n)]


def start_warm_pool(
    profile: ShipProfile,
    primitives: list[Primitive],
    scheduler: Any = None,
    workers: int | None = None,
    **protocol: Any,
) -> Any:
    """A :class:`expdesign.warmpool.WarmPool` for a Monte Carlo to come on the local engine, started
    now, each worker warmed by :func:`warm_worker` on the random design of ``primitives`` with the
    Monte Carlo's ``protocol``; None where the local engine would not fork several workers (another
    engine, one usable core, no fork). ``workers`` defaults to the cores this process may run on
    (:func:`os.sched_getaffinity` where there is one: a container's CPU mask, not the host's count).
    The compiled passes are loaded here, in the parent, before the fork
    (:func:`expdesign.montecarlo.warm_compiled`): the workers inherit the machine code instead of
    each compiling it at once from a cold numba cache (about 15 s of CPU a process).
    Pass it to :class:`expdesign.parallel.LocalEngine` and close it. No command uses it: the
    bench's ``warm xW`` rows do (``shiptrial design --monte-carlo`` measured slower with it on 2
    cores, docs/kernel-speed.md, Stop 57)."""
    import multiprocessing
    import os

    from expdesign.parallel import ENV_SCHEDULER
    from expdesign.warmpool import WarmPool
    from primitives.threads import usable_cpus

    if (scheduler or os.environ.get(ENV_SCHEDULER) or "local") != "local":
        return None
    n = workers or usable_cpus()
    if n <= 1 or multiprocessing.get_start_method() != "fork":
        return None
    sh = prepare(profile, {"random": "random"}, MCConfig(runs=MAX_CHUNK, **protocol), primitives)
    warm_compiled(sh)  # in the parent, before the fork: the workers inherit the compiled passes
    return WarmPool(n, lambda: warm_worker(sh))


def warm_worker(sh: MCShared) -> None:
    """A warm pool's worker made ready for the Monte Carlo's tasks before they come: the compiled
    passes loaded (:func:`expdesign.montecarlo.warm_compiled`) and the heap grown to the largest
    task's working set (:func:`expdesign.dask_preload.grow_heap`, as a preloaded Dask worker), so
    that its first task costs what a later one does (a fresh worker's first task: 33-75 ms more,
    Stop 56). ``sh`` must hold a design named "random"."""
    from expdesign.dask_preload import grow_heap

    warm_compiled(sh)
    grow_heap(sh)


def evaluate_designs_parallel(
    profile: ShipProfile,
    designs: Mapping[str, Any],
    runs: int = 500,
    seed: int = 0,
    *,
    scheduler: Any = None,
    chunk_runs: int | None = None,
    tasks_per_worker: int = 4,
    progress: bool = True,
    primitives: list[Primitive] | None = None,
    disturbances: Disturbances | None = None,
    **protocol: Any,
) -> MCEvaluation:
    """:func:`expdesign.montecarlo.evaluate_designs` cut into (design, runs) tasks on an engine of ``expdesign.parallel``
    (all local cores by default, "inline", or a Dask scheduler / cluster). The engine is asked
    for its workers and threads and gets up to ``tasks_per_worker`` tasks per worker (:func:`plan_tasks`); the
    shared inputs are computed once here and shipped once per worker. The per-run numbers are
    bit-identical to one in-process call."""
    from expdesign.parallel import LocalEngine, get_engine

    cfg = MCConfig(runs=runs, seed=seed, **protocol)
    sh = prepare(profile, designs, cfg, primitives, disturbances)
    engine = get_engine(scheduler)
    t0 = time.perf_counter()
    try:
        workers, threads = engine.capacity()
        tasks = cut_tasks(sh.designs, runs, plan_tasks(runs, len(sh.designs), workers * threads, tasks_per_worker, chunk_runs))
        if isinstance(engine, LocalEngine) and engine.pool is None and min(workers, len(tasks)) > 1:
            warm_compiled(sh)  # once here, not once per worker (a warm pool's workers warmed themselves)
        res = engine.map(
            _task, tasks, desc="Monte Carlo", progress=progress, shared=sh, weights=[b - a for _, a, b in tasks], unit="runs"
        )
    finally:
        if engine is not scheduler:
            engine.close()
    elapsed = time.perf_counter() - t0
    parts = [{r.name: r} for r in res.finished()]
    results = merge_results(parts) if parts else {}
    errors = [f"task {tasks[i][0]} runs {tasks[i][1]}..{tasks[i][2] - 1}: {msg}" for i, msg in sorted(res.errors.items())]
    info = {
        "name": engine.name,
        "workers": workers,
        "threads_per_worker": threads,
        "tasks": len(tasks),
        "tasks_per_worker": len(tasks) / max(1, workers * threads),
        "runs_per_task": max(b - a for _, a, b in tasks),
    }
    return MCEvaluation(
        results,
        cfg,
        res.complete,
        res.interrupted,
        errors,
        elapsed,
        info,
        profile.sample_time,
        profile.name,
        asdict(sh.dist),
        profile.library,
        tuple(sh.designs),
    )
