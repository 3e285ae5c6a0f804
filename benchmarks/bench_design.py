"""Speed of the design step (issue 3 targets): prints the median of 5 runs and the ratio to target.

    python benchmarks/bench_design.py [--runs 5] [--mc-runs 500]
    python benchmarks/bench_design.py --scaling [--mc-runs 2000] [--workers 2 3] [--scheduler tcp://...] [--runs 3] [--model-only]
        [--dask-local 2 4 [--no-preload]]
    python benchmarks/bench_design.py --threads
    python benchmarks/bench_design.py --profile-task

convex (7.18)/(7.53) solve for the 11 model-ship primitives: < 0.5 s; non-convex (7.57) multi-start
solve: < 1 s; Monte Carlo of one design with 500 runs of 1000 samples: < 20 s (2 cores).

``--scaling`` (issue 14): the optimized and the random design, ``--mc-runs`` runs each, inline and on
local pools of each ``--workers`` count (and a Dask scheduler if given, and local Dask clusters of
each ``--dask-local`` count: :mod:`benchmarks.scaling_dask`, modelled apart): median wall time, the
SHA-256 digests of all per-run results (must equal inline's), tasks per worker, runs/s, speed-up
against inline and parallel efficiency (speed-up / workers). Target: >= 1.8x on 2 workers.
Each count also on a warm pool (``warm xW``, :class:`expdesign.warmpool.WarmPool` from
:func:`expdesign.mc_parallel.start_warm_pool`, which no command uses: forked and warmed before the clock starts; its CPU the parent's plus the
workers' during the Monte Carlo, read from /proc).
The wall-clock speed-up needs an otherwise idle machine (the load average is printed); the CPU
seconds of this process and its reaped workers give the load-independent bound
workers x CPU(inline) / CPU(pool), which shows the pool's own overhead, and the CPU per run and its
ratio to inline's per worker count (CPU the workers waste shows there).

Then the model that reads off larger machines (goal: 70 % efficiency on 16 cores):
:mod:`benchmarks.scaling_model` (task cost, pool overhead, first-task extra, CPU inflation, makespan), with
the warm pool's prediction beside the fresh pool's (:mod:`benchmarks.scaling_warm`).

``--profile-task``: a task of 1 and of 63 runs per design: CPU, and how much of it is the
simulation kernel's time loops (how many, and their CPU).

``--threads``: one task in one thread against two in two threads of one process, CPU per wall
second: whether the threads of a Dask worker (``--nthreads`` > 1) compute at once.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Sequence

import numpy as np

if __package__ in (None, ""):  # run as a script: its sibling modules, as benchmarks/run.py finds them
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.scaling_model import cpu_s, setup, task_cost
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
    print(
        f"{name:45s} median {med:7.3f} s  target {target:5.1f} s  ratio {med / target:5.2f}  {'OK' if med <= target else 'SLOW'}"
    )
    return med


def scaling(
    runs: int, workers: list[int], scheduler: str | None, repeat: int, dask_local: Sequence[int] = (), preload: bool = True
) -> list[dict]:
    """Inline against local pools (and a cluster, and local Dask clusters of ``dask_local`` workers):
    same digests, speed-up per worker count. Returns per engine: label, worker slots, median wall
    and CPU seconds."""
    from expdesign.mc_parallel import evaluate_designs_parallel
    from expdesign.montecarlo import MCConfig, prepare, warm_compiled
    from expdesign.parallel import Engine, LocalEngine, get_engine

    p, lib, designs = setup()
    # numba loaded and the passes compiled before any clock starts: inline then runs warm, as the
    # pools' workers do (forked from this process after the engines' own warm-up)
    warm_compiled(prepare(p, designs, MCConfig(runs=1), lib))
    engines = [("inline", Engine)] + [(f"local x{w}", lambda w=w: LocalEngine(w)) for w in workers]
    if scheduler:
        engines.append((f"dask {scheduler}", lambda: get_engine(scheduler)))
    base = ref = base_cpu = None
    rows = []
    print(
        f"Monte Carlo scaling: {runs} runs x {len(designs)} designs, median of {repeat}; "
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs"
    )
    engines += [(f"warm x{w}", w) for w in workers if w > 1]  # one worker: no pool (start_warm_pool gives None)
    for label, make in engines:
        times, cpus = [], []
        for _ in range(repeat):
            if isinstance(make, int):  # a warm pool, started and warmed before the clock
                ev, cpu = _warm_run(p, designs, runs, lib, make)
            else:
                c0 = cpu_s()
                with make() as eng:
                    ev = evaluate_designs_parallel(p, designs, runs=runs, seed=0, scheduler=eng, primitives=lib, progress=False)
                cpu = cpu_s() - c0
            times.append(ev.elapsed_s)
            cpus.append(cpu)
        med, cpu = statistics.median(times), statistics.median(cpus)
        base_cpu = base_cpu or cpu
        dig = {k: r.digest() for k, r in ev.results.items()}
        ref = ref or dig
        base = base or med
        e = ev.engine
        slots = e["workers"] * e["threads_per_worker"]
        rows.append({"label": label, "slots": slots, "wall": med, "cpu": cpu})
        _result_lines(label, med, cpu, runs, base, base_cpu, slots, e, dig == ref)
    if dask_local:
        from benchmarks.scaling_dask import dask_runs

        def run(client):
            ev = evaluate_designs_parallel(p, designs, runs=runs, seed=0, scheduler=client, primitives=lib, progress=False)
            return ev, {k: r.digest() for k, r in ev.results.items()}

        for row in dask_runs(run, dask_local, repeat, preload):
            rows.append(row)
            _result_lines(
                row["label"],
                row["wall"],
                row["cpu"],
                runs,
                base,
                base_cpu,
                row["slots"],
                row["engine"],
                row["digests"] == ref,
                f"; first run on the new workers {row['first_wall']:.2f} s, CPU {row['first_cpu']:.2f} s",
                "this process, its scheduler and the workers",
            )
    return rows


def _warm_run(p, designs: dict, runs: int, lib: list, w: int) -> tuple:
    """The Monte Carlo on a warm pool of ``w`` workers (:func:`expdesign.mc_parallel.start_warm_pool`,
    waited for until every worker is warm): the evaluation and the CPU seconds of this process and
    the workers during it."""
    from benchmarks.scaling_warm import procs_cpu_s
    from expdesign.mc_parallel import evaluate_designs_parallel, start_warm_pool
    from expdesign.parallel import LocalEngine

    with start_warm_pool(p, lib, "local", w) as pool:
        pool.wait_ready()
        pids = [q.pid for q in pool.procs.values()]
        c0, k0 = cpu_s(), procs_cpu_s(pids)
        ev = evaluate_designs_parallel(
            p, designs, runs=runs, seed=0, scheduler=LocalEngine(pool=pool), primitives=lib, progress=False
        )
        return ev, cpu_s() - c0 + procs_cpu_s(pids) - k0


def _result_lines(
    label: str,
    wall: float,
    cpu: float,
    runs: int,
    base: float,
    base_cpu: float,
    slots: int,
    engine: dict,
    same: bool,
    note: str = "",
    who: str = "this process and its workers",
) -> None:
    """An engine's two lines: wall, speed-up, efficiency, the cut and the digests' check; then its
    CPU (``who`` says whose), per run and against inline's (``base``, ``base_cpu``: inline's wall and CPU)."""
    print(
        f"{label:14s} {wall:7.2f} s  {2 * runs / wall:6.0f} runs/s  speed-up {base / wall:5.2f}  efficiency "
        f"{base / wall / slots:5.2f}  {engine['tasks']:3d} tasks ({engine['tasks_per_worker']:.1f} per worker, "
        f"{engine['runs_per_task']} runs each)  digests {'same as inline' if same else 'DIFFER from inline'}{note}"
    )
    print(
        f"{'':14s} CPU {cpu:7.2f} s ({who}), {1e3 * cpu / (2 * runs):5.2f} ms per run, "
        f"{cpu / base_cpu:4.2f} x inline's: CPU-bound speed-up {slots * base_cpu / cpu:5.2f} on an idle machine"
    )


def profile_task(sizes: tuple[int, ...] = (1, 63), repeat: int = 3) -> None:
    """What a task's CPU time is made of: the simulation kernel's time loops (every call of
    ``simulate`` made by the Monte Carlo and its estimators: count and CPU) against the rest."""
    import expdesign.mc_data as data
    import expdesign.montecarlo as mc
    import expdesign.oerefine as oe

    p, lib, designs = setup()
    sh = mc.prepare(p, designs, mc.MCConfig(runs=repeat * max(sizes)), lib)
    calls = []
    kernel = mc.simulate

    def timed(*args, **kw):
        t = time.process_time()
        out = kernel(*args, **kw)
        calls.append(time.process_time() - t)
        return out

    mods = [m for m in (mc, data, oe) if getattr(m, "simulate", None) is kernel]
    for m in mods:
        m.simulate = timed
    try:
        for d in sh.designs:
            for n in sizes:
                rows = []
                for k in range(repeat):
                    calls.clear()
                    t = time.process_time()
                    mc.run_chunk(sh, d, range(k * n, (k + 1) * n))
                    rows.append((time.process_time() - t, len(calls), sum(calls)))
                tot, loops, sim = (statistics.median(r[i] for r in rows) for i in range(3))
                print(
                    f"task of {n:3d} runs, {d:9s}: CPU {1e3 * tot:6.0f} ms, of which {loops:.0f} kernel time loops "
                    f"({sh.config.n_samples} steps each) {1e3 * sim:6.0f} ms, the rest {1e3 * (tot - sim):6.0f} ms (median of {repeat})"
                )
    finally:
        for m in mods:
            m.simulate = kernel


def threads_check(runs: int = 63, repeat: int = 3) -> None:
    """One Monte Carlo task in one thread against two in two threads of one process (a Dask worker
    with several threads): the CPU seconds per wall second exceed 1 only where threads compute at
    once; near 1 with two threads, the interpreter lock serialises them."""
    import threading

    from expdesign.montecarlo import MCConfig, prepare, run_chunk

    p, lib, designs = setup()
    sh = prepare(p, designs, MCConfig(runs=2 * runs), lib)
    for k in (1, 2):
        walls, ratios = [], []
        for _ in range(repeat):
            th = [threading.Thread(target=run_chunk, args=(sh, "random", range(i * runs, (i + 1) * runs))) for i in range(k)]
            w, c = time.perf_counter(), time.process_time()
            for t in th:
                t.start()
            for t in th:
                t.join()
            w, c = time.perf_counter() - w, time.process_time() - c
            walls.append(w)
            ratios.append(c / w)
        print(
            f"{k} task(s) of {runs} runs in {k} thread(s) of one process: wall {statistics.median(walls):5.2f} s, "
            f"CPU / wall {statistics.median(ratios):4.2f} (median of {repeat}; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs)"
        )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--mc-runs", type=int, default=500)
    ap.add_argument("--scaling", action="store_true", help="Monte Carlo inline vs worker counts (issue 14)")
    ap.add_argument("--workers", type=int, nargs="*", default=[2])
    ap.add_argument("--scheduler", default=None, help="also time this Dask scheduler address")
    ap.add_argument(
        "--dask-local", type=int, nargs="*", default=[], help="with --scaling: also local Dask clusters of these worker counts"
    )
    ap.add_argument("--no-preload", action="store_true", help="Dask workers without expdesign.dask_preload")
    ap.add_argument("--model-only", action="store_true", help="with --scaling: only the task-cost model (about a minute)")
    ap.add_argument(
        "--threads", action="store_true", help="Monte Carlo tasks in threads of one process (Dask workers with --nthreads > 1)"
    )
    ap.add_argument("--profile-task", action="store_true", help="what a Monte Carlo task's CPU time is made of")
    a = ap.parse_args()
    if a.profile_task:
        profile_task()
        return
    if a.threads:
        threads_check()
        return
    if a.scaling:
        rows = [] if a.model_only else scaling(a.mc_runs, a.workers, a.scheduler, a.runs, a.dask_local, not a.no_preload)
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
    bench(
        f"Monte Carlo, 1 design, {a.mc_runs} runs x 1000 samples",
        lambda: evaluate_designs(p, {"optimized": w}, runs=a.mc_runs, seed=0, primitives=lib),
        20.0,
        a.runs,
    )


if __name__ == "__main__":
    main()
