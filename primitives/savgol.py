"""Savitzky-Golay smoothing and differentiation without :mod:`scipy.signal` (whose import costs
about 2 s of CPU: :mod:`primitives.iir`).

:func:`savgol_filter` is ``scipy.signal.savgol_filter(x, window, polyorder, deriv, delta, axis)``
with its default ``mode='interp'``: inside, the least-squares polynomial of degree ``polyorder``
over each centred window of ``window`` samples, its ``deriv``-th derivative at the centre
(Savitzky & Golay 1964, Anal. Chem. 36(8); the weights are the row ``deriv! / delta^deriv`` of
the pseudo-inverse of the window's Vandermonde matrix); over the first and last ``window // 2``
samples, the polynomial fitted to the first (last) whole window, evaluated there. Both are linear
maps of the data, applied here as weighted sums of shifted slices and two small matrices. Equal to
scipy's to rounding (tests/test_savgol.py: 1e-12 of the output's largest value on random inputs).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np


@lru_cache(maxsize=32)
def _weights(window: int, polyorder: int, deriv: int, delta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centre weights (window,), first edge (half, window), last edge (half, window))."""
    half = window // 2
    t = np.arange(window, dtype=np.float64) - half  # centred: a better conditioned fit
    vander = t[:, None] ** np.arange(polyorder + 1)  # columns t^p
    fit = np.linalg.pinv(vander)  # (polyorder + 1, window): the polynomial's coefficients from the window
    powers = np.arange(polyorder + 1)
    # d^deriv/dt^deriv of t^p: p! / (p - deriv)! t^(p - deriv) for p >= deriv
    scale = np.array([math.perm(p, deriv) if p >= deriv else 0.0 for p in powers], dtype=np.float64)
    exps = np.maximum(powers - deriv, 0)

    def at(ts: np.ndarray) -> np.ndarray:
        return (scale * ts[:, None] ** exps) @ fit / delta**deriv

    centre = at(np.array([0.0]))[0]
    first = at(t[:half])
    last = at(t[window - half :])
    for a in (centre, first, last):
        a.flags.writeable = False
    return centre, first, last


def savgol_filter(x: np.ndarray, window: int, polyorder: int, deriv: int = 0, delta: float = 1.0, axis: int = -1) -> np.ndarray:
    """scipy.signal.savgol_filter(x, window, polyorder, deriv=deriv, delta=delta, axis=axis) (mode
    'interp'), to rounding; ``window`` odd, greater than ``polyorder`` and at most x's length."""
    x = np.asarray(x, dtype=np.float64)
    window, polyorder, deriv = int(window), int(polyorder), int(deriv)
    n = x.shape[axis]
    if window % 2 == 0 or window <= polyorder or window > n:
        raise ValueError(f"savgol_filter: window {window} must be odd, > polyorder {polyorder} and <= the length {n}")
    centre, first, last = _weights(window, polyorder, deriv, float(delta))
    moved = np.moveaxis(x, axis, 0)
    half = window // 2
    out = np.empty(moved.shape)
    inner = out[half : n - half]
    np.multiply(moved[0 : n - window + 1], centre[0], out=inner)
    for j in range(1, window):
        inner += centre[j] * moved[j : n - window + 1 + j]
    out[:half] = np.tensordot(first, moved[:window], axes=(1, 0))
    out[n - half :] = np.tensordot(last, moved[n - window :], axes=(1, 0))
    return np.moveaxis(out, 0, axis)
