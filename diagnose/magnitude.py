"""The final estimate of the accepted findings' magnitudes: Kallstrom's maximum-likelihood
output-error criterion with an unknown noise variance per output channel (Källström 1977), i.e.
each channel weighted by the inverse RMS of its own residual, iterated (issue 13).

The search weighs the channels by :func:`diagnose.baseline.noise_scale`, a measurement-noise
level with a floor of 2 % of each signal's spread (quantised real data). That floor, not the
noise, sets the weights whenever the noise is coloured or the signal varies much (a turning
circle's speed drop): on the MMG battery's model-scale AR(1) runs it weighs the yaw rate about
three times (nine in variance) heavier, relative to surge and sway, than their residuals
warrant, and the sway channel, where a steering delay shows most, counts for little. The
weights serve the search (which candidates, judged on held-out runs) well enough; an estimate
reported with a tolerance wants the efficient ones. Maximising the Gaussian likelihood over the
parameters and the three channel variances, ``sum_i (N/2) log(RSS_i)``, is the least-squares
fit with weights ``1 / sqrt(RSS_i / N)`` at the optimum; two reweighted refits reach it (the
weights change by well under 1 % after the first).
"""

from __future__ import annotations

import numpy as np

from diagnose import plausible
from diagnose.candidates import Candidate
from diagnose.describe import describe
from diagnose.model import AugmentedModel, Prepared, fit, residuals, stack
from diagnose.perrun import GUARD_SLACK, per_run_fits, short_label
from diagnose.search import base_bounds, slot_bounds

N_REWEIGHT = 2


def channel_weights(res: list[np.ndarray]) -> np.ndarray:
    """Inverse RMS of each output channel's open-loop residual ``res`` (:func:`diagnose.model.residuals`
    of one parameter vector; pooled over the runs)."""
    r = np.concatenate([x[0, 1:] for x in res])
    rms = np.sqrt(np.mean(r**2, axis=0))
    return 1.0 / np.maximum(rms, 1e-12 * (np.max(rms) + 1e-300))


def ml_refit(
    model: AugmentedModel,
    preps: list[Prepared],
    P: np.ndarray,
    free: list[int],
    chosen: list[Candidate],
    base_free: list[int],
    w: np.ndarray,
    prior_std: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, str]:
    """Refit the ``free`` parameters (the kept findings' slots, the refitted baseline
    parameters ``base_free`` and the initial states) from the search's estimate P (weights
    ``w``, prior std ``prior_std`` towards the profile) by the maximum-likelihood criterion of
    the module docstring, within the search's bounds. The prior keeps its weight relative to
    the data: its std is rescaled by the change of the residual level. Returns (P, weights,
    prior std, note); the search's, with a note, when a refit diverges."""
    if not chosen:
        return P, w, prior_std, ""
    bounds = base_bounds(model.p0(), base_free, model)
    for c in chosen:
        bounds |= slot_bounds(model, c, P)
    res = residuals(model, preps, P[None])  # one simulation per reweighting gives its weights and prior scale
    r_old = stack(res, w)[0]
    Pn, wn, sdn = P, w, prior_std
    for k in range(N_REWEIGHT):
        if k:
            res = residuals(model, preps, Pn[None])
        wk = channel_weights(res)
        prior = None
        if prior_std is not None and base_free:
            r_new = stack(res, wk)[0]
            prior = (model.p0(), prior_std * np.sqrt(float(r_old @ r_old) / max(float(r_new @ r_new), 1e-300)))
        Pk, _cov, rss = fit(model, preps, Pn, free, wk, max_iter=15, tol=1e-7, bounds=bounds, prior=prior, need_cov=False)
        if not np.isfinite(rss):
            return (
                P,
                w,
                prior_std,
                ("the maximum-likelihood refit of the findings' magnitudes diverged: the search's estimate is reported"),
            )
        Pn, wn, sdn = Pk, wk, (prior[1] if prior is not None else prior_std)
    return Pn, wn, sdn, ""


def heldout_worse(
    model: AugmentedModel,
    preps: list[Prepared],
    val_preps: list[Prepared],
    w: np.ndarray,
    P_search: np.ndarray,
    P_ml: np.ndarray,
    w_ml: np.ndarray,
    free: list[int],
) -> str:
    """Why the ML estimate fits the held-out runs worse than the search's, or "" when it does
    not beyond what noise explains. Held-out runs: the validation runs (simulated), otherwise
    each diagnosed run left out in turn (linearised refit, each estimate stepped with the
    weights it was made with). The test is per run and channel, in fit points, which no
    weighting enters: no channel may lose more than GUARD_SLACK points, the least slack the per-run
    guard (:func:`diagnose.perrun.guard`) gives a validation channel against the baseline. A
    misfit weighted by the search's ``w`` would not do: the ML estimate departs from the
    w-optimum on purpose, and on the MMG battery's model-delay-3 it rose 2-6 % on validation runs
    whose channels moved 0.2 points at most. The ML criterion is the better estimator only if
    its model is right (Källström 1977); a model error it weighs differently shows as a held-out
    channel's loss, and then the search's estimate, already judged held out, stands. One
    diagnosed run and no validation run: nothing is held out, the ML estimate stands."""
    if not val_preps and len(preps) < 2:
        return ""
    ref, method = per_run_fits(model, preps, val_preps, w, P_search, P_search, free, w)
    new, _ = per_run_fits(model, preps, val_preps, w, P_search, P_ml, free, w_ml)
    for a, b in zip(ref, new):
        drop = {k: b["after"][k] - a["after"][k] for k in a["after"]}
        k = min(drop, key=drop.get)
        if not drop[k] >= -GUARD_SLACK:  # a NaN fit fails too
            return (
                f"{short_label(a['run'])} ({method}): {k} fit {a['after'][k]:.1f} -> {b['after'][k]:.1f} % "
                f"({drop[k]:+.1f} points, at most -{GUARD_SLACK:g})"
            )
    return ""


def implausible(
    model: AugmentedModel, chosen: list[Candidate], P: np.ndarray, free: list[int], inputs: np.ndarray | None
) -> list[tuple[Candidate, str]]:
    """The findings whose magnitude at P fails :func:`diagnose.plausible.check`, with the reason."""
    out = []
    for c in chosen:
        ok, why = plausible.check(c.effect, describe(c, model, P, np.zeros((0, 0)), free), model.profile, inputs)
        if not ok:
            out.append((c, why))
    return out
