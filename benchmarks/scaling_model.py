"""The task-cost model of ``python benchmarks/bench_design.py --scaling`` (issue 14, issue 30).

- a task of n runs of design d costs F_d + n p_d CPU seconds, fitted per design from tasks of 16,
  63, 250 and 500 runs (F is the simulation kernel's time loops, paid per batch whatever its size),
  robustly: the least CPU of 3 repeats per size, Siegel's repeated-median line, F >= 0;
- the pool's serial part s(W) (forking W workers holding the shared inputs, collecting, joining),
  measured with no-op tasks as the parent's CPU plus one worker's;
- a process's first task costs more than the same task in a warm process (a new process grows its
  heap to the task's working set: page faults), measured at the two task sizes the engines cut for
  2,000 x 2 runs (125 and 250 runs; interpolated between them, held beyond: it is not proportional
  to the runs, 1-run tasks already pay part of it); as in a command, inline pays it once and every
  worker once (in parallel);
- predicted wall(W) = s(W) + the finish time of the engines' own task list (same cut as
  ``evaluate_designs_parallel``) taken in order by the first free of W workers; inline = the sum
  of the inline tasks; speed-up = inline / wall(W), efficiency = speed-up / W, also without s(W).
- CPU inflation per worker count: the measured CPU over the model's CPU, relative to inline's, applied
  to the workers' tasks (a worker count not measured takes the largest measured one's figure).
- a warm pool (:mod:`benchmarks.scaling_warm`): the same tasks, the workers forked and warmed before
  the Monte Carlo, so no fork and no join on its path; predicted with its own start terms and first-task extra.
The model is checked against the measured engines: its CPU (tasks + prepare + pool) beside the
measured CPU for any worker count (local x3 and x4 on a 2-core machine check the fixed-cost term),
its wall beside the measured wall where the machine has the cores. It leaves out what a 16-core
machine adds (shared caches and memory bandwidth, a lower all-core clock), so it is an upper bound.
"""

from __future__ import annotations

import heapq
import os
import resource
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from expdesign.montecarlo import MCShared
from primitives.library import Primitive, model_ship_thesis
from primitives.ship import ShipProfile, load_profile


def setup() -> tuple[ShipProfile, list[Primitive], dict[str, object]]:
    """The model ship, its primitive library and the two designs the scaling benchmark times."""
    from expdesign.api import run_design
    from primitives.heap import keep_freed_memory

    # the task cost fitted as the pools' workers run it (freed memory kept, primitives.heap); the inline
    # rows measured in this process run so too, a little faster than a library caller's inline engine,
    # so an efficiency against them is the stricter one
    keep_freed_memory(always=True)
    p = load_profile("model-ship")
    lib = model_ship_thesis(p)
    return p, lib, {"optimized": run_design(p, lib).weights, "random": "random"}


SIZES = (16, 63, 250, 500)  # runs per task of the cost fit


@dataclass
class TaskCost:
    """CPU seconds of one task of ``n`` runs of a design: ``fixed[d] + n * per_run[d]``."""

    fixed: dict[str, float]
    per_run: dict[str, float]

    def of(self, tasks: list[tuple[str, int, int]]) -> list[float]:
        return [self.fixed[d] + (b - a) * self.per_run[d] for d, a, b in tasks]


def fit_task_cost(sh: MCShared, sizes: tuple[int, ...] = SIZES, repeat: int = 3) -> TaskCost:
    """The line F_d + n p_d through the CPU time of tasks of ``sizes`` runs, per design (each
    repeat on other runs), over the task sizes the engines cut (16 to 500 runs), made robust to
    a loaded machine (:func:`robust_line`): per size the least CPU of the repeats (other
    processes only ever add CPU time: cache and memory contention), F clipped at 0 (p is not
    clipped). The worst relative residual of the line is printed, so a curve
    (e.g. an iteration count that grows with the batch) shows."""
    from expdesign.montecarlo import run_chunk

    fixed, per_run = {}, {}
    for d in sh.designs:
        cost = []
        for n in sizes:
            ts = []
            for k in range(repeat):
                t = time.process_time()
                run_chunk(sh, d, range(k * n, (k + 1) * n))
                ts.append(time.process_time() - t)
            cost.append(min(ts))
        fixed[d], per_run[d] = robust_line(sizes, cost)
        resid = max(abs(fixed[d] + n * per_run[d] - c) / c for n, c in zip(sizes, cost))
        print(
            f"task cost {d:9s} (CPU, least of {repeat} at {'/'.join(map(str, sizes))} runs: "
            f"{', '.join(f'{1e3 * c:.0f}' for c in cost)} ms): fixed {1e3 * fixed[d]:5.0f} ms "
            f"+ {1e3 * per_run[d]:5.2f} ms per run (worst residual of the line {100 * resid:.0f} %)"
        )
    return TaskCost(fixed, per_run)


def robust_line(sizes: Sequence[int], cost: Sequence[float]) -> tuple[float, float]:
    """(F, p) of cost = F + n p by Siegel's (1982) repeated medians: p the median over the points
    of each point's median slope to the others, F the median of cost - n p, clipped at 0. One
    point of four spoilt by load moves neither (half the points may be), where the
    least-squares line fitted on times taken under load gave negative fixed costs, which the
    makespan model cannot use."""
    n, c = np.asarray(sizes, float), np.asarray(cost, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        slopes = (c[None, :] - c[:, None]) / (n[None, :] - n[:, None])
    np.fill_diagonal(slopes, np.nan)
    p = float(np.median(np.nanmedian(slopes, axis=1)))
    return max(0.0, float(np.median(c - n * p))), p


def _noop(item: int, shared: MCShared) -> int:
    return item


def pool_overhead(sh: MCShared, w: int, repeat: int = 5) -> dict[str, float]:
    """The pool machinery alone: fork ``w`` workers that hold the shared inputs, one no-op task
    each, collect, shut down (medians of ``repeat``). Seconds: ``wall`` on this machine, ``cpu``
    of the parent and the workers; ``fork``, the parent's CPU per fork, and ``child``, one worker's
    CPU (its start and exit): the pool feeds each worker as soon as it is forked
    (:mod:`expdesign.forkpool`), so worker k starts its first task (k + 1) forks + one child's start
    after the pool does (:func:`pool_starts`), while the others already compute; ``serial``, the
    rest of the parent's CPU, which no worker overlaps (stopping and joining the workers, setting
    up the pool and its progress)."""
    from expdesign.parallel import LocalEngine

    runs = []
    for _ in range(repeat):
        t, c, k = time.perf_counter(), time.process_time(), children_cpu_s()
        with LocalEngine(w) as eng:
            eng.map(_noop, list(range(w)), progress=False, shared=sh)
        parent, kids = time.process_time() - c, children_cpu_s() - k
        forks = eng.times.forks
        runs.append(
            {
                "wall": time.perf_counter() - t,
                "cpu": parent + kids,
                "fork": statistics.median(forks),
                "child": kids / w,
                "serial": parent - sum(forks),
            }
        )
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def pool_starts(pool: dict[str, float], w: int) -> list[float]:
    """When each of ``w`` workers of the local pool can start its first task (:func:`pool_overhead`)."""
    return [(k + 1) * pool["fork"] + pool["child"] for k in range(w)]


def _timed_task(item: tuple[str, int, int], shared: MCShared) -> float:
    from expdesign.montecarlo import run_chunk

    t = time.process_time()
    run_chunk(shared, item[0], range(item[1], item[2]))
    return time.process_time() - t


_TASKS_RUN = 0  # tasks this process has run through _first_and_second


def _first_and_second(items: list[tuple[str, int, int]], shared: MCShared) -> tuple[int, float, float]:
    """Two tasks one after the other in this process: (tasks it ran before, CPU of each)."""
    global _TASKS_RUN
    before, _TASKS_RUN = _TASKS_RUN, _TASKS_RUN + 1
    return before, _timed_task(items[0], shared), _timed_task(items[1], shared)


def first_task_extra(sh: MCShared, n: int, repeat: int = 2) -> float:
    """Extra CPU seconds of a fresh worker's first task of ``n`` runs over its second (other runs of
    the same design and size, in the same worker): a new process grows its heap to the task's
    working set (page faults), once. Both tasks run beside the pool's other worker, so the CPU
    inflation of processes running at once (measured apart, :func:`_inflation`) is not counted here
    as well."""
    from expdesign.parallel import LocalEngine

    extra = []
    for _ in range(repeat):
        with LocalEngine(2) as eng:
            extra += first_extras(eng, sh, n, 2)
    return max(0.0, statistics.median(extra))


def first_extras(engine: object, sh: MCShared, n: int, w: int) -> list[float]:
    """``w`` pairs of tasks of ``n`` runs on ``engine``: the extra CPU seconds of each worker's first
    such task over its second (workers that got two pairs count once)."""
    pairs = [[("random", (2 * k + j) * n, (2 * k + j + 1) * n) for j in range(2)] for k in range(w)]
    res = engine.map(_first_and_second, pairs, progress=False, shared=sh).results
    return [first - second for before, first, second in res if before == 0]  # a worker's own first task


EXTRA_SIZES = (125, 250)  # runs per task at which a fresh worker's first task is measured


def first_extra_curve(sh: MCShared, sizes: tuple[int, ...] = EXTRA_SIZES) -> Callable[[int], float]:
    """A fresh worker's first-task extra CPU seconds against the task's runs: measured at ``sizes``
    (:func:`first_task_extra`), linear between them and held beyond."""
    extra = [first_task_extra(sh, n) for n in sizes]
    print(
        "a worker's first task costs more than in a warm process (heap growth: page faults): "
        + ", ".join(f"{1e3 * e:.0f} ms at {n} runs" for n, e in zip(sizes, extra))
    )
    return lambda n: float(np.interp(n, sizes, extra))


def makespan(costs: list[float], w: int, first_extra: float = 0.0, starts: Sequence[float] = ()) -> float:
    """Finish time of ``costs`` taken in submission order by whichever of ``w`` workers is free
    first (what the process pool and Dask's scheduler do with equal-priority tasks); each
    worker's first task costs ``first_extra`` more; worker i is free from ``starts[i]`` (0 if not given)."""
    free = sorted((starts[i] if i < len(starts) else 0.0, i) for i in range(w))
    started = set()
    for c in costs:
        t, i = free[0]
        heapq.heapreplace(free, (t + c + (first_extra if i not in started else 0.0), i))
        started.add(i)
    return max(t for t, _ in free)


def predict(
    cost: TaskCost,
    designs: list[str],
    runs: int,
    w: int,
    serial: float,
    tasks_per_worker: int | None = None,
    first_extra: Callable[[int], float] = lambda n: 0.0,
    inflation: float = 1.0,
    per_task: float = 0.0,
    starts: Sequence[float] = (),
) -> dict:
    """Predicted wall time on ``w`` otherwise idle cores: the parent's serial time (pool start and
    stop, Amdahl) plus the makespan of the tasks cut as the engines cut them, in fresh processes
    (as a command runs: inline pays ``first_extra`` once, each worker once). ``inflation``: the
    measured CPU of W processes over what the model counts (shared caches, memory bandwidth,
    threads: CPU the workers burn that a warm single process does not), multiplying every task;
    ``per_task``: the engine's own CPU seconds per task (Dask's), added to every task; ``starts``:
    when each worker can take its first task (:func:`pool_starts`; 0 if not given);
    ``tasks_per_worker``: that many tasks per worker whatever their size, instead of the engine's
    cut (:func:`expdesign.mc_parallel.plan_tasks`, which takes fewer when they would be small)."""
    from expdesign.mc_parallel import cut_tasks, plan_tasks

    nd = len(designs)
    chunk_runs = -(-runs * nd // (tasks_per_worker * w)) if tasks_per_worker else None
    tasks = cut_tasks(designs, runs, plan_tasks(runs, nd, w, chunk_runs=chunk_runs))
    costs = [c * inflation + per_task for c in cost.of(tasks)]
    chunk = max(b - a for _, a, b in tasks)
    extra = first_extra(chunk) * inflation
    compute = makespan(costs, w, extra, starts)
    return {"tasks": len(tasks), "chunk": chunk, "cpu": sum(costs) + w * extra, "compute": compute, "wall": serial + compute}


def task_cost(runs: int, workers: list[int], measured: list[dict]) -> None:
    """The task-cost model, checked against the measured engines, and the speed-up and
    efficiency it predicts per worker count up to 16 (goal there: 70 %) on an idle machine."""
    from expdesign.montecarlo import MCConfig, prepare

    p, lib, designs = setup()
    t = time.process_time()
    sh = prepare(p, designs, MCConfig(runs=max(runs, 3 * max(SIZES))), lib)
    prep = time.process_time() - t
    cost = fit_task_cost(sh)
    names = list(sh.designs)
    counts = sorted({1, 2, 3, 4, 8, 16, *workers})
    pool = {w: pool_overhead(sh, w) for w in counts if w > 1}
    serial = {1: 0.0} | {w: v["serial"] for w, v in pool.items()}
    starts = {w: pool_starts(v, w) for w, v in pool.items()}
    first = first_extra_curve(sh)
    print(
        f"serial in the parent: shared inputs {1e3 * prep:.0f} ms CPU (prepare(), before the clock starts, the same for every "
        "engine); the pool with W workers (no-op tasks; wall here in brackets): the parent's CPU per fork, a worker's start "
        "and exit, and the parent's serial rest (stop, join): "
        + ", ".join(
            f"{w}: {1e3 * v['fork']:.1f} + {1e3 * v['child']:.1f} + {1e3 * v['serial']:.0f} ms ({1e3 * v['wall']:.0f})"
            for w, v in pool.items()
        )
        + "; the last worker starts its first task "
        + ", ".join(f"{w}: {1e3 * s[-1]:.0f} ms" for w, s in starts.items())
        + " after the pool does"
    )
    modelled = {}
    for row in (
        r for r in measured if r["label"] == "inline" or r["label"].startswith("local")
    ):  # CPU any machine, wall <= cores
        fresh = row["slots"] > 1  # the pools' workers are new processes, the inline runs reuse this warm one
        pr = predict(
            cost,
            names,
            runs,
            row["slots"],
            serial.get(row["slots"], 0.0),
            first_extra=lambda n, f=fresh: first(n) * f,
            starts=starts.get(row["slots"], ()),
        )
        cpu = pr["cpu"] + prep + (pool[row["slots"]]["cpu"] if row["slots"] > 1 else 0.0)
        modelled[row["slots"]] = row["cpu"] / cpu
        print(
            f"  model vs measured {row['label']:12s}: CPU {cpu:6.2f} s vs {row['cpu']:6.2f} s (inflation {row['cpu'] / cpu:4.2f}); "
            f"wall {pr['wall']:6.2f} s vs "
            f"{row['wall']:6.2f} s{'' if row['slots'] <= (os.cpu_count() or 1) else ' (more workers than CPUs: wall not comparable)'}"
        )
    infl = _inflation(modelled)
    _predicted(cost, names, runs, serial, f"{runs} runs x {len(names)} designs", first, infl, starts=starts)
    _warm_model(sh, cost, names, runs, counts, first, infl)
    dask_rows = [r for r in measured if r["label"].startswith("dask x")]
    if dask_rows:
        _dask_model(cost, names, runs, sh, prep, dask_rows, modelled.get(1, 1.0), first, infl)
    # `shiptrial design --monte-carlo 500` evaluates 4 designs; uniform and thesis cost as the optimized one (fixed shares)
    cost.fixed |= {k: cost.fixed["optimized"] for k in ("uniform", "thesis")}
    cost.per_run |= {k: cost.per_run["optimized"] for k in ("uniform", "thesis")}
    _predicted(
        cost,
        ["optimized", "random", "uniform", "thesis"],
        500,
        serial,
        "shiptrial design --monte-carlo 500 (4 designs)",
        first,
        infl,
        starts=starts,
    )


def _warm_model(
    sh: MCShared,
    cost: TaskCost,
    names: list[str],
    runs: int,
    counts: list[int],
    first: Callable[[int], float],
    infl: Callable[[int], float],
) -> None:
    """The same prediction for a warm pool (:mod:`benchmarks.scaling_warm`): no fork and no join on
    the Monte Carlo's path, each worker's start its share of the map's sending plus its unpickling,
    its first task's extra as measured on warm workers; the local pool's CPU inflation."""
    from benchmarks.scaling_warm import print_warm_terms, warm_first_extra_curve, warm_pool_overhead, warm_starts

    pools = {w: warm_pool_overhead(sh, w) for w in counts if w > 1}
    print_warm_terms(pools)
    _predicted(
        cost,
        names,
        runs,
        {1: 0.0} | dict.fromkeys(pools, 0.0),
        f"warm pool (started before the Monte Carlo), {runs} runs x {len(names)} designs",
        first,
        infl,
        starts={w: warm_starts(v, w) for w, v in pools.items()},
        worker_first=warm_first_extra_curve(sh),
    )


def _dask_model(
    cost: TaskCost,
    names: list[str],
    runs: int,
    sh: MCShared,
    prep: float,
    rows: list[dict],
    base: float,
    first: Callable[[int], float],
    pool_inflation: Callable[[int], float],
) -> None:
    """The same model for the local Dask clusters measured (warm workers): Dask's serial part a + b W and
    CPU per task (:func:`benchmarks.scaling_dask.dask_overhead`), its CPU inflation relative to inline's,
    the 16-worker prediction; and with new workers that were not preloaded, each worker's first-run
    cost (the measured first run's extra CPU per worker) on top.

    Dask's housekeeping (heartbeats, the event loops, the scheduler's periodic work) costs CPU per
    second of wall, whatever the tasks: on a loaded machine, where a run's wall is many times its
    CPU, it would read as CPU inflation of the tasks. It is measured on the idle cluster
    (:func:`benchmarks.scaling_dask.idle_rates`), taken out of each measured run's CPU at its wall
    before the inflation is computed, and put back where it acts on W cores: each worker's own
    share slows its tasks by 1 / (1 - its rate); the client's and scheduler's run on the parent's
    core, beside the tasks. The inflation is taken no lower than the local pool's
    (``pool_inflation``): the same tasks in single-thread processes on the same cores; a lower
    figure means the housekeeping taken out was over-counted (under load it can be 40 % of the
    measured CPU, so a small error in its rate moves the inflation by several per cent)."""
    from benchmarks.scaling_dask import dask_overhead, print_overhead

    ov = dask_overhead(sh, sorted({r["slots"] for r in rows}))
    print_overhead(ov)
    serial = {w: ov["a"] + ov["b"] * w for w in (1, 2, 3, 4, 8, 16)}
    modelled = {1: base}
    for row in rows:
        w = row["slots"]
        pr = predict(cost, names, runs, w, serial[w], per_task=ov["per_task"])
        cpu = pr["cpu"] + prep + serial[w]
        house = (row["idle_parent"] + w * row["idle_worker"]) * row["wall"]
        modelled[w] = (row["cpu"] - house) / cpu
        cold = (row["first_cpu"] - row["cpu"]) / w
        print(
            f"  model vs measured {row['label']:12s}: CPU {cpu:6.2f} s vs {row['cpu']:6.2f} s, of which housekeeping "
            f"{house:5.2f} s (idle cluster: {1e3 * row['idle_parent']:.0f} ms a second in this process, "
            f"{1e3 * row['idle_worker']:.0f} in each worker; inflation {modelled[w]:4.2f} without it, {row['cpu'] / cpu:4.2f} with); "
            f"wall {pr['wall']:6.2f} s vs {row['wall']:6.2f} s; a new worker's first run: {cold:.2f} s CPU more per worker"
        )
    rate = statistics.median(r["idle_worker"] for r in rows)
    measured = _inflation(modelled)
    floored = sorted(w for w in modelled if measured(w) < pool_inflation(w))
    if floored:
        print(
            "  Dask's inflation taken at the local pool's where it measured lower (housekeeping over-counted): "
            + ", ".join(f"{w} workers {modelled[w] / base:4.2f} -> {pool_inflation(w):4.2f}" for w in floored)
        )
    infl = dask_inflation(measured, pool_inflation, rate)
    how = "not preloaded" if any("no preload" in r["label"] for r in rows) else "preloaded"
    # a preloaded worker's heap is grown before its first task (expdesign.dask_preload.grow_heap): its
    # first task's extra is measured on Dask's own new workers; without the preload, the local pool's
    worker_first = first if how == "not preloaded" or ov["first_extra"] is None else (lambda n: ov["first_extra"])
    _predicted(
        cost,
        names,
        runs,
        serial,
        f"Dask, warm single-thread workers, {runs} runs x {len(names)} designs",
        first,
        infl,
        ov["per_task"],
        worker_first=worker_first,
    )
    cold = max(0.0, statistics.median((r["first_cpu"] - r["cpu"]) / r["slots"] for r in rows))
    inline = predict(cost, names, runs, 1, 0.0, first_extra=first)["wall"]
    pr = predict(cost, names, runs, 16, serial[16] + cold, per_task=ov["per_task"], inflation=infl(16), first_extra=worker_first)
    print(
        f"  16 new workers, {how} as measured (a worker's first run cost {cold:.2f} s CPU more than a warm one's): "
        f"efficiency {inline / pr['wall'] / 16:4.2f}"
    )
    preload = statistics.median(r.get("preload_cpu", 0.0) for r in rows)
    if preload > 0:  # the workers preload in parallel as they start: a command that starts them waits that long
        pr = predict(
            cost,
            names,
            runs,
            16,
            serial[16] + cold + preload,
            per_task=ov["per_task"],
            inflation=infl(16),
            first_extra=worker_first,
        )
        print(
            f"  16 workers started for the command, counting their preload ({preload:.2f} s CPU each, measured, in parallel): "
            f"efficiency {inline / pr['wall'] / 16:4.2f}"
        )


def dask_inflation(dask: Callable[[int], float], pool: Callable[[int], float], rate: float) -> Callable[[int], float]:
    """Dask's CPU inflation per worker count for the prediction: its own (housekeeping taken out),
    no lower than the local pool's (the same tasks in single-thread processes on the same cores),
    times 1 / (1 - ``rate``), the share of its core a worker's housekeeping takes."""
    return lambda w: max(dask(w), pool(w)) / (1.0 - rate)


def _inflation(measured: dict[int, float]) -> Callable[[int], float]:
    """CPU inflation per worker count W: measured CPU over the model's CPU, relative to inline's
    (so inline is 1). A W that was not measured takes the largest measured W's inflation at or
    below it (on a 2-core machine, the 4-process figure stands for 16: an assumption the output
    says; shared caches and memory bandwidth of a real many-core machine may add more)."""
    base = measured.get(1, 1.0)
    rel = {w: max(1.0, v / base) for w, v in measured.items()}
    if rel:
        print(
            "CPU inflation (measured CPU / modelled CPU, relative to inline): "
            + ", ".join(f"{w} workers {v:4.2f}" for w, v in sorted(rel.items()))
            + f"; more workers than measured take the {max(rel)}-worker figure"
        )
    return lambda w: rel.get(w) or next((rel[k] for k in sorted(rel, reverse=True) if k <= w), 1.0)


def _predicted(
    cost: TaskCost,
    names: list[str],
    runs: int,
    serial: dict[int, float],
    what: str,
    first: Callable[[int], float],
    inflation: Callable[[int], float] = lambda w: 1.0,
    per_task: float = 0.0,
    starts: dict[int, list[float]] | None = None,
    worker_first: Callable[[int], float] | None = None,
) -> None:
    """Predicted wall, speed-up and efficiency per worker count in ``serial``, and at the most workers by tasks per
    worker; ``first``: a worker's first task's extra CPU seconds by its runs (:func:`first_extra_curve`); ``inflation``: the measured CPU inflation
    per worker count (:func:`_inflation`), applied to the workers' tasks; ``starts``: per worker count, when each
    worker can take its first task (:func:`pool_starts`; the local pool's); ``worker_first``: a worker's first-task
    extra where it differs from inline's ``first`` (Dask's preloaded workers)."""
    inline = predict(cost, names, runs, 1, 0.0, first_extra=first)["wall"]
    print(f"predicted on an idle machine with >= W cores, {what} (inline {inline:.2f} s):")
    for w in serial:
        extra = {"first_extra": worker_first or first, "starts": (starts or {}).get(w, ())}
        pr = predict(cost, names, runs, w, serial[w], inflation=inflation(w), per_task=per_task, **extra)
        pr0 = predict(cost, names, runs, w, serial[w], per_task=per_task, **extra)
        print(
            f"  {w:2d} workers: {pr['tasks']:3d} tasks of <= {pr['chunk']:3d} runs ({pr['tasks'] / w:4.1f} per worker)  wall {pr['wall']:6.2f} s  "
            f"speed-up {inline / pr['wall']:5.2f}  efficiency {inline / pr['wall'] / w:4.2f} with CPU inflation {inflation(w):4.2f} "
            f"({inline / pr0['wall'] / w:4.2f} without it; without the serial part {inline / pr['compute'] / w:4.2f})"
        )
    w = max(serial)
    extra = {"first_extra": worker_first or first, "starts": (starts or {}).get(w, ())}
    alt = ", ".join(
        f"{k}: {inline / predict(cost, names, runs, w, serial[w], k, inflation=inflation(w), per_task=per_task, **extra)['wall'] / w:4.2f}"
        for k in (1, 2, 3, 4, 8)
    )
    print(f"  {w} workers, efficiency by tasks per worker whatever their size (the engine's cut above): {alt}")


def cpu_s() -> float:
    """CPU seconds of this process and of its children that have exited (pool workers)."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    return me.ru_utime + me.ru_stime + children_cpu_s()


def children_cpu_s() -> float:
    """CPU seconds of this process's children that have exited."""
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return kids.ru_utime + kids.ru_stime
