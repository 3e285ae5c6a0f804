"""Likelihood-ratio CUSUM along change signatures, with the change named (seed 000 ch. 5 improved).

A relative change ``theta`` of property ``j`` moves the prior model's prediction by about
``theta * S_j(t)``, ``S_j = d r_hat / d ln(property_j)`` (yaw inertia acts at turn onsets and ends,
damping in steady turns, actuator gain with the input). The residual ``eps = r - r_hat`` is
coloured (input noise and model error pass through the yaw dynamics), so residual and signatures
are averaged over 1 s blocks (the signatures are slower than that) and whitened with the prior's
AR innovation filter. For white innovations ``sigma_w`` the
log-likelihood ratio of "changed by +-theta1 along S_j" against "no change" accumulates as a
two-sided CUSUM per signature (Basseville and Nikiforov 1993, section 2.2).

The thresholds come from no-change records simulated from the prior alone
(``yawmodel.null_records``: its bootstrap parameter errors, the nominal data's noise levels on
every signal, this recording's smoothed inputs): a 500 s prior's I_r is only known to about 2 %
(the Cramer-Rao bound of the nine-parameter fit), and that error moves r_hat along the very
signatures tested; input noise passing through the yaw dynamics is slow, coloured noise on r_hat.
bench_detect (10 priors x 100 runs, Table 4.1 noise, full model): 2.1 % false alarms for a 2 %
design (12.0 % with the former Gaussian null from the fit's covariance and AR residual noise).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diagnose.detect.cusum import cusum_path, first_alarms
from diagnose.detect.yawmodel import CANDIDATES, YawPrior, block_mean, whiten


@dataclass
class SignatureCusum:
    """Two-sided LR-CUSUM along each candidate signature for a relative change of size ``theta1``."""

    prior: YawPrior
    theta1: float = 0.05
    h: float = np.inf

    def statistics(self, eps_blocks: np.ndarray, S: np.ndarray) -> np.ndarray:
        """Statistic per 1 s block, (nb, k) or (nb, runs, k), for block-mean residuals (nb,) or
        (nb, runs) and per-sample signatures ``S`` (n, k): max of the up and down CUSUMs."""
        p = self.prior
        ew = whiten(np.asarray(eps_blocks, float), p.ar)
        m = self.theta1 * whiten(block_mean(S, p.block), p.ar)[: len(ew)]
        if ew.ndim == 2:
            m = m[:, None, :]
        e = ew[..., None]
        s2 = p.sigma_w**2
        half = 0.5 * m * m
        return np.maximum(cusum_path((m * e - half) / s2), cusum_path((-m * e - half) / s2))

    def alarms(self, stat: np.ndarray) -> np.ndarray:
        """First alarm sample index per run (any candidate over its threshold; the end of the
        alarming block), -1 where none; ``stat`` from :meth:`statistics` ((nb, k) or (nb, runs, k))."""
        b = first_alarms(stat.max(axis=-1), self.h)
        return np.where(b >= 0, (b + 1) * self.prior.block - 1, -1)


def calibrate(prior: YawPrior, S: np.ndarray, null: np.ndarray, theta1: float = 0.05,
              false_alarm: float = 0.02) -> SignatureCusum:
    """Threshold: the (1 - false_alarm) quantile of the statistic's maximum (over time and the
    candidates) over ``null`` (nb, runs) no-change block residuals (:func:`yawmodel.null_records`)."""
    det = SignatureCusum(prior, theta1)
    det.h = float(np.quantile(det.statistics(null, S).max(axis=(0, 2)), 1 - false_alarm))
    return det


def attribute(eps: np.ndarray, S: np.ndarray, prior: YawPrior, upto: int, null: np.ndarray | None = None) -> dict:
    """Which candidate explains the residual up to sample ``upto``: per candidate, the GLR estimate
    ``theta_j = sum S_j eps / sum S_j^2`` (whitened) and its log-likelihood ratio
    ``(sum S_j eps)^2 / (2 s^2 sum S_j^2)``; the largest names the change. At an onset more
    inertia and less actuator gain look alike, so the whole record up to ``upto`` is used.
    ``std`` is the estimate's standard deviation under no change: from the no-change records
    ``null`` (n, runs) when given (noise and the prior's own parameter error), else from the noise alone."""
    w = slice(0, max(upto // prior.block, 2))
    Sw = whiten(block_mean(S, prior.block), prior.ar)[w]
    s2 = prior.sigma_w**2
    den = np.maximum(np.sum(Sw**2, axis=0), 1e-300)

    def project(e: np.ndarray) -> np.ndarray:
        return Sw.T @ whiten(block_mean(e, prior.block), prior.ar)[w]

    num = project(eps)
    std = np.std(project(null), axis=1) / den if null is not None else np.sqrt(s2 / den)
    llr = num**2 / (2 * s2 * den)
    order = np.argsort(-llr)
    return {"property": CANDIDATES[int(order[0])],
            "candidates": {c: {"relative_change": float(num[i] / den[i]), "llr": float(llr[i]), "std": float(std[i])}
                           for i, c in enumerate(CANDIDATES)},
            "llr_margin": float(llr[order[0]] - llr[order[1]])}
