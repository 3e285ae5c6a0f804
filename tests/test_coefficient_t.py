"""primitives.goodness.coefficient_t, the project's one t helper (diagnose's rudder and tau_n sign checks, lags=0;
yawid's sign check, Newey-West lags): the ordinary and the Newey-West (1987) t against their textbook sums, and the
reason for the lags - residuals correlated by a moving mean make the ordinary t's spread on a no-evidence run
grow, the Newey-West one's not."""

from __future__ import annotations

import numpy as np

from primitives.goodness import coefficient_t


def _data(rng, n=400):
    t = np.arange(n)
    X = np.column_stack([np.sin(t / 17.0) + 0.3 * rng.standard_normal(n), rng.standard_normal(n), np.ones(n)])
    return X, X @ np.array([0.7, -0.2, 0.1]) + rng.standard_normal(n)


def test_lags_zero_is_the_ordinary_least_squares_t():
    X, y = _data(np.random.default_rng(1))
    b = np.linalg.solve(X.T @ X, X.T @ y)
    e = y - X @ b
    se = np.sqrt(e @ e / (len(y) - 3) * np.linalg.inv(X.T @ X)[0, 0])
    assert np.isclose(coefficient_t(X, y, 0), b[0] / se, rtol=1e-10)
    assert coefficient_t(X, y, 0, lags=0) == coefficient_t(X, y, 0)


def test_newey_west_t_is_the_bartlett_weighted_sum():
    X, y = _data(np.random.default_rng(2))
    b = np.linalg.solve(X.T @ X, X.T @ y)
    e = y - X @ b
    L, n = 4, len(y)
    S = np.zeros((3, 3))
    for lag in range(L + 1):  # G_l = sum_k x_k e_k e_{k-l} x_{k-l}', weight 1 - l / (L + 1), G_l + G_l' for l > 0
        G = sum(np.outer(X[k] * e[k], X[k - lag] * e[k - lag]) for k in range(lag, n))
        S += (1.0 - lag / (L + 1)) * (G + G.T if lag else G)
    A = np.linalg.inv(X.T @ X)
    assert np.isclose(coefficient_t(X, y, 0, lags=L), b[0] / np.sqrt((A @ S @ A)[0, 0]), rtol=1e-10)


def test_newey_west_keeps_the_spread_of_a_smoothed_no_evidence_regression():
    """A 5-sample moving mean of white noise regressed on a slow input it does not depend on: the ordinary t
    spreads far beyond 1 (a 3-sigma test refuses runs with nothing in them), the Newey-West t (lags = window) not."""
    rng = np.random.default_rng(3)
    n, w = 600, 5
    X = np.column_stack([np.sin(np.arange(n) / 40.0), np.ones(n)])
    ols, hac = [], []
    for _ in range(300):
        y = np.convolve(rng.standard_normal(n), np.ones(w) / w, mode="same")
        ols.append(coefficient_t(X, y, 0))
        hac.append(coefficient_t(X, y, 0, lags=2 * w))
    assert np.std(ols) > 1.8
    assert 0.8 < np.std(hac) < 1.25


def test_no_information_is_zero():
    X = np.column_stack([np.zeros(50), np.ones(50)])
    y = np.random.default_rng(4).standard_normal(50)
    assert coefficient_t(X, y, 0) == 0.0 and coefficient_t(X, y, 0, lags=3) == 0.0


def test_the_tau_n_sign_check_refuses_no_noise_only_run():
    """diagnose's tau_n sign check keeps the ordinary t (lags=0): its one-step fit holds r(k), which takes the
    differencing's correlation. The model-ship control run with its yaw rate replaced by white or AR(1) noise (a
    ship that does not answer tau_n), 300 draws: refused as no more often than a 3-sigma test allows (stop 60:
    0-4 of 500 at every noise level), where yawid's ordinary t had refused 6 of 500 at 50 x noise."""
    import dataclasses

    from diagnose.battery import scenario
    from diagnose.recording import RecordingError
    from diagnose.recording_checks import check_yaw_moment_sign
    from primitives.ship import load_profile

    ship = load_profile("model-ship")
    rec = scenario((), 1).diagnose[0]
    check_yaw_moment_sign(rec, ship)  # the run as recorded passes
    rng = np.random.default_rng(5)
    refused = 0
    for i in range(300):
        w = rng.standard_normal(len(rec.y))
        if i % 2:  # AR(1) 0.9, unit variance: the MMG battery's coloured noise
            for k in range(1, len(w)):
                w[k] = 0.9 * w[k - 1] + np.sqrt(0.19) * w[k]
        y = rec.y.copy()
        y[:, 2] = 0.02 * w
        try:
            check_yaw_moment_sign(dataclasses.replace(rec, y=y), ship)
        except RecordingError:
            refused += 1
    assert refused <= 3, refused
