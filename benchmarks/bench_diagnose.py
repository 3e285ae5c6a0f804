"""Benchmark: diagnose a 2000-sample recording against the full candidate library (target < 10 s).

Run: python benchmarks/bench_diagnose.py [repeats]
Prints the median over the repeats for a control recording (every candidate screened, none
kept) and for one with two concealed effects (current + actuator delay: two output-error
refits and a backward check), and the ratio to the 10 s target.
"""

from __future__ import annotations

import statistics
import sys
import time

from diagnose.api import run
from diagnose.battery import scenario
from primitives.ship import load_profile

TARGET_S = 10.0
N = 2000


def main(repeats: int = 5) -> None:
    ship = load_profile("model-ship")
    for effects in ((), ("current", "actuator_delay")):
        sc = scenario(effects, 7, n_prims=9)
        rec = sc.diagnose[0].window(0, N + 1)
        times, named = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            d = run([rec], ship)
            times.append(time.perf_counter() - t0)
            named = [f["effect"] for f in d.findings]
        med = statistics.median(times)
        print(f"{sc.name:24s} {rec.n_samples} samples, {len(d.model.candidates)} candidates: median {med:.2f} s "
              f"over {repeats} runs (min {min(times):.2f}, max {max(times):.2f}); ratio to {TARGET_S:.0f} s target "
              f"{med / TARGET_S:.2f}; found {named or 'nothing'}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
