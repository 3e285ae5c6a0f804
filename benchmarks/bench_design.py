"""Speed of the design step (issue 3 targets): prints the median of 5 runs and the ratio to target.

    python benchmarks/bench_design.py [--runs 5] [--mc-runs 500]
    python benchmarks/bench_design.py --scaling [--mc-runs 2000] [--workers 2 3] [--scheduler tcp://...] [--runs 3]

convex (7.18)/(7.53) solve for the 11 model-ship primitives: < 0.5 s; non-convex (7.57) multi-start
solve: < 1 s; Monte Carlo of one design with 500 runs of 1000 samples: < 20 s (2 cores).

``--scaling`` (issue 14): the optimized and the random design, ``--mc-runs`` runs each, inline and on
local pools of each ``--workers`` count (and a Dask scheduler if given): median wall time, the
SHA-256 digests of all per-run results (must equal inline's), tasks per worker, runs/s, speed-up
against inline and parallel efficiency (speed-up / workers). Target: >= 1.8x on 2 workers. Then the
fixed and per-run CPU cost of a task and the speed-up they predict per worker count up to 16 (goal
there: 70 % efficiency).
The wall-clock speed-up needs an otherwise idle machine (the load average is printed); the CPU
seconds of this process and its reaped workers give the load-independent bound
workers x CPU(inline) / CPU(pool), which shows the pool's own overhead.
"""

from __future__ import annotations

import argparse
import heapq
import os
import resource
import statistics
import time
from dataclasses import dataclass

import numpy as np

from expdesign.dopt import InfoSet, solve_convex
from expdesign.montecarlo import evaluate_designs
from expdesign.nonconvex import solve_nonconvex
from primitives.information import library_information
from primitives.library import model_ship_thesis
from primitives.ship import load_profile


def bench(name: str, fn, target: float, runs: int) -> float:
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    med = statistics.median(times)
    print(f"{name:45s} median {med:7.3f} s  target {target:5.1f} s  ratio {med / target:5.2f}  {'OK' if med <= target else 'SLOW'}")
    return med


def scaling(runs: int, workers: list[int], scheduler: str | None, repeat: int) -> list[dict]:
    """Inline against local pools (and a cluster): same digests, speed-up per worker count.
    Returns per engine: label, worker slots, runs per task, median wall and CPU seconds."""
    from expdesign.montecarlo import evaluate_designs_parallel
    from expdesign.parallel import Engine, LocalEngine, get_engine

    p, lib, designs = _setup()
    engines = [("inline", Engine)] + [(f"local x{w}", lambda w=w: LocalEngine(w)) for w in workers]
    if scheduler:
        engines.append((f"dask {scheduler}", lambda: get_engine(scheduler)))
    base = ref = base_cpu = None
    rows = []
    print(f"Monte Carlo scaling: {runs} runs x {len(designs)} designs, median of {repeat}; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    for label, make in engines:
        times, cpus = [], []
        for _ in range(repeat):
            c0 = _cpu_s()
            with make() as eng:
                ev = evaluate_designs_parallel(p, designs, runs=runs, seed=0, scheduler=eng, primitives=lib, progress=False)
            times.append(ev.elapsed_s)
            cpus.append(_cpu_s() - c0)
        med, cpu = statistics.median(times), statistics.median(cpus)
        base_cpu = base_cpu or cpu
        dig = {k: r.digest() for k, r in ev.results.items()}
        ref = ref or dig
        base = base or med
        e = ev.engine
        slots = e["workers"] * e["threads_per_worker"]
        rows.append({"label": label, "slots": slots, "wall": med, "cpu": cpu})
        print(f"{label:14s} {med:7.2f} s  {2 * runs / med:6.0f} runs/s  speed-up {base / med:5.2f}  efficiency "
              f"{base / med / slots:5.2f}  {e['tasks']:3d} tasks ({e['tasks_per_worker']:.1f} per worker, {e['runs_per_task']} runs each)  "
              f"digests {'same as inline' if dig == ref else 'DIFFER from inline'}")
        print(f"{'':14s} CPU {cpu:7.2f} s (this process and its workers): CPU-bound speed-up "
              f"{slots * base_cpu / cpu:5.2f} on an idle machine")
    return rows


def _setup():
    from expdesign.api import run_design

    p = load_profile("model-ship")
    lib = model_ship_thesis(p)
    return p, lib, {"optimized": run_design(p, lib).weights, "random": "random"}


@dataclass
class TaskCost:
    """CPU seconds of one task of ``n`` runs of a design: ``fixed[d] + n * per_run[d]``."""

    fixed: dict[str, float]
    per_run: dict[str, float]

    def of(self, tasks: list[tuple[str, int, int]]) -> list[float]:
        return [self.fixed[d] + (b - a) * self.per_run[d] for d, a, b in tasks]


def fit_task_cost(sh, sizes: tuple[int, ...] = (1, 63, 250), repeat: int = 3) -> TaskCost:
    """Least-squares line through the median CPU time of tasks of ``sizes`` runs, per design
    (each repeat on other runs). The fixed part is the simulation kernel's time loops (data, IV
    re-simulations, validation: 1000 steps each, whatever the batch); the worst relative
    residual of the line is printed, so a curve (e.g. iterations growing with the batch) shows."""
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
            cost.append(statistics.median(ts))
        per_run[d], fixed[d] = np.polyfit(sizes, cost, 1)
        resid = max(abs(fixed[d] + n * per_run[d] - c) / c for n, c in zip(sizes, cost))
        print(f"task cost {d:9s} (CPU, median of {repeat} at {'/'.join(map(str, sizes))} runs): fixed {1e3 * fixed[d]:5.0f} ms "
              f"+ {1e3 * per_run[d]:5.2f} ms per run (worst residual of the line {100 * resid:.0f} %)")
    return TaskCost(fixed, per_run)


def _noop(item: int, shared) -> int:
    return item


def pool_overhead(sh, w: int, repeat: int = 5) -> dict[str, float]:
    """The pool machinery alone: fork ``w`` workers that hold the shared inputs, one no-op task
    each, collect, shut down (medians of ``repeat``). Seconds: ``wall`` on this machine, ``cpu``
    of the parent and the workers, and ``serial``, the wall on an idle machine with >= w cores:
    the parent's CPU (the forks are made one after the other before any task starts, then the
    results and the joins) plus one worker's CPU (its start and exit, in parallel with the
    others'). The wall on a machine with fewer cores than workers also counts the workers
    queueing for a core."""
    from expdesign.parallel import LocalEngine

    runs = []
    for _ in range(repeat):
        t, c, k = time.perf_counter(), time.process_time(), _children_cpu_s()
        with LocalEngine(w) as eng:
            eng.map(_noop, list(range(w)), progress=False, shared=sh)
        parent, kids = time.process_time() - c, _children_cpu_s() - k
        runs.append({"wall": time.perf_counter() - t, "cpu": parent + kids, "serial": parent + kids / w})
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def makespan(costs: list[float], w: int) -> float:
    """Finish time of ``costs`` taken in submission order by whichever of ``w`` workers is free
    first (what the process pool and Dask's scheduler do with equal-priority tasks)."""
    free = [0.0] * w
    for c in costs:
        heapq.heapreplace(free, free[0] + c)
    return max(free)


def predict(cost: TaskCost, designs: list[str], runs: int, w: int, serial: float, tasks_per_worker: int = 4) -> dict:
    """Predicted wall time on ``w`` otherwise idle cores: the parent's serial time (pool start and
    stop, Amdahl) plus the makespan of the tasks cut as the engines cut them."""
    from expdesign.montecarlo import cut_tasks, plan_tasks

    tasks = cut_tasks(designs, runs, plan_tasks(runs, len(designs), w, tasks_per_worker))
    costs = cost.of(tasks)
    compute = makespan(costs, w)
    return {"tasks": len(tasks), "chunk": max(b - a for _, a, b in tasks), "cpu": sum(costs), "compute": compute,
            "wall": serial + compute}


def task_cost(runs: int, workers: list[int], measured: list[dict]) -> None:
    """The task-cost model, checked against the measured engines, and the speed-up and
    efficiency it predicts per worker count up to 16 (goal there: 70 %) on an idle machine."""
    from expdesign.montecarlo import MCConfig, prepare

    p, lib, designs = _setup()
    t = time.process_time()
    sh = prepare(p, designs, MCConfig(runs=max(runs, 750)), lib)
    prep = time.process_time() - t
    cost = fit_task_cost(sh)
    names = list(sh.designs)
    counts = sorted({1, 2, 3, 4, 8, 16, *workers})
    pool = {w: pool_overhead(sh, w) for w in counts if w > 1}
    serial = {1: 0.0} | {w: v["serial"] for w, v in pool.items()}
    print(f"serial in the parent: shared inputs {1e3 * prep:.0f} ms CPU (prepare(), before the clock starts, the same for every "
          "engine); pool start + stop with W workers, serial part on an idle machine (wall here): "
          + ", ".join(f"{w}: {1e3 * v['serial']:.0f} ms ({1e3 * v['wall']:.0f})" for w, v in pool.items()))
    inline = predict(cost, names, runs, 1, 0.0)["wall"]
    for row in (r for r in measured if not r["label"].startswith("dask")):  # CPU on any machine, wall up to the core count
        pr = predict(cost, names, runs, row["slots"], serial.get(row["slots"], 0.0))
        cpu = pr["cpu"] + prep + (pool[row["slots"]]["cpu"] if row["slots"] > 1 else 0.0)
        print(f"  model vs measured {row['label']:12s}: CPU {cpu:6.2f} s vs {row['cpu']:6.2f} s; wall {pr['wall']:6.2f} s vs "
              f"{row['wall']:6.2f} s{'' if row['slots'] <= (os.cpu_count() or 1) else ' (more workers than CPUs: wall not comparable)'}")
    print(f"predicted on an idle machine with >= W cores, {runs} runs x {len(names)} designs (inline {inline:.2f} s):")
    for w in counts:
        pr = predict(cost, names, runs, w, serial[w])
        print(f"  {w:2d} workers: {pr['tasks']:3d} tasks of {pr['chunk']:3d} runs ({pr['tasks'] / w:4.1f} per worker)  wall {pr['wall']:6.2f} s  "
              f"speed-up {inline / pr['wall']:5.2f}  efficiency {inline / pr['wall'] / w:4.2f}  "
              f"(without the serial part {inline / pr['compute'] / w:4.2f})")
    w = 16
    alt = ", ".join(f"{k} per worker {inline / predict(cost, names, runs, w, serial[w], k)['wall'] / w:4.2f}" for k in (1, 2, 3, 4, 8))
    print(f"  16 workers, efficiency by tasks per worker (the issue asks for >= 4): {alt}")


def _cpu_s() -> float:
    """CPU seconds of this process and of its children that have exited (pool workers)."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    return me.ru_utime + me.ru_stime + _children_cpu_s()


def _children_cpu_s() -> float:
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return kids.ru_utime + kids.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--mc-runs", type=int, default=500)
    ap.add_argument("--scaling", action="store_true", help="Monte Carlo inline vs worker counts (issue 14)")
    ap.add_argument("--workers", type=int, nargs="*", default=[2])
    ap.add_argument("--scheduler", default=None, help="also time this Dask scheduler address")
    a = ap.parse_args()
    if a.scaling:
        rows = scaling(a.mc_runs, a.workers, a.scheduler, a.runs)
        task_cost(a.mc_runs, a.workers, rows)
        return
    p = load_profile("model-ship")
    lib = model_ship_thesis(p)
    info = InfoSet.from_infos(library_information(p, lib))
    solve_convex(info)  # import cvxpy and warm caches once
    cvx = solve_convex(info, "D", "complete")
    bench("convex D-optimal, 11 primitives (Clarabel)", lambda: solve_convex(info, "D", "complete"), 0.5, a.runs)
    bench("non-convex (7.57), 6 starts (SLSQP)", lambda: solve_nonconvex(info, convex_start=cvx.weights, n_random=4), 1.0, a.runs)
    w = dict(zip(info.names, np.round(cvx.weights, 6)))
    bench(f"Monte Carlo, 1 design, {a.mc_runs} runs x 1000 samples",
          lambda: evaluate_designs(p, {"optimized": w}, runs=a.mc_runs, seed=0, primitives=lib), 20.0, a.runs)


if __name__ == "__main__":
    main()
