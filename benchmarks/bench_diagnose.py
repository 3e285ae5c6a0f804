"""Benchmark: diagnosis speed (issue 13 targets).

Run: python benchmarks/bench_diagnose.py [repeats]
Cases:
- single: one 2,000-sample recording (model ship, current + actuator delay concealed), every
  candidate screened by held-out blocks; target < 2 s;
- model_test: a 13-run model test, 3,500 samples per run (model ship, a current concealed in
  every run), every candidate screened by leave-one-run-out; target < 10 s.
Prints the median over the repeats, min/max, the ratio to the target and what was found.
"""

from __future__ import annotations

import statistics
import sys
import time

from diagnose.api import run
from diagnose.battery import scenario
from primitives.ship import load_profile

TARGETS = {"single": 2.0, "model_test": 10.0}


def single_recording():
    return [scenario(("current", "actuator_delay"), 7, n_prims=9).diagnose[0].window(0, 2001)]


def model_test(n_runs: int = 13, n_samples: int = 3500):
    recs = [scenario(("current",), 100 + i, n_prims=15).diagnose[0] for i in range(n_runs)]
    return [r.window(0, min(n_samples + 1, r.n_samples)) for r in recs]


def main(repeats: int = 3) -> None:
    ship = load_profile("model-ship")
    for name, recs in (("single", single_recording()), ("model_test", model_test())):
        times, named = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            d = run(recs, ship)
            times.append(time.perf_counter() - t0)
            named = [f["effect"] for f in d.findings]
        med = statistics.median(times)
        target = TARGETS[name]
        print(
            f"{name:11s} {len(recs)} run(s) x {recs[0].n_samples} samples, {len(d.model.candidates)} candidates: "
            f"median {med:.2f} s over {repeats} (min {min(times):.2f}, max {max(times):.2f}); target {target:g} s, "
            f"ratio {med / target:.2f}; found {named or 'nothing'}",
            flush=True,
        )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
