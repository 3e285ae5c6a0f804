"""The search's acceptance tests (:mod:`diagnose.search`): significance on the estimation data,
corrected for the residual's colour, together with a gain on held-out data (Källström 1977:
output error with a likelihood-ratio test and split data), and the size of effect they accept.

:func:`smallest_significant_rms` turns the tests round: how large a misfit on one run must be
before the search would call a candidate that absorbs it significant. The --fit-on check
(:func:`diagnose.baseline.unpinned_runs`) compares the baseline's own uncertainty with it.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

ALPHA = 1e-6  # family-wise significance per round (Bonferroni over candidates)
MIN_GAIN = 0.002  # held-out weighted RSS must drop by at least 0.2 % ...
STRONG_GAIN = 0.10  # ... or by 10 %, which then needs only p < 0.01 on the estimation data
ALPHA_STRONG = 1e-2
ALPHA_INDEPENDENT = 0.05


def independent_heldout(n_validate: int, n_diagnosed: int) -> bool:
    """Two or more whole held-out runs (validation runs, or leave one run out of the diagnosed
    runs) are evidence enough to relax the in-sample test; a single held-out run is not."""
    return n_validate >= 2 or (not n_validate and n_diagnosed >= 2)


def passes(p_value: float, gain: float, n_cand: int, alpha: float = ALPHA, independent: bool = False) -> bool:
    """Significant on the estimation data AND better on held-out data. When the held-out data
    are whole runs the fit never saw (validation runs, or leave one run out), they are the
    guard against chance: the estimation data need only ordinary significance (5 %)."""
    if independent and gain > MIN_GAIN and p_value < ALPHA_INDEPENDENT:
        return True
    return (p_value < alpha / n_cand and gain > MIN_GAIN) or (p_value < ALPHA_STRONG / n_cand and gain > STRONG_GAIN)


def loosest_alpha(n_cand: int, independent: bool) -> float:
    """The largest p-value :func:`passes` accepts for some held-out gain: 5 % with independent
    held-out runs, else ALPHA_STRONG over the candidates (with a held-out gain of 10 %)."""
    return ALPHA_INDEPENDENT if independent else ALPHA_STRONG / max(n_cand, 1)


def inflation(res: np.ndarray, n_dof: int = 3, max_lag: int = 30) -> float:
    """Variance inflation of coloured residuals (largest over the DOFs): the larger of the
    Bartlett sum 1 + 2 sum (1 - k/K) rho_k and, near the noise level, the AR(1) value."""
    r = res.reshape(-1, n_dof)
    taus = []
    for i in range(n_dof):
        x = r[:, i] - r[:, i].mean()
        den = float(x @ x)
        if den <= 0 or len(x) < 3 * max_lag:
            taus.append(1.0)
            continue
        K = max_lag
        rho = np.array([x[:-k] @ x[k:] / den for k in range(1, K + 1)])
        tau = 1.0 + 2.0 * np.sum((1 - np.arange(1, K + 1) / K) * rho)
        if np.sqrt(np.mean(r[:, i] ** 2)) < 3.0:
            r1 = float(np.clip(rho[0], -0.99, 0.995))
            tau = max(tau, (1 + r1) / (1 - r1))
        taus.append(tau)
    return float(np.clip(np.max(taus), 1.0, 400.0))


def lr_stats(res1: np.ndarray, rss0: float, rss1: float, q: int, M: int) -> tuple[float, float]:
    """(F, p) of q added parameters, effective sample count from the colour of ``res1``."""
    tau = inflation(res1)
    n_eff = M / tau
    f = ((rss0 - rss1) / q) / (rss1 / max(M - q, 1)) / tau
    p = float(stats.f.sf(f, q, max(n_eff - q, 1))) if f > 0 else 1.0
    return float(f), p


def smallest_significant_rms(n_rows: int, n_total: int, level: float, tau: float, alpha: float) -> float:
    """RMS over one run of ``n_rows`` samples (one channel, in noise units) of the smallest misfit
    a one-parameter candidate that took it up whole would make significant at ``alpha`` in the
    search's F test (:func:`lr_stats`): its RSS drop n_rows e^2 against F(alpha; 1, n_total / tau - 1)
    times the residual variance ``level`` (per sample, noise units) and the colour ``tau``, so
    e = sqrt(F tau level / n_rows). ``n_total``: the elements of the data the test pools."""
    f_crit = float(stats.f.isf(alpha, 1, max(n_total / tau - 1.0, 1.0)))
    return float(np.sqrt(f_crit * tau * level / max(n_rows, 1)))
