"""Welch's power spectral density without :mod:`scipy.signal` (whose import costs about 2 s of CPU:
:mod:`primitives.iir`).

:func:`welch` is ``scipy.signal.welch(x, fs, nperseg=nperseg)`` with its defaults: periodic Hann
window w_k = 0.5 - 0.5 cos(2 pi k / N), segments of N samples overlapping by N // 2, each's mean
removed, one-sided density |FFT(w x)|^2 / (fs sum w^2) doubled but at 0 and Nyquist, averaged over
the segments (Welch 1967, IEEE Trans. Audio Electroacoust. 15(2), eq. 3-4). Equal to scipy's to
rounding (tests/test_savgol.py).
"""

from __future__ import annotations

import numpy as np


def welch(x: np.ndarray, fs: float = 1.0, nperseg: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies, power spectral density) of the 1-D ``x``, as scipy.signal.welch."""
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError("welch: x must be 1-D")
    nperseg = min(int(nperseg), len(x))
    if nperseg < 1:
        raise ValueError("welch: nperseg must be positive")
    step = nperseg - nperseg // 2
    count = (len(x) - nperseg) // step + 1
    win = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(nperseg) / nperseg)
    segs = x[np.arange(count)[:, None] * step + np.arange(nperseg)]
    segs = segs - segs.mean(axis=1, keepdims=True)
    p = np.abs(np.fft.rfft(segs * win, axis=1)) ** 2 / (fs * np.sum(win * win))
    if nperseg % 2:
        p[:, 1:] *= 2
    else:
        p[:, 1:-1] *= 2
    return np.fft.rfftfreq(nperseg, 1.0 / fs), p.mean(axis=0)
