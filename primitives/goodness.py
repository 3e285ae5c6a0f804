"""How well a simulated response matches a measured one, and how well a regression determines a coefficient."""

from __future__ import annotations

import numpy as np


def fit_percent(y: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """NRMSE fit per DOF, 100 (1 - ||y - y_hat|| / ||y - mean y||) (Ljung 1999, System
    Identification, the fit measure of ``compare``)."""
    num = np.linalg.norm(y - yhat, axis=0)
    den = np.linalg.norm(y - y.mean(axis=0), axis=0)
    return 100.0 * (1.0 - num / np.maximum(den, 1e-300))


def coefficient_t(X: np.ndarray, y: np.ndarray, j: int) -> float:
    """The t value of coefficient ``j`` in the least-squares fit of ``y`` on the columns of ``X``: ``b_j /
    sqrt(s^2 [(X'X)^-1]_jj)`` with ``s^2 = |y - X b|^2 / (n - p)`` (the ordinary least-squares variance
    ``s^2 (X'X)^-1`` of the coefficients); 0 when the variance is not a positive finite number (no information)."""
    with np.errstate(all="ignore"):
        coef = np.linalg.lstsq(X, y, rcond=None)[0]
        e = y - X @ coef
        var = float(e @ e) / max(len(y) - X.shape[1], 1) * np.linalg.pinv(X.T @ X)[j, j]
    return float(coef[j] / np.sqrt(var)) if var > 0 and np.isfinite(var) else 0.0
