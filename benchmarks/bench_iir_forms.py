"""CPU of one filtfilt pass pair with and without ``modal=True`` on ``shiptrial mass``'s check band-passes
(stop 53): the modal block products the checks ask for against the sample-by-sample loop (scipy's bits)
every other caller keeps, and their difference.

    cd REPO && PYTHONPATH=$PWD nice -n 10 python benchmarks/bench_iir_forms.py [--repeat 21]

The signal is a 3,286-sample random walk (the bundled example's nominal.csv at 50 Hz); each design's
probes run once before timing. Prints, per design, whether it has a modal form
(:func:`primitives.iir._modal_blocks`), the median ``time.process_time`` of ``iir.filtfilt(..., modal=True)``
and of the default call, and the largest difference of the two outputs over the output's peak.
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


def _median_cpu(b: np.ndarray, a: np.ndarray, x: np.ndarray, repeat: int, modal: bool) -> float:
    """Median CPU of ``iir.filtfilt(b, a, x, modal=modal)`` over ``repeat`` calls."""
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        iir.filtfilt(b, a, x, modal=modal)
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
        blockable = iir._blockable(bn.tobytes(), an.tobytes())
        form = "companion blocks" if blockable else "modal" if iir._modal_blocks(bn.tobytes(), an.tobytes()) else "loop"
        fast, slow = iir.filtfilt(b, a, x, modal=True), iir.filtfilt(b, a, x)
        cpu_fast, cpu_slow = _median_cpu(b, a, x, repeat, True), _median_cpu(b, a, x, repeat, False)
        diff = float(np.max(np.abs(fast - slow)) / np.max(np.abs(slow)))
        print(
            f"{label}: modal=True takes the {form} form, filtfilt {1e3 * cpu_fast:.2f} ms CPU against {1e3 * cpu_slow:.2f} ms "
            f"by default{'' if blockable else ' (sample by sample)'} (median of {repeat}); largest difference {diff:.1e} of the peak"
        )


if __name__ == "__main__":
    main()
