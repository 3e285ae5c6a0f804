"""The output-error fit's covariance and stationarity check: a central-difference Jacobian, the
Newey-West sandwich covariance of a least-squares fit and the load's Gauss-Newton decrement in it
(used by :mod:`identify.rollmass.output_error`)."""

from __future__ import annotations

import numpy as np


def central_jacobian(fun, x: np.ndarray) -> np.ndarray:
    """Central-difference Jacobian of ``fun`` at ``x``, step ``eps^(1/3) max(1, |x_j|)``.

    The covariance and the stationarity check need it along the ill-conditioned mass-height ridge:
    on ``mass-sim --case case1 --seed 3`` the fit's own forward-difference Jacobian (step
    ``sqrt(eps)``) gave a sensitivity of the load to z_f of -14.7 kg/m where this one gave -0.66.
    """
    steps = np.finfo(float).eps ** (1 / 3) * np.maximum(1.0, np.abs(x))
    cols = []
    for j, hj in enumerate(steps):
        e = np.zeros_like(x)
        e[j] = hj
        cols.append((fun(x + e) - fun(x - e)) / (2 * hj))
    return np.column_stack(cols)


def load_decrement(J: np.ndarray, f: np.ndarray, lengths: list[int], lags: int) -> float:
    """Squared length ``d^T C^-1 d`` of the load part ``d = dx[-2:]`` (``m``, ``zbar_m``, the last two
    parameters) of the Gauss-Newton step ``dx = -(J^T J)^-1 J^T f``, in the load's sandwich covariance
    ``C`` (:func:`sandwich_cov`): how far a further step would move the reported load, in the standard
    errors reported with it. With white, unit-variance residuals and every parameter counted it is the
    Newton decrement (Boyd & Vandenberghe 2004, sec. 9.5.1), the step in ``(J^T J)^-1``; that metric
    is not the interval's when the residual is structure rather than noise, and on a noise-free basin
    run (base, case 1) it was 0.13 where the load's step was 0.055 of its reported sd. NaN when the
    covariance is singular (then not stationary)."""
    dx = -np.linalg.lstsq(J, f, rcond=None)[0]
    d = dx[-2:]
    try:
        return float(d @ np.linalg.solve(sandwich_cov(J, f, lengths, lags)[-2:, -2:], d))
    except np.linalg.LinAlgError:  # a singular J^T J or load covariance: no interval to measure in
        return float("nan")


def bartlett_meat(h: np.ndarray, lags: int) -> np.ndarray:
    """Long-run ``sum_|k|<=L w_k sum_t h_t h_{t+k}^T`` of one dataset's scores ``h`` (n x p), Bartlett
    weights ``w_k = 1 - |k|/(lags+1)`` over ``|k| <= min(lags, n-1)`` samples (Newey & West 1987, eq. 2).
    Summed over every lag at once: ``h^T (K h)``, ``K_ts = w_|t-s|`` the Bartlett band, ``K h`` a
    convolution of each score column with the kernel (one FFT, not a product per lag)."""
    L = min(lags, len(h) - 1)
    kernel = 1.0 - np.abs(np.arange(-L, L + 1)) / (lags + 1)  # a window beyond the data: cut, not rescaled
    Kh = same_convolution(h, kernel)
    return 0.5 * (h.T @ Kh + Kh.T @ h)


def same_convolution(h: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Each column of ``h`` (n, p) convolved with ``kernel`` (odd length), the ``n`` central samples:
    ``scipy.signal.fftconvolve(h, kernel[:, None], mode="same", axes=0)`` by numpy's real FFT, to rounding
    (1e-15 of the largest value, tests/test_rollmass_oe_fit.py), without scipy.signal's import (2 s of CPU)."""
    n, k = len(h), len(kernel)
    size = n + k - 1
    nfft = 1 << (size - 1).bit_length()  # a power of two: numpy's FFT has no fast-length helper
    full = np.fft.irfft(np.fft.rfft(h, nfft, axis=0) * np.fft.rfft(kernel, nfft)[:, None], nfft, axis=0)
    start = (k - 1) // 2
    return full[start : start + n]


def _meat(J: np.ndarray, f: np.ndarray, lengths: list[int], lags: int) -> np.ndarray:
    """The sandwich's ``S``: each dataset's per-sample scores ``h_t = sum_channels J_t f_t`` in
    :func:`bartlett_meat` (datasets independent); rows after the datasets' (a Gaussian prior, as a
    standardised observation) add ``J_p^T J_p``."""
    S = np.zeros((J.shape[1], J.shape[1]))
    i = 0
    for n in lengths:
        rows = slice(i, i + 3 * n)
        S += bartlett_meat((J[rows] * f[rows, None]).reshape(n, 3, -1).sum(axis=1), lags)
        i += 3 * n
    return S + J[i:].T @ J[i:]


def sandwich_cov(J: np.ndarray, f: np.ndarray, lengths: list[int], lags: int) -> np.ndarray:
    """Sandwich (Huber-White, Newey-West) covariance ``A^-1 S A^-1`` of a least-squares fit, ``A = J^T J``,
    ``S`` from :func:`_meat` (a prior row adds its information ``1/sd^2``). Unlike ``s^2 A^-1`` it
    allows for residuals that stay correlated after the whitening (unmodelled dynamics); it does not
    allow for a bias.
    """
    Ainv = np.linalg.inv(J.T @ J)
    return Ainv @ _meat(J, f, lengths, lags) @ Ainv
