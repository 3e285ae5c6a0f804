"""Residual tests of an identified steering model (Källström 1977, Figs. 3.3 c, d and 4.1 b-4.4 b):
the autocorrelation of each channel's residuals (whiteness) and their cross-correlation with the rudder,
each against its +-2 sigma band 2/sqrt(n), for the one-step prediction residuals and for the simulation
residuals both (a maximum-likelihood model can predict well and simulate badly: Källström's Fig. 4.3 a).

Residuals are taken in sample order over the measured samples (the lags are sample lags; on an irregular
grid they are approximately lags in time).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CorrelationTest:
    """Normalised correlations at lags 1..M (ACF) or 0..M (rudder -> residual CCF), the band and the verdict."""

    kind: str  # "whiteness" | "rudder"
    lags: np.ndarray
    values: np.ndarray
    band: float
    n_outside: int
    passed: bool

    def as_dict(self) -> dict:
        return {
            "kind": self.kind,
            "band": self.band,
            "lags_outside": int(self.n_outside),
            "lags": int(len(self.lags)),
            "passed": self.passed,
            "max_abs": float(np.max(np.abs(self.values))) if len(self.values) else 0.0,
        }


def _allowed(m: int) -> int:
    """Lags a white residual puts outside its 95 % band in 95 % of records: the 95th percentile of Binomial(m, 0.05)
    (lags treated as independent), 3 of 20."""
    from scipy.stats import binom

    return int(binom.ppf(0.95, m, 0.05))


def _verdict(values: np.ndarray, band: float, n: int) -> tuple[int, bool]:
    """Lags outside the +-2 sigma band, and the verdict: no more of them than chance allows (:func:`_allowed`)
    and none beyond the Bonferroni band z(1 - 0.025/m)/sqrt(n) (one large spike is a finding too)."""
    from scipy.stats import norm

    m = len(values)
    out = int(np.sum(np.abs(values) > band))
    big = float(np.max(np.abs(values))) if m else 0.0
    return out, out <= _allowed(m) and big <= norm.ppf(1 - 0.025 / max(m, 1)) / np.sqrt(n)


def whiteness(e: np.ndarray, max_lag: int) -> CorrelationTest:
    """Autocorrelation of ``e`` at lags 1..max_lag against +-2/sqrt(n)."""
    e = np.asarray(e, float)
    e = e[np.isfinite(e)] - np.nanmean(e)
    n = len(e)
    m = int(min(max_lag, n - 2))
    den = float(e @ e) or 1.0
    acf = np.array([e[:-k] @ e[k:] / den for k in range(1, m + 1)])
    band = 2.0 / np.sqrt(n)
    out, ok = _verdict(acf, band, n)
    return CorrelationTest("whiteness", np.arange(1, m + 1), acf, band, out, ok)


def rudder_correlation(e: np.ndarray, delta: np.ndarray, max_lag: int) -> CorrelationTest:
    """Cross-correlation of the rudder (leading) and ``e`` at lags 0..max_lag against +-2/sqrt(n)."""
    ok = np.isfinite(e)
    e = np.asarray(e, float)[ok]
    u = np.asarray(delta, float)[ok]
    e, u = e - e.mean(), u - u.mean()
    n = len(e)
    m = int(min(max_lag, n - 2))
    den = float(np.sqrt((e @ e) * (u @ u))) or 1.0
    ccf = np.array([u[: n - k] @ e[k:] / den for k in range(0, m + 1)])
    band = 2.0 / np.sqrt(n)
    out, ok = _verdict(ccf, band, n)
    return CorrelationTest("rudder", np.arange(0, m + 1), ccf, band, out, ok)


def residual_tests(
    e: np.ndarray, delta: np.ndarray, channels: tuple[str, ...], max_lag: int = 20
) -> dict[str, dict[str, CorrelationTest]]:
    """Per channel: whiteness and rudder cross-correlation of the residual columns of ``e`` (N, ny)."""
    return {
        c: {"whiteness": whiteness(e[:, i], max_lag), "rudder": rudder_correlation(e[:, i], delta, max_lag)}
        for i, c in enumerate(channels)
    }
