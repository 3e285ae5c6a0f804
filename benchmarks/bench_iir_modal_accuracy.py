"""Accuracy of ``primitives.iir``'s modal form (``modal=True``, stop 53) against scipy's loop run in
``numpy.longdouble``, as formed on x86-64 and with ``iirmodal.EXT, CEXT`` patched to float64, complex128 (a
platform whose longdouble is double), and the modal form's distance from the double loop on the probe that
:func:`primitives.iir._modal_blocks` judges against ``MODAL_TOLERANCE``.

    cd REPO && PYTHONPATH=$PWD nice -n 10 python benchmarks/bench_iir_modal_accuracy.py [--samples 3000]

Per design: whether the companion blocks carry it, whether it has a modal form that the guard accepts, and
the largest error from a state (a random walk) over the output's peak of the modal form and of scipy's
``lfilter``, against the extended loop. Needs an extended longdouble (x86-64) for the reference.
"""

from __future__ import annotations

import argparse

import numpy as np
import scipy.signal as ss

from primitives import iir, iirmodal

#: mass's sign band (0.1-0.45 Hz) and role band (0.1-2.0 Hz) over sampling rates; low cutoffs and a high order
DESIGNS = [(2, (0.1, 0.45), "bandpass", fs) for fs in (10.0, 20.0, 25.0, 50.0, 100.0, 200.0, 1000.0)]
DESIGNS += [(2, (0.1, 2.0), "bandpass", fs) for fs in (25.0, 50.0, 100.0, 200.0)]
DESIGNS += [(4, 0.05, "lowpass", 10.0), (6, 0.05, "lowpass", 10.0), (3, 0.01, "lowpass", 10.0), (8, 0.3, "lowpass", 50.0)]
#: (label, b, a): a triple pole numpy.roots splits, and three near-repeated poles
POLES = [
    ("triple pole 0.999", np.r_[1e-6, 0.0, 0.0, 0.0], np.poly([0.999] * 3)),
    ("poles 0.999 / 0.9991 / 0.9992", np.r_[1e-6, 0.0, 0.0, 0.0], np.poly([0.999, 0.9991, 0.9992])),
]


def extended_loop(b: np.ndarray, a: np.ndarray, x: np.ndarray, zi: np.ndarray) -> np.ndarray:
    """scipy's transposed direct form II loop (:func:`iir._stepwise`) in numpy.longdouble (tests/test_iirmodal.py too)."""
    ext = [[np.longdouble(v) for v in c] for c in (b, a, x, zi)]
    return np.array(iir._stepwise(*ext), dtype=np.longdouble)


def _row(label: str, b: np.ndarray, a: np.ndarray, n: int) -> str:
    bn, an = iir._normalized(b, a)
    bb, ab = bn.tobytes(), an.tobytes()
    blocks = iirmodal.modal_blocks(bb, ab, iir.BLOCK)
    probe_diff = "-"
    if blocks is not None:
        probe, z0, want = iir._probe(bb, ab)
        got = iirmodal.modal_products(probe[None, :], blocks, z0[None, :])[0]
        probe_diff = f"{np.max(np.abs(got - want)) / np.max(np.abs(want)):.1e}"
    accepted = iir._modal_blocks(bb, ab) is not None
    x = np.random.default_rng(len(a)).standard_normal(n).cumsum()
    zi = iir.lfilter_zi(b, a) * x[0]
    exact = extended_loop(bn, an, x, zi)
    peak = float(np.max(np.abs(exact)))
    forced = iirmodal.modal_products(np.r_[x, np.zeros(-n % iir.BLOCK)][None, :], blocks, zi[None, :])[0, :n] if blocks else None
    mine = "-" if forced is None else f"{np.max(np.abs(forced - exact)) / peak:.1e}"
    theirs = np.max(np.abs(ss.lfilter(b, a, x, zi=zi)[0] - exact)) / peak
    carried = iir._blockable(bb, ab)
    return f"  {label}: blocks {carried!s:5} modal accepted {accepted!s:5} probe {probe_diff:7} modal {mine:7} scipy {theirs:.1e}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=3000)
    n = ap.parse_args().samples
    if np.finfo(np.longdouble).eps >= np.finfo(np.float64).eps:
        raise SystemExit("error: numpy.longdouble is double here: no extended-precision reference")
    for ext in ((np.longdouble, np.clongdouble), (np.float64, np.complex128)):
        iirmodal.EXT, iirmodal.CEXT = ext
        iirmodal.modal_blocks.cache_clear()
        iir._modal_blocks.cache_clear()
        print(f"iirmodal.EXT = {ext[0].__name__}")
        for order, wn, btype, fs in DESIGNS:
            print(_row(f"{order} {wn} {btype} {fs:g} Hz", *ss.butter(order, wn, btype=btype, fs=fs), n))
        for label, b, a in POLES:
            print(_row(label, b, a, n))


if __name__ == "__main__":
    main()
