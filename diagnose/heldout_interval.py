"""The model error held-out (--validate) runs show on each finding: a part of its interval.

A model error common to every diagnosed run is a bias no spread over those runs can see. Each
held-out run is a draw the fit never saw: the finding refitted on it alone (one Gauss-Newton step
from the diagnosis's estimate, the rest of the model held) moves by the structural misfit of its
manoeuvre. The excess of those moves over what noise would give is an out-of-sample measure of the
model error on the finding (a cross-validation estimate of prediction error, Stone 1974), added to
its covariance (:class:`diagnose.uncertainty.FindingCov`, part ``heldout``) where it exceeds the
model-error parts already there; :func:`diagnose.uncertainty.half_width_95` gives it one degree of
freedom a held-out run.
"""

from __future__ import annotations

import numpy as np

from diagnose.model import AugmentedModel, Prepared
from diagnose.uncertainty import (
    FindingCov,
    excess,
    finite_or_nan,
    inverse_or_pinv,
    positive_part,
    prior_hessian_diag,
    sandwich,
    sensitivities,
)


def heldout_moves(
    runs: list[list[tuple[np.ndarray, np.ndarray]]], prior_D: np.ndarray | None, claimed: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """Where each held-out run alone would move one finding from the diagnosis's estimate, from
    each run's (residual, sensitivity to the finding's parameters) pairs at that estimate
    (``prior_D`` the prior's Hessian diagonal): the Gauss-Newton step ``delta_v = -H_v^-1 J_v^T r_v``
    (the baseline held as diagnosed: the run's misfit projected on the finding's direction), with
    what noise alone would give it, its run's AR(1) sandwich ``C_v`` plus the estimate's own noise
    covariance ``claimed`` (independent runs; the noise of the other fitted parameters is left out,
    so on a right model a move can come out larger than a noise draw's). A run that does not move
    every finding column is left out; None when a step is not finite."""
    moves = []
    for pairs in runs:
        G = sum(np.einsum("anc,bnc->ab", J, J) for _r, J in pairs)
        if not np.all(np.diag(G) > 0):
            continue
        C_d, H = sandwich(pairs, prior_D)
        delta = -inverse_or_pinv(H) @ sum(np.einsum("anc,nc->a", J, r) for r, J in pairs)
        if not (np.all(np.isfinite(delta)) and np.all(np.isfinite(C_d))):
            return None
        moves.append((delta, C_d + claimed))
    return moves


def heldout_term(
    runs: list[list[tuple[np.ndarray, np.ndarray]]], prior_D: np.ndarray | None, claimed: np.ndarray
) -> tuple[np.ndarray, int] | None:
    """The model error held-out runs show on one finding's parameters (:func:`heldout_moves`, one
    draw a run; ``claimed`` the estimate's own noise covariance): the excess of the mean
    ``delta_v delta_v^T`` over the mean of what noise would give (:func:`excess`), and the runs it
    was measured over. None when no run moves every finding column or a step is not finite."""
    moves = heldout_moves(runs, prior_D, claimed)
    if not moves:
        return None
    return _excess_of(moves), len(moves)


def _excess_of(moves: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """The excess of the moves' mean outer product over the mean of their noise expectations."""
    S = sum(np.outer(d, d) for d, _E in moves) / len(moves)
    return excess(S, sum(E for _d, E in moves) / len(moves))


def with_heldout(
    cov: FindingCov,
    model: AugmentedModel,
    val: list[Prepared],
    w: np.ndarray,
    P: np.ndarray,
    free: list[int],
    keys: list[str],
    prior_sd: np.ndarray | None = None,
) -> FindingCov:
    """``cov`` with the model error the held-out (--validate) runs ``val`` show on each finding
    ``keys`` (:func:`heldout_term`, each finding refitted alone on each run, the rest of ``P``
    held; prior std ``prior_sd`` per parameter) as its ``heldout`` part: only its excess over the
    model-error parts already in the interval (run-to-run, within-run, --fit-on), so the interval
    holds the largest of them. ``heldout_runs``: the fewest held-out runs a finding's part was
    measured over (its degrees of freedom).

    Why: a model error common to every diagnosed run is a bias no spread over those runs can see
    (the MMG battery's model-scale current: 0.5966-0.5973 m/s for 0.6 on every noise seed, its
    interval 0.7 % wide). A held-out run is a draw the fit never saw; the finding fitted on it
    alone moves by the structural misfit of its manoeuvre (there by 0.4-1.4 % of the current,
    5-7 noise stds), an out-of-sample measure of the error common to the diagnosed runs as well
    (a cross-validation estimate of prediction error, Stone 1974). One degree of freedom a run
    (:func:`half_width_95`)."""
    if not val or not len(cov.noise):
        return cov
    X, runs, along = np.zeros_like(cov.noise), [], {}
    done = cov.model + sum((Y for Y in (cov.within, cov.reference) if Y is not None), np.zeros_like(cov.noise))
    for key in keys:
        own = list(model.slot_of[key])
        pos = [free.index(j) for j in own]
        ix = np.ix_(pos, pos)
        D = prior_hessian_diag(None if prior_sd is None else np.asarray(prior_sd, float)[own], len(own))
        moves = heldout_moves([sensitivities(model, [v], P, own, w) for v in val], D, cov.noise[ix])
        if moves:
            X[ix] = positive_part(_excess_of(moves) - done[ix])
            along[key] = [1.0 + _along(d, E, P[own]) for d, E in moves]
            runs.append(len(moves))
    cov.heldout = finite_or_nan(X)
    cov.heldout_runs = min(runs, default=0)
    cov.heldout_along = along
    return cov


def _along(d: np.ndarray, E: np.ndarray, est: np.ndarray) -> float:
    """The move ``d``'s component along ``est`` as a multiple of it (metric: ``E``'s inverse)."""
    Ei = inverse_or_pinv(E)
    den = float(est @ Ei @ est)
    return float(est @ Ei @ d) / den if den > 0 else 0.0
