"""Measurement-noise level per output channel of a recording, from its differences (the residual
weights of a diagnosis); moved from :mod:`diagnose.model`, which re-exports them."""

from __future__ import annotations

import numpy as np


def noise_std(y: np.ndarray) -> np.ndarray:
    """Measurement-noise std per output from second differences (robust: median absolute)."""
    d2 = y[2:] - 2 * y[1:-1] + y[:-2]
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0) * 1.4826 / np.sqrt(6.0)
    floor = 1e-3 * (np.std(y, axis=0) + 1e-12)
    return np.maximum(mad, floor)


def noise_std_coloured(y: np.ndarray, max_lag: int = 6) -> np.ndarray:
    """Measurement-noise std per output, robust to coloured (AR(1)) noise.

    The robust variance of the lag-L second difference y(k+L) - 2 y(k) + y(k-L) is modelled as
    c L^4 (a smooth motion) + s^2 (6 - 8 rho^L + 2 rho^2L) (AR(1) noise of std s and lag-one
    correlation rho) over L = 1..max_lag; (c, s^2) by non-negative least squares on the relative
    error for each rho of a grid. White noise is rho = 0 (the plain second-difference estimate);
    coloured noise hides from the lag-one difference, which underestimates it several times.
    """
    from scipy.optimize import nnls

    n = len(y)
    lags = np.arange(1, max_lag + 1)
    lags = lags[2 * lags < n - 2]
    out = noise_std(y)
    if len(lags) < 3:
        return out
    for i in range(y.shape[1]):
        v = np.empty(len(lags))
        for q, L in enumerate(lags):
            d2 = y[2 * L :, i] - 2 * y[L:-L, i] + y[: -2 * L, i]
            v[q] = (1.4826 * np.median(np.abs(d2 - np.median(d2)))) ** 2
        if not np.all(v > 0):
            continue
        best = (np.inf, out[i] ** 2)
        for rho in np.linspace(0.0, 0.9, 19):
            A = np.column_stack([lags.astype(float) ** 4, 6 - 8 * rho**lags + 2 * rho ** (2 * lags)]) / v[:, None]
            coef, res = nnls(A, np.ones(len(lags)))
            if res < best[0] - 1e-9:
                best = (res, coef[1])
        out[i] = max(np.sqrt(best[1]), out[i])
    return out
