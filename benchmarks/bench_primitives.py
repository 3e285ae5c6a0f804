"""Benchmarks of the foundation (issue 2): library build with information matrices, and a
500 x 1000-sample Monte Carlo batch simulation of the model ship.

    python benchmarks/bench_primitives.py [--repeat 5]

Prints the median of the repeats and the ratio to the target (< 1 is within target).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from primitives.information import library_information
from primitives.library import model_ship_thesis
from primitives.ship import load_profile
from primitives.simulate import Disturbances, simulate


def case_library_build() -> None:
    """11-primitive model-ship library with X, Y, Z, Gamma per primitive (target < 2 s)."""
    prof = load_profile("model-ship")
    library_information(prof, model_ship_thesis(prof))


def case_monte_carlo_sim() -> None:
    """500 realisations x 1000 samples of the model ship with current and noise (target < 2 s)."""
    prof = load_profile("model-ship")
    rng = np.random.default_rng(0)
    inputs = np.column_stack(
        [4000 + 1000 * np.sin(np.arange(1000) / 30), 500 * rng.standard_normal(1000), 200 * np.sign(np.sin(np.arange(1000) / 40))]
    )
    simulate(prof, inputs, disturbances=Disturbances.from_profile(prof), batch=500, seed=1)


CASES = {"library_build": (case_library_build, 2.0), "monte_carlo_500x1000": (case_monte_carlo_sim, 2.0)}


def run(repeat: int = 5) -> dict[str, dict]:
    out = {}
    for name, (fn, target) in CASES.items():
        fn()  # warm-up (imports, caches)
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        med = statistics.median(times)
        out[name] = {
            "median_s": med,
            "min_s": min(times),
            "max_s": max(times),
            "target_s": target,
            "ratio_to_target": med / target,
        }
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    res = run(ap.parse_args().repeat)
    for name, r in res.items():
        print(
            f"{name:24s} median {r['median_s']:.3f} s (min {r['min_s']:.3f}, max {r['max_s']:.3f}); target {r['target_s']} s; ratio {r['ratio_to_target']:.2f}"
        )
