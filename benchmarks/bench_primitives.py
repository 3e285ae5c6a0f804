"""Benchmarks of the foundation (issue 2): library build with information matrices, and a
500 x 1000-sample Monte Carlo batch simulation of the model ship.

    python benchmarks/bench_primitives.py [--repeat 5]

(the two cases of ``benchmarks/run.py`` that belong to the foundation).
"""

from __future__ import annotations

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


if __name__ == "__main__":
    # the shared runner times each case in a fresh process (median, min, max, peak memory, ratio)
    import subprocess
    import sys
    from pathlib import Path

    runner = Path(__file__).with_name("run.py")
    sys.exit(subprocess.call([sys.executable, str(runner), "--only", "library_build", "monte_carlo_sim_500x1000", *sys.argv[1:]]))
