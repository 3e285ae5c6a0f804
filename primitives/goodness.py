"""How well a simulated response matches a measured one, and how well a regression determines a coefficient."""

from __future__ import annotations

import numpy as np


def fit_percent(y: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """NRMSE fit per DOF, 100 (1 - ||y - y_hat|| / ||y - mean y||) (Ljung 1999, System
    Identification, the fit measure of ``compare``)."""
    num = np.linalg.norm(y - yhat, axis=0)
    den = np.linalg.norm(y - y.mean(axis=0), axis=0)
    return 100.0 * (1.0 - num / np.maximum(den, 1e-300))


def coefficient_t(X: np.ndarray, y: np.ndarray, j: int, lags: int = 0) -> float:
    """The t value of coefficient ``j`` in the least-squares fit of ``y`` on the columns of ``X``; 0 when the
    variance is not a positive finite number (no information).

    ``lags=0``: the ordinary least-squares variance ``s^2 [(X'X)^-1]_jj`` with ``s^2 = |y - X b|^2 / (n - p)``.
    ``lags=L > 0``: Newey and West's (1987) heteroskedasticity and autocorrelation consistent variance
    ``[(X'X)^-1 S (X'X)^-1]_jj``, ``S = G_0 + sum_{l=1..L} (1 - l / (L + 1)) (G_l + G_l')``,
    ``G_l = sum_k x_k e_k e_{k-l} x_{k-l}'`` (Bartlett weights; L clipped to n - 1): for residuals correlated over
    up to L samples (a moving mean, a differentiation), where the ordinary error misstates the spread."""
    if lags <= 0:
        with np.errstate(all="ignore"):
            coef = np.linalg.lstsq(X, y, rcond=None)[0]
            e = y - X @ coef
            var = float(e @ e) / max(len(y) - X.shape[1], 1) * np.linalg.pinv(X.T @ X)[j, j]
        return float(coef[j] / np.sqrt(var)) if var > 0 and np.isfinite(var) else 0.0
    coef = np.linalg.lstsq(X, y, rcond=None)[0]
    xe = X * (y - X @ coef)[:, None]
    s = xe.T @ xe
    lags = min(lags, len(xe) - 1)
    for lag in range(1, lags + 1):
        g = xe[lag:].T @ xe[:-lag]
        s += (1.0 - lag / (lags + 1)) * (g + g.T)
    b = np.linalg.pinv(X.T @ X)
    var = float((b @ s @ b)[j, j])
    return float(coef[j] / np.sqrt(var)) if var > 0 and np.isfinite(var) else 0.0
