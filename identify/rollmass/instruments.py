"""Regressors (16)-(18) and instruments (29)-(30) of Linder et al. (2015) for one dataset."""

from __future__ import annotations

import numpy as np

from identify.rollmass.model import Known, Load, RollParams
from identify.rollmass.simulate import RollRecording

N_LAGS = 16  # n_y = n_as = n_r = 16 of section 5
N_DELTA = 2  # n_delta = 2


def diff2(x: np.ndarray) -> np.ndarray:
    """``x_t - x_{t-2}`` with zeros for the first two samples (the mu of (16))."""
    out = np.zeros_like(x)
    out[2:] = x[2:] - x[:-2]
    return out


def lagged(x: np.ndarray, n: int) -> np.ndarray:
    """Columns ``x_t, x_{t-1}, ..., x_{t-n+1}`` (zeros before the start), shape (len(x), n)."""
    out = np.zeros((len(x), n))
    for j in range(n):
        out[j:, j] = x[: len(x) - j]
    return out


def regression(rec: RollRecording) -> tuple[np.ndarray, np.ndarray]:
    """``Y = y_t`` and ``Phi = [-y_{t-1}, -y_{t-2}, mu1, mu2, mu3]`` of (16)-(18), all rows."""
    y = rec.p
    Phi = np.column_stack([-np.r_[0, y[:-1]], -np.r_[0, 0, y[:-2]], diff2(rec.a_s), diff2(rec.r), diff2(rec.delta)])
    return y, Phi


def black_box_sim(u: np.ndarray, y: np.ndarray, na: int = 4, nb: int = 10) -> np.ndarray:
    """Iteration-0 instrument of (29): an ARX(na, nb) fit of ``u -> y`` simulated from ``u`` alone.

    Unstable fitted poles are reflected into the unit circle so the simulation stays bounded.
    """
    from scipy.signal import lfilter  # here: for the IV methods only (its import: 2 s of CPU)

    n0 = max(na, nb)
    X = np.column_stack([-lagged(y, na + 1)[:, 1:], lagged(u, nb), np.ones(len(y))])[n0:]
    coef, *_ = np.linalg.lstsq(X, y[n0:], rcond=None)
    a = np.r_[1.0, coef[:na]]
    roots = np.roots(a)
    big = np.abs(roots) >= 0.999
    if big.any():
        roots[big] = 0.99 / np.conj(roots[big])
        a = np.real(np.poly(roots))
    return lfilter(coef[na : na + nb], a, u - u.mean()) + coef[-1] / a.sum()


def paper_model_sim(
    p: RollParams, kn: Known, load: Load, r_hat: np.ndarray, delta: np.ndarray, T: float
) -> tuple[np.ndarray, np.ndarray]:
    """Refined instruments (31)-(32) as we read them: roll (3) simulated with ``v' = 0``.

    The printed (31)-(32) use an undefined ``F_y,d`` and (32) does not follow from (31); their
    intent is the model's own roll response to the simulated yaw rate and the rudder, with the
    sway acceleration left out: ``A1 phi'' + d phi' + C phi = (K_ur + M z_g + m z_m) U r + K_delta delta``
    and ``a_s = z_s phi'' + g phi - U r``. Returns ``(p_hat, a_s_hat)``.
    """
    from scipy.signal import lfilter  # here: for the IV methods only (its import: 2 s of CPU)

    z_g, z_s, z_m = kn.zbar_g + p.z_f, kn.zbar_s + p.z_f, load.zbar + p.z_f
    A1 = p.A_x + kn.M * z_g**2 + load.m * z_m**2
    C = p.k + kn.M * kn.g * z_g + load.m * kn.g * z_m
    K_ur = p.K_r / kn.U + p.K_vdot
    u = (K_ur + kn.M * z_g + load.m * z_m) * kn.U * r_hat + p.K_delta * delta
    den = np.array([4 * A1 + 2 * p.d * T + C * T**2, 2 * C * T**2 - 8 * A1, 4 * A1 - 2 * p.d * T + C * T**2])
    if not np.all(np.isfinite(den)) or np.any(np.abs(np.roots(den)) >= 1):
        raise FloatingPointError("unstable model in the instrument refinement")
    phi = lfilter(T**2 * np.array([1.0, 2.0, 1.0]), den, u)
    pr = lfilter(2 * T * np.array([1.0, 0.0, -1.0]), den, u)
    pdot = lfilter(4 * np.array([1.0, -2.0, 1.0]), den, u)
    return pr, z_s * pdot + kn.g * phi - kn.U * r_hat


def instrument_matrix(
    y_hat: np.ndarray, as_hat: np.ndarray, r_hat: np.ndarray, delta: np.ndarray, n_lags: int = N_LAGS, n_delta: int = N_DELTA
) -> np.ndarray:
    """(30): ``[y_hat lags, mu1_hat lags, mu2_hat lags, mu3 lags]`` (the rudder from the data)."""
    return np.column_stack(
        [lagged(y_hat, n_lags), lagged(diff2(as_hat), n_lags), lagged(diff2(r_hat), n_lags), lagged(diff2(delta), n_delta)]
    )


def black_box_instruments(rec: RollRecording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(y_hat, a_s_hat, r_hat)`` simulated from the rudder by black-box fits (29), iteration 0.

    ``a_s_hat`` is fitted to the measured accelerometer, so it carries the sway acceleration
    ``v'`` that the model-based refinement (32) leaves out.
    """
    return (black_box_sim(rec.delta, rec.p), black_box_sim(rec.delta, rec.a_s), black_box_sim(rec.delta, rec.r))
