"""CPU of one filtfilt pass pair through each of primitives.iir's forms, on ``shiptrial mass``'s band-passes
(stop 53): the modal block products against the sample-by-sample loop they replace, and their difference.

    cd REPO && PYTHONPATH=$PWD nice -n 10 python benchmarks/bench_iir_forms.py [--repeat 21]

The signal is a 3,286-sample random walk (the bundled example's nominal.csv at 50 Hz); each design's
probes run once before timing. Prints, per design, the form :func:`primitives.iir._form` picks, the median
``time.process_time`` of ``iir.filtfilt`` (its form) and of the same call forced sample by sample (the
form replaced for the call), and the largest difference of the two outputs over the output's peak.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from primitives import iir

#: (label, order, band, fs): identify.rollmass.signs' roll band and roles' band at the example's 50 Hz
DESIGNS = [
    ("signs roll band 0.1-0.45 Hz", 2, (0.1, 0.45), 50.0),
    ("roles roll band 0.1-2.0 Hz", 2, (0.1, 2.0), 50.0),
]


def _median_cpu(b: np.ndarray, a: np.ndarray, x: np.ndarray, repeat: int) -> float:
    """Median CPU of ``iir.filtfilt(b, a, x)`` over ``repeat`` calls."""
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        iir.filtfilt(b, a, x)
        times.append(time.process_time() - t0)
    return float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=21)
    repeat = ap.parse_args().repeat
    x = np.random.default_rng(53).standard_normal(3286).cumsum()
    for label, order, band, fs in DESIGNS:
        b, a = iir.butter(order, list(band), btype="bandpass", fs=fs)
        bn, an = iir._normalized(b, a)
        form = iir._form(bn.tobytes(), an.tobytes())
        fast = iir.filtfilt(b, a, x)
        cpu_fast = _median_cpu(b, a, x, repeat)
        kept = iir._form
        iir._form = lambda *_: "stepwise"  # the loop this stop replaced, for the comparison only
        try:
            slow = iir.filtfilt(b, a, x)
            cpu_slow = _median_cpu(b, a, x, repeat)
        finally:
            iir._form = kept
        diff = float(np.max(np.abs(fast - slow)) / np.max(np.abs(slow)))
        print(
            f"{label}: form {form}, filtfilt {1e3 * cpu_fast:.2f} ms CPU against {1e3 * cpu_slow:.2f} ms "
            f"sample by sample (median of {repeat}); largest difference {diff:.1e} of the peak"
        )


if __name__ == "__main__":
    main()
