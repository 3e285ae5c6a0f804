"""How well a simulated response matches a measured one."""

from __future__ import annotations

import numpy as np


def fit_percent(y: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """NRMSE fit per DOF, 100 (1 - ||y - y_hat|| / ||y - mean y||) (Ljung 1999, System
    Identification, the fit measure of ``compare``)."""
    num = np.linalg.norm(y - yhat, axis=0)
    den = np.linalg.norm(y - y.mean(axis=0), axis=0)
    return 100.0 * (1.0 - num / np.maximum(den, 1e-300))
