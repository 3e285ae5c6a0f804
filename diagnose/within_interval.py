"""The misfit within the runs: a part of a finding's interval (:attr:`diagnose.uncertainty.FindingCov.within`).

A structural misfit that follows the manoeuvre within every run (a wind whose load varies with
the relative angle otherwise than the model's coefficients say) moves a finding from one stretch
of a run to the next, where the runs, each holding the whole manoeuvre, agree. It is measured over
contiguous blocks of each run (:data:`BLOCKS_PER_RUN`) by the cluster-robust sandwich (Liang &
Zeger 1986, over clusters that are contiguous stretches of a time series: the batch-means / HAC
estimator of the estimate's covariance)

    V = H^-1 (sum_b g_b g_b^T) H^-1,   g_b = J_b^T r_b  (block b's gradient at the fit)

beside its exact expectation were the residuals AR(1) noise alone (:func:`block_sandwich`); the
excess of ``V`` over it (:func:`diagnose.uncertainty.excess`) is the misfit's share.

Not the delete-a-block jackknife used before (Künsch 1989; :func:`diagnose.uncertainty.jackknife`
over blocks): its pseudo-value for block i is ``(H - H_i)^-1 g_i``, and where one block holds most
of a parameter's information (a delay, seen only at the few rudder reversals of a short zig-zag)
``H - H_i`` is nearly singular and that block's pseudo-value explodes (issue 26's size bench,
delay-3-two-runs: a within-run std of 6.3 s on a 2.994 s estimate whose noise std is 0.018 s). The
sandwich inverts only ``H``; where one block holds all of a parameter's information its score is
(nearly) the others' with the sign changed and the spread says little about that parameter, which
its exact noise expectation carries (the estimator's leverage), so that the excess stays near
zero instead of exploding.
"""

from __future__ import annotations

import numpy as np

from diagnose.interval95 import BLOCKS_PER_RUN, small_sample
from diagnose.model import AugmentedModel, Prepared
from diagnose.uncertainty import (
    FindingCov,
    ar1,
    excess,
    finite_or_nan,
    inverse_or_pinv,
    positive_part,
    prior_and_findings,
    run_grams,
    sensitivities,
)


def block_pairs(pairs: list[tuple[np.ndarray, np.ndarray]], k: int = BLOCKS_PER_RUN) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each run's (residual, sensitivity) pair cut into ``k`` contiguous blocks."""
    return [(r[ix], J[:, ix]) for r, J in pairs for ix in np.array_split(np.arange(len(r)), k) if len(ix)]


def block_sandwich(
    blocks: list[tuple[np.ndarray, np.ndarray]],
    prior_D: np.ndarray | None = None,
    noise: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The cluster-robust covariance ``V = H^-1 (sum_b g_b g_b^T) H^-1`` of a penalised
    least-squares fit over the contiguous ``blocks`` (Liang & Zeger 1986; module docstring), ``H``
    the blocks' Gram matrices plus the prior's Hessian ``diag(prior_D)``, and its expectation were
    the residuals AR(1) noise alone (``noise``: its (rho, innovation variance) per channel, by
    default from the blocks). Linearised at the fit, ``g_b = u_b - H_b H^-1 U`` with ``u_b`` block
    b's noise score (covariance ``M_b``, :func:`diagnose.uncertainty.run_grams`) and ``U`` their
    sum, so ``E[g_b g_b^T] = M_b - H_b H^-1 M_b - M_b H^-1 H_b + H_b H^-1 M H^-1 H_b`` exactly
    (``M = sum M_b``): the residuals' leverage, which makes the plain sandwich read low over few
    blocks, is in the expectation. Noise in neighbouring blocks is taken as independent (blocks
    long against the AR(1) correlation), in ``V`` as in its expectation, and each block's noise as
    starting from rest (:func:`diagnose.uncertainty.run_grams`): measured against the mean of ``V``
    over 300 AR(1) draws of one 2,000-3,500-sample run, the expectation is 1-7 % low at rho 0.9 and
    5-17 % low at 0.99 (:func:`diagnose.uncertainty.ar1`'s limit; 15-33 % with rho estimated), so
    under strongly coloured noise alone the excess comes out a little positive: the interval widens,
    never narrows. None with fewer than two blocks."""
    if len(blocks) < 2:
        return None
    per = run_grams(blocks, *(noise if noise is not None else ar1(blocks)))
    Hb = np.array([g for g, _m in per])
    Mb = np.array([m for _g, m in per])
    gs = np.array([np.einsum("anc,nc->a", J, r) for r, J in blocks])
    H = Hb.sum(axis=0) + (np.diag(prior_D) if prior_D is not None else 0.0)
    Hi = inverse_or_pinv(H)
    V = Hi @ (gs.T @ gs) @ Hi
    HbHi = Hb @ Hi  # H_b H^-1
    X = (HbHi @ Mb).sum(axis=0)  # sum_b H_b H^-1 M_b
    S = Mb.sum(axis=0)
    meat = S - X - X.T + (HbHi @ S @ HbHi.transpose(0, 2, 1)).sum(axis=0)
    return finite_or_nan(V), finite_or_nan(Hi @ meat @ Hi)


def within_term(
    pairs: list[tuple[np.ndarray, np.ndarray]], cols: list[int], run_part: np.ndarray, prior_D: np.ndarray | None = None
) -> np.ndarray | None:
    """The ``within`` part of :func:`with_within` from the runs' (residual, sensitivity) pairs
    at the fit (every sensitivity column fitted; ``cols`` the findings' columns) and the
    run-to-run part ``run_part`` already in the interval: the excess of the blocks' sandwich over
    its noise expectation (:func:`block_sandwich`), widened for the blocks' number
    (:func:`small_sample`), beyond ``run_part``. None when not measurable (no column, fewer than
    two blocks, or a non-finite spread)."""
    blocks = block_pairs(pairs)
    VE = block_sandwich(blocks, prior_D, ar1(pairs)) if cols else None
    if VE is None:
        return None
    ix = np.ix_(cols, cols)
    if not (np.all(np.isfinite(VE[0][ix])) and np.all(np.isfinite(VE[1][ix]))):
        return None
    B = np.zeros_like(run_part)
    B[ix] = small_sample(len(blocks)) * excess(VE[0][ix], VE[1][ix])
    return finite_or_nan(positive_part(B - run_part))


def with_within(
    cov: FindingCov,
    model: AugmentedModel,
    preps: list[Prepared],
    w: np.ndarray,
    P: np.ndarray,
    free: list[int],
    prior_sd: np.ndarray | None = None,
    pairs: list[tuple[np.ndarray, np.ndarray]] | None = None,
) -> FindingCov:
    """``cov`` with the misfit within the runs as its ``within`` part (:func:`within_term`, module
    docstring) on the findings' parameters. Only its excess over the run-to-run part is added (the
    positive part of the difference), so the interval holds the larger of the two and never shrinks
    (White 1982: the sandwich's meat from the scores, not from a noise model). ``pairs``: the runs'
    :func:`diagnose.uncertainty.sensitivities` at P whose first ``len(free)`` columns are those to
    ``free``, when already computed (:func:`diagnose.uncertainty.finding_pairs`)."""
    if not len(cov.noise) or cov.n_runs < 2:  # one run: no between-run check either, and it says so
        return cov
    if pairs is None:
        pairs = sensitivities(model, preps, P, list(free), w)
    else:
        pairs = [(r, J[: len(free)]) for r, J in pairs]
    D, cols = prior_and_findings(model, free, prior_sd)
    cov.within = within_term(pairs, cols, cov.model, D)
    return cov
