"""The Monte Carlo of :mod:`expdesign.montecarlo` cut into (design, runs) tasks and run on an engine
of :mod:`expdesign.parallel` (inline, a local process pool or a Dask cluster).

The engine is asked for its workers and threads and gets at least ``tasks_per_worker`` tasks per
worker slot, in near-equal run ranges; the shared inputs (:class:`expdesign.montecarlo.MCShared`)
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

    @property
    def runs_finished(self) -> dict[str, int]:
        return {k: len(r.runs) for k, r in self.results.items()}


def _task(item: tuple[str, int, int], shared: MCShared) -> MCResult:
    design, a, b = item
    return run_chunk(shared, design, range(a, b))


def plan_tasks(runs: int, n_designs: int, slots: int, tasks_per_worker: int = 4, chunk_runs: int | None = None) -> int:
    """Tasks per design: together at least ``tasks_per_worker`` per worker slot (load balance and
    progress), each of at most MAX_CHUNK runs (or ``chunk_runs``, which then alone decides).

    Not more: a task's cost is a fixed part (the simulation kernel's time loops, paid once per
    batch whatever its size) plus a part per run, so every extra task adds the fixed part to the
    total; ``python benchmarks/bench_design.py --scaling`` measures both and predicts the
    efficiency per worker count."""
    cap = max(1, min(chunk_runs or MAX_CHUNK, MAX_CHUNK))
    n = -(-runs // cap)
    if slots > 1 and not chunk_runs:
        n = max(n, -(-tasks_per_worker * slots // n_designs))
    return max(1, min(runs, n))


def cut_tasks(designs: Sequence[str], runs: int, n: int) -> list[tuple[str, int, int]]:
    """(design, first run, end run): ``n`` ranges per design whose sizes differ by at most one
    (no short tail task paying the fixed cost for a few runs), design by design as submitted."""
    return [(d, i * runs // n, (i + 1) * runs // n) for d in designs for i in range(n)]


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
    for its workers and threads and gets at least ``tasks_per_worker`` tasks per worker; the
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
        if isinstance(engine, LocalEngine) and min(workers, len(tasks)) > 1:
            warm_compiled(sh)  # once here, not once per worker
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
    )
