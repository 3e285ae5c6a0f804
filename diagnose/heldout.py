"""Held-out evidence per run and per channel (Källström 1977: split-data cross-validation, Table 3.8).

One batched simulation gives, per recording and per output channel, the Gram matrix of the
output-error sensitivities ``G = J^T J``, ``h = J^T r`` and ``r^T r`` at the current model.
From these, a linearised (Gauss-Newton) refit of any subset of parameters on any subset of
runs, and its residual on every other run, cost a small solve: leave-one-run-out for every
candidate without one simulation per fold.

Folds: with validation runs, fit on every diagnosed run and test on each validation run; with
two or more diagnosed runs, leave one run out; with one run, leave one of four time blocks out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diagnose.model import AugmentedModel, Prepared, residuals
from primitives.ship import DOFS

N_BLOCKS = 4
RUN_RISE = 0.02  # a held-out run's noise-weighted misfit may rise by 2 % at most


@dataclass
class Parts:
    """Row masks (over samples 1..N of each prepared run) of the units evidence is counted on."""

    prep: list[int]  # index into the list of prepared runs
    mask: list[np.ndarray]
    label: list[str]
    test: list[int]  # parts that are held out, one fold each
    fit_of: list[list[int]]  # per fold: the parts fitted


def make_parts(preps: list[Prepared], val_preps: list[Prepared]) -> Parts:
    nd = len(preps)
    if val_preps:
        prep = list(range(nd + len(val_preps)))
        mask = [np.ones(p.n, bool) for p in preps + val_preps]
        label = [p.rec.source for p in preps + val_preps]
        test = list(range(nd, nd + len(val_preps)))
        return Parts(prep, mask, label, test, [list(range(nd)) for _ in test])
    if nd >= 2:
        prep = list(range(nd))
        return Parts(
            prep,
            [np.ones(p.n, bool) for p in preps],
            [p.rec.source for p in preps],
            prep,
            [[j for j in prep if j != i] for i in prep],
        )
    n = preps[0].n
    blk = (np.arange(n) * N_BLOCKS) // max(n, 1)
    mask = [blk == b for b in range(N_BLOCKS)]
    label = [f"{preps[0].rec.source} block {b + 1}/{N_BLOCKS}" for b in range(N_BLOCKS)]
    test = list(range(N_BLOCKS))
    return Parts([0] * N_BLOCKS, mask, label, test, [[j for j in test if j != i] for i in test])


@dataclass
class Grams:
    G: np.ndarray  # (n_parts, 3, c, c)
    h: np.ndarray  # (n_parts, 3, c)
    rr: np.ndarray  # (n_parts, 3)
    den: np.ndarray  # (n_parts, 3) weighted sum of squares of y - mean(y) (the fit denominator)
    cols: list[int]
    n_rows: np.ndarray  # (n_parts,)


def grams(
    model: AugmentedModel,
    all_preps: list[Prepared],
    parts: Parts,
    P: np.ndarray,
    cols: list[int],
    w: np.ndarray,
    h_step: np.ndarray,
) -> Grams:
    """Sensitivities of every part at P to the parameters ``cols`` (one batched simulation per run)."""
    c = len(cols)
    Pb = np.repeat(P[None], c + 1, axis=0)
    for k, j in enumerate(cols):
        Pb[k + 1, j] += h_step[j]
    per_run = {}
    runs = sorted(set(parts.prep))
    for i, res in zip(runs, residuals(model, [all_preps[i] for i in runs], Pb)):  # one batched simulation
        R = res[:, 1:] * (w[i] if isinstance(w, list) else w)  # (c+1, N, 3)
        per_run[i] = (R[0], (R[1:] - R[0]) / h_step[cols][:, None, None])
    return gram_sums(per_run, all_preps, parts, cols, w)


def gram_sums(
    per_run: dict[int, tuple[np.ndarray, np.ndarray]] | list[tuple[np.ndarray, np.ndarray]],
    all_preps: list[Prepared],
    parts: Parts,
    cols: list[int],
    w: np.ndarray | list[np.ndarray],
) -> Grams:
    """The parts' Gram sums from each run's weighted residual (N, 3) and its sensitivity (c, N, 3) to
    ``cols`` (finite differences in :func:`grams`, forward sensitivities in ``baseline``)."""
    c = len(cols)
    n_p = len(parts.prep)
    G = np.zeros((n_p, 3, c, c))
    hv = np.zeros((n_p, 3, c))
    rr = np.zeros((n_p, 3))
    den = np.zeros((n_p, 3))
    for q, (i, m) in enumerate(zip(parts.prep, parts.mask)):
        r0, J = per_run[i]
        y = all_preps[i].y[1:][m] * (w[i] if isinstance(w, list) else w)
        for ch in range(3):
            Jc = J[:, m, ch]  # (c, n)
            G[q, ch] = Jc @ Jc.T
            hv[q, ch] = Jc @ r0[m, ch]
            rr[q, ch] = r0[m, ch] @ r0[m, ch]
            den[q, ch] = float(np.sum((y[:, ch] - y[:, ch].mean()) ** 2))
    return Grams(G, hv, rr, den, list(cols), np.array([int(m.sum()) for m in parts.mask]))


def gauss_newton_step(g: Grams, fit_parts: list[int], sel: list[int], prior_D: np.ndarray, prior_g: np.ndarray) -> np.ndarray:
    """Gauss-Newton step of the columns ``sel`` fitted on ``fit_parts`` (with the prior)."""
    ix = np.ix_(sel, sel)
    A = g.G[fit_parts][:, :, ix[0], ix[1]].sum(axis=(0, 1)) + np.diag(prior_D[sel])
    b = g.h[fit_parts][:, :, sel].sum(axis=(0, 1)) + prior_g[sel]
    A += np.eye(len(sel)) * 1e-10 * (np.trace(A) / len(sel) + 1e-300)
    try:
        return -np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return -np.linalg.lstsq(A, b, rcond=None)[0]


def _rss_after(g: Grams, parts: list[int], sel: list[int], d: np.ndarray) -> np.ndarray:
    """Residual sum of squares per channel over ``parts`` after the step ``d`` of ``sel``."""
    ix = np.ix_(sel, sel)
    G = g.G[parts][:, :, ix[0], ix[1]].sum(axis=0)
    h = g.h[parts][:, :, sel].sum(axis=0)
    return g.rr[parts].sum(axis=0) + 2.0 * h @ d + np.einsum("i,cij,j->c", d, G, d)


def heldout_rss(g: Grams, parts: Parts, sel: list[int], prior_D: np.ndarray, prior_g: np.ndarray) -> np.ndarray:
    """Held-out residual sum of squares (n_folds, 3) after a linearised refit of the columns
    ``sel`` (positions in g.cols) on each fold's fit parts. ``prior_D``/``prior_g``: the prior's
    Hessian diagonal and gradient over all columns (zero where none)."""
    out = np.empty((len(parts.test), 3))
    for f, (t, fit_parts) in enumerate(zip(parts.test, parts.fit_of)):
        out[f] = _rss_after(g, [t], sel, gauss_newton_step(g, fit_parts, sel, prior_D, prior_g)) if sel else g.rr[t]
    return np.maximum(out, 0.0)


def insample_rss(
    g: Grams, parts: Parts, sel: list[int], prior_D: np.ndarray, prior_g: np.ndarray, fit_parts: list[int]
) -> tuple[float, np.ndarray]:
    """Residual sum of squares over ``fit_parts`` after a linearised refit of ``sel`` on them,
    and the step."""
    if not sel:
        return float(g.rr[fit_parts].sum()), np.zeros(0)
    d = gauss_newton_step(g, fit_parts, sel, prior_D, prior_g)
    return max(float(_rss_after(g, fit_parts, sel, d).sum()), 0.0), d


def fit_pct(rss: np.ndarray, den: np.ndarray) -> np.ndarray:
    """NRMSE fit (per cent) from a residual sum of squares and the output's spread."""
    return 100.0 * (1.0 - np.sqrt(rss / np.maximum(den, 1e-300)))


@dataclass
class Verdict:
    """Held-out comparison of a model with a candidate against the model without it."""

    rss0: np.ndarray  # (n_folds, 3)
    rss1: np.ndarray
    den: np.ndarray
    delta_aic: float
    gain: float  # relative drop of the pooled held-out weighted RSS
    improved: int  # folds whose held-out weighted RSS dropped
    worst_drop: float  # largest fall of a per-fold, per-channel fit (percentage points)

    @property
    def n_folds(self) -> int:
        return len(self.rss0)

    @property
    def worst_run_rise(self) -> float:
        """Largest relative rise of a fold's noise-weighted RSS over its three channels."""
        r0, r1 = self.rss0.sum(axis=1), self.rss1.sum(axis=1)
        return float(np.max((r1 - r0) / np.maximum(r0, 1e-300))) if r0.size else 0.0

    def accepted(self, much_worse: float) -> bool:
        """Better by AIC on held-out data, better on most folds, much worse on none: no fold's
        weighted misfit rises by more than RUN_RISE and no channel of a fold loses more than
        ``much_worse`` points of fit."""
        return self.failed_criterion(much_worse) is None

    def failed_criterion(self, much_worse: float) -> dict | None:
        """The first criterion of :meth:`accepted` that fails, named (``criterion``: ``penalty``
        held-out AIC not negative, ``too_few_improved``, ``channel_much_worse``,
        ``run_misfit_rises``, ``no_pooled_gain``) with the verdict's numbers; None when accepted."""
        if not self.delta_aic < 0:
            crit = "penalty"
        elif not 2 * self.improved > self.n_folds:
            crit = "too_few_improved"
        elif not self.worst_drop <= much_worse:
            crit = "channel_much_worse"
        elif not self.worst_run_rise <= RUN_RISE:
            crit = "run_misfit_rises"
        elif not self.gain > 0:
            crit = "no_pooled_gain"
        else:
            return None
        return {
            "criterion": crit,
            "heldout_delta_aic": self.delta_aic,
            "runs_improved": self.improved,
            "n_folds": self.n_folds,
            "heldout_gain": self.gain,
            "worst_fit_drop": self.worst_drop,
            "worst_run_rise": self.worst_run_rise,
            "much_worse": much_worse,
            "run_rise": RUN_RISE,
        }

    @property
    def best_gain(self) -> float:
        """Largest rise of fit (points) on any channel of any fold: what the candidate does at
        best for a held-out run."""
        rise = fit_pct(self.rss1, self.den) - fit_pct(self.rss0, self.den)
        return float(np.max(rise)) if rise.size else 0.0

    def table(self, labels: list[str]) -> list[dict]:
        f0, f1 = fit_pct(self.rss0, self.den), fit_pct(self.rss1, self.den)
        return [
            {"run": lab, "before": dict(zip(DOFS, a.tolist())), "after": dict(zip(DOFS, b.tolist()))}
            for lab, a, b in zip(labels, f0, f1)
        ]


def verdict(rss0: np.ndarray, rss1: np.ndarray, den: np.ndarray, n_rows: np.ndarray, q: int, tau: float) -> Verdict:
    """AIC on the held-out Gaussian likelihood (per-channel variance, Kallstrom's criterion with
    the sample count corrected for residual colour ``tau``) plus per-fold counts."""
    R0, R1 = rss0.sum(axis=0), rss1.sum(axis=0)
    n_eff = max(float(n_rows.sum()) / max(tau, 1.0), 1.0)
    active = R0 > 1e-300
    d_aic = float(n_eff * np.sum(np.log(np.maximum(R1[active], 1e-300) / R0[active])) + 2 * q)
    gain = float((R0.sum() - R1.sum()) / max(R0.sum(), 1e-300))
    improved = int(np.sum(rss1.sum(axis=1) < rss0.sum(axis=1)))
    drop = fit_pct(rss0, den) - fit_pct(rss1, den)
    return Verdict(rss0, rss1, den, d_aic, gain, improved, float(np.max(drop)) if drop.size else 0.0)


def rejection_entry(v: Verdict, much_worse: float, validation: bool) -> dict | None:
    """The search's record of a refitted candidate the held-out test rejects (None: accepted):
    the criterion that failed with its numbers (``failed``), on which held-out data."""
    failed = v.failed_criterion(much_worse)
    if failed is None:
        return None
    on = "validation runs" if validation else "held-out runs (folds refitted from the refitted model)"
    return {
        "reason": f"the refitted model does not improve the {on}",
        "judged_on": "validation" if validation else "folds",
        "failed": failed,
    }


def refit_verdict(
    model: AugmentedModel,
    all_preps: list[Prepared],
    parts: Parts,
    P1: np.ndarray,
    free: list[int],
    w: list,
    prior_terms,
    v: Verdict,
    q: int,
    tau: float,
) -> Verdict:
    """Held-out verdict of the refitted model P1 (no validation runs): each fold's refit is a
    Gauss-Newton step from P1, which is near it, against the round's held-out misfit without the
    candidate (``v.rss0``). ``prior_terms(P, cols)``: the fit's prior Hessian diagonal and gradient."""
    cols = [j for j in free if j < model.n_slots_end]
    g = grams(model, all_preps, parts, P1, cols, w, model.steps([all_preps[i] for i in sorted(set(parts.prep))], P1))
    D, pg = prior_terms(P1, cols)
    return verdict(v.rss0, heldout_rss(g, parts, list(range(len(cols))), D, pg), v.den, g.n_rows[parts.test], q, tau)
