"""Speed of the design step (issue 3 targets): prints the median of 5 runs and the ratio to target.

    python benchmarks/bench_design.py [--runs 5] [--mc-runs 500]

convex (7.18)/(7.53) solve for the 11 model-ship primitives: < 0.5 s; non-convex (7.57) multi-start
solve: < 1 s; Monte Carlo of one design with 500 runs of 1000 samples: < 20 s (2 cores).
"""

from __future__ import annotations

import argparse
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


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--mc-runs", type=int, default=500)
    a = ap.parse_args()
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
