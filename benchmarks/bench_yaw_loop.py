"""CPU of the yaw row's time loop alone (``identify.yawid.estimate.simulate_yaw`` without sensitivities, the
full model (2.17)) on random inputs of 5,000 steps and 5, 64 and 400 batch members: the sizes of ``detect``'s
recording prediction, bootstrap ships and no-change records. Median of 5 ``process_time`` figures a size.

    SHIPTRIAL_KERNEL=numpy PYTHONPATH=. python benchmarks/bench_yaw_loop.py    # the numpy loops
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from identify.yawid.estimate import simulate_yaw
from identify.yawid.model import FULL


def main() -> None:
    rng = np.random.default_rng(0)
    n, out = 5000, []
    for b in (5, 64, 400):
        # member-major views of time-contiguous rows, as the detector hands them over
        w = {k: np.ascontiguousarray((0.01 * rng.standard_normal((b, n))).T).T for k in ("u", "v", "v_dot", "phi", "p", "tau_r")}
        w["u"] = w["u"] + 3.0
        theta = -0.1 * np.abs(rng.standard_normal((b, len(FULL.params))))
        theta[:, 0] = 1.0 + rng.random(b)
        spent = []
        for _ in range(5):
            t = time.process_time()
            simulate_yaw(FULL, theta, w, np.zeros(b), 0.1, sensitivities=False)
            spent.append(time.process_time() - t)
        out.append(f"{b} members {statistics.median(spent):.3f} s")
    print(f"yaw-row loop, {n} steps, CPU median of 5: " + ", ".join(out))


if __name__ == "__main__":
    main()
