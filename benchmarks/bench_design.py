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
import os
import resource
import statistics
import time

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


def scaling(runs: int, workers: list[int], scheduler: str | None, repeat: int) -> None:
    """Inline against local pools (and a cluster): same digests, speed-up per worker count."""
    from expdesign.api import run_design
    from expdesign.montecarlo import evaluate_designs_parallel
    from expdesign.parallel import Engine, LocalEngine, get_engine

    p = load_profile("model-ship")
    lib = model_ship_thesis(p)
    designs = {"optimized": run_design(p, lib).weights, "random": "random"}
    engines = [("inline", Engine)] + [(f"local x{w}", lambda w=w: LocalEngine(w)) for w in workers]
    if scheduler:
        engines.append((f"dask {scheduler}", lambda: get_engine(scheduler)))
    base = ref = base_cpu = None
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
        print(f"{label:14s} {med:7.2f} s  {2 * runs / med:6.0f} runs/s  speed-up {base / med:5.2f}  efficiency "
              f"{base / med / slots:5.2f}  {e['tasks']:3d} tasks ({e['tasks_per_worker']:.1f} per worker, {e['runs_per_task']} runs each)  "
              f"digests {'same as inline' if dig == ref else 'DIFFER from inline'}")
        print(f"{'':14s} CPU {cpu:7.2f} s (this process and its workers): CPU-bound speed-up "
              f"{slots * base_cpu / cpu:5.2f} on an idle machine")


def task_cost(runs: int, workers: list[int]) -> None:
    """CPU cost of one Monte Carlo task: a fixed part (the simulation kernel's time loops: data, IV
    re-simulations, validation; paid once per task whatever its size) and a part per run, fitted
    from tasks of 1 and 250 runs; then the efficiency those predict for ``runs`` x 2 designs cut
    as the engines cut them (at least 4 tasks per worker), on an otherwise idle machine."""
    from expdesign.api import run_design
    from expdesign.montecarlo import MCConfig, plan_tasks, prepare, run_chunk

    p = load_profile("model-ship")
    lib = model_ship_thesis(p)
    sh = prepare(p, {"optimized": run_design(p, lib).weights, "random": "random"}, MCConfig(runs=max(runs, 250)), lib)
    cost = {}
    for n in (1, 250):
        ts = []
        for _ in range(3):
            t = time.process_time()
            for d in sh.designs:
                run_chunk(sh, d, range(n))
            ts.append((time.process_time() - t) / len(sh.designs))
        cost[n] = statistics.median(ts)
    per_run = (cost[250] - cost[1]) / 249
    fixed = cost[1] - per_run
    print(f"task cost (CPU, median of 3): fixed {1e3 * fixed:.0f} ms per task + {1e3 * per_run:.2f} ms per run")
    inline = 2 * -(-runs // plan_tasks(runs, 2, 1)) * fixed + 2 * runs * per_run
    for w in sorted({*workers, 16}):
        chunk = plan_tasks(runs, 2, w)
        tasks = 2 * -(-runs // chunk)
        wall = -(-tasks // w) * (fixed + chunk * per_run)
        print(f"  {w:2d} workers: {tasks} tasks of {chunk} runs ({tasks / w:.1f} per worker), predicted speed-up "
              f"{inline / wall:5.2f}, efficiency {inline / wall / w:4.2f}")


def _cpu_s() -> float:
    """CPU seconds of this process and of its children that have exited (pool workers)."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--mc-runs", type=int, default=500)
    ap.add_argument("--scaling", action="store_true", help="Monte Carlo inline vs worker counts (issue 14)")
    ap.add_argument("--workers", type=int, nargs="*", default=[2])
    ap.add_argument("--scheduler", default=None, help="also time this Dask scheduler address")
    a = ap.parse_args()
    if a.scaling:
        scaling(a.mc_runs, a.workers, a.scheduler, a.runs)
        task_cost(a.mc_runs, a.workers)
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
