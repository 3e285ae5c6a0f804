"""Selection of candidate physics by held-out evidence (Källström 1977: output error, AIC, split data).

Each round:
1. one batched simulation per run gives the output-error sensitivities of every untried
   candidate at the current model (:mod:`diagnose.heldout`);
2. every candidate is scored by a linearised refit on the fit runs and its residual on each
   held-out run (leave one run out, or the validation runs): AIC on the held-out likelihood,
   the number of runs it improves and the largest fall of any run's per-channel fit; it must
   also be significant on the estimation data (F test with a sample count corrected for
   residual colour);
3. candidates are tried in order of held-out AIC: an output-error refit within physical
   bounds, regularised towards the profile; a refit that diverges, an implausible estimate, one
   too small to matter (:func:`diagnose.plausible.practical`: below a ship-scaled minimum size,
   or moving the simulated outputs by less than half the noise) or one the nonlinear
   likelihood-ratio test does not confirm is rejected and said; with
   validation runs the refitted model must also pass the held-out test by simulation;
4. after a candidate is kept, each earlier one is tested again without it (backtracking).
Rounds repeat until no candidate passes. The control (no missing physics) ends with nothing.

With --fit-on runs the baseline parameters those runs determine at least as well as the
diagnosed runs are held as fitted there (a finding is what differs from them); only the others
are refitted on the diagnosed runs (:func:`held_by_fit_on`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from diagnose import delaycheck, plausible, windstart
from diagnose.candidates import STEADY_WIND, Candidate
from diagnose.describe import describe
from diagnose.heldout import (
    Parts,
    Verdict,
    grams,
    heldout_rss,
    insample_rss,
    make_parts,
    refit_verdict,
    rejection_entry,
    verdict,
)
from diagnose.model import AugmentedModel, Prepared, fit, residuals, stack
from diagnose.reference import ReferencedModel
from diagnose.search_limits import (  # noqa: F401  (moved: the names other modules and tests read from diagnose.search)
    base_bounds,
    base_term_index,
    held_by_fit_on,
    prior_sd,
    refitted_alias,
    slot_bounds,
)
from diagnose.significance import ALPHA, independent_heldout, inflation, lr_stats, passes

MUCH_WORSE = 15.0  # percentage points of fit a finding may cost one channel of a held-out run
MAX_TRIES = 8  # nonlinear refits per round (in order of held-out AIC)
MAX_PASSED = 3  # refitted candidates that pass, compared by held-out AIC before one is kept


@dataclass
class Step:
    candidate: Candidate
    rss_before: float
    rss_after: float
    f_stat: float
    p_value: float
    delta_aic: float  # on the held-out likelihood
    cv_gain: float  # relative drop of the pooled held-out weighted RSS
    dof_gain: np.ndarray  # in-sample RSS drop per DOF (weighted)
    correlation: float
    heldout: list[dict] = field(default_factory=list)  # per held-out run: fit before/after per channel
    plausibility: str = ""


@dataclass
class SearchResult:
    P: np.ndarray
    cov: np.ndarray
    free: list[int]
    steps: list[Step] = field(default_factory=list)
    screened: list[dict] = field(default_factory=list)
    rejected: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    base_free: list[int] = field(default_factory=list)
    prior_std: np.ndarray | None = None  # the refit's prior std per parameter (None: no prior)


class _Search:
    """State of one selection: the model, the data, the folds and the prior."""

    def __init__(
        self,
        model: AugmentedModel,
        preps: list[Prepared],
        val_preps: list[Prepared],
        w: np.ndarray,
        base_free: list[int],
        alpha: float,
        calm: list[Prepared] | None = None,
    ):
        self.model, self.preps, self.val, self.w, self.alpha = model, preps, list(val_preps), w, alpha
        self.all = preps + self.val
        self.parts: Parts = make_parts(preps, self.val)
        self.diag_parts = [q for q, i in enumerate(self.parts.prep) if i < len(preps)]
        self.base_free = list(base_free)
        self.held: list[int] = []
        self.ref = model.p0()
        self.wr = [w] * len(preps)  # one weight per output and recording (the same for every recording)
        r0 = stack(residuals(model, preps, self.ref[None]), self.wr)[0]
        self.tau = inflation(r0)
        level = np.sqrt(float(r0 @ r0) / max(len(r0), 1) * self.tau)
        self.sd = prior_sd(self.ref, self.base_free, level, model.n_params)
        self.held = held_by_fit_on(model, calm or [], preps, w, self.ref, self.base_free)
        self.base_free = [j for j in self.base_free if j not in self.held]
        self.prior = (self.ref, self.sd) if self.base_free else None
        self.bounds = base_bounds(self.ref, self.base_free, model)
        self.n_cand = max(len(model.candidates), 1)
        self.independent = independent_heldout(len(self.val), len(preps))

    def prior_terms(self, P: np.ndarray, cols: list[int]) -> tuple[np.ndarray, np.ndarray]:
        D = np.zeros(len(cols))
        g = np.zeros(len(cols))
        for k, j in enumerate(cols):
            if np.isfinite(self.sd[j]):
                D[k] = 1.0 / self.sd[j] ** 2
                g[k] = (P[j] - self.ref[j]) / self.sd[j] ** 2
        return D, g

    def refit(self, P: np.ndarray, free: list[int], extra_bounds: dict, max_iter: int = 10):
        return fit(
            self.model, self.preps, P, free, self.wr, max_iter=max_iter, bounds={**self.bounds, **extra_bounds}, prior=self.prior
        )

    def val_rss(self, P: np.ndarray) -> np.ndarray:
        """Held-out RSS per validation run and channel by simulation (n_val, 3)."""
        res = residuals(self.model, self.val, P[None])
        return np.array([np.sum((r[0, 1:] * self.w) ** 2, axis=0) for r in res])


def select(
    model: AugmentedModel,
    preps: list[Prepared],
    w: np.ndarray,
    *,
    val_preps: list[Prepared] | None = None,
    base_free: list[int] | None = None,
    max_rounds: int = 5,
    alpha: float = ALPHA,
    inputs: np.ndarray | None = None,
    calm_preps: list[Prepared] | None = None,
) -> SearchResult:
    """Greedy forward selection with backtracking over ``model.candidates``. ``calm_preps``: the
    --fit-on runs the baseline was fitted on; what they determine of ``base_free`` is held
    (:func:`held_by_fit_on`)."""
    S = _Search(model, preps, val_preps or [], w, base_free or [], alpha, calm_preps)
    x0 = model.x0_params()
    out = SearchResult(model.p0(), np.zeros((0, 0)), [], base_free=list(S.base_free))
    if S.held:
        out.notes.append(
            f"{len(S.held)} of {len(S.held) + len(S.base_free)} baseline parameters are determined by the "
            "--fit-on runs and held as fitted there (a finding is what differs from those runs)"
        )
    free = list(S.base_free) + x0
    P, cov, rss = S.refit(out.P, free, {}, max_iter=20)
    if not np.isfinite(rss) and S.base_free:
        out.notes.append(
            "the bounded refit of the baseline parameters on the diagnosed runs diverged; "
            "it was rejected and the baseline kept as given"
        )
        S.base_free, S.prior, S.bounds = [], None, {}
        free = list(x0)
        P, cov, rss = S.refit(model.p0(), free, {}, max_iter=20)
    # with reference runs the baseline refit is the joint structure fit the candidates are judged against: kept
    if S.base_free and np.isfinite(rss) and not isinstance(model, ReferencedModel):
        v = _baseline_verdict(S, model.p0(), P, free)
        if not v.accepted(MUCH_WORSE):
            out.notes.append(
                f"refitting the baseline parameters on the diagnosed runs does not improve the held-out runs "
                f"(held-out AIC {v.delta_aic:+.1f}, {v.improved}/{v.n_folds} better, worst fit drop "
                f"{v.worst_drop:.1f} points): the baseline is kept as given"
            )
            S.base_free, S.prior, S.bounds = [], None, {}
            free = list(x0)
            P, cov, rss = S.refit(model.p0(), free, {}, max_iter=20)
    out.base_free = list(S.base_free)
    chosen: list[Candidate] = []
    alias = refitted_alias(model, S.base_free)
    for rnd in range(max_rounds):
        todo = [c for c in model.candidates if c not in chosen and c.key not in alias]
        if not todo:
            break
        best = _round(S, P, free, todo, rnd, out, inputs)
        if best is None:
            break
        c, new, P, cov, step, _profile = best
        chosen.append(c)
        free = free + new
        out.steps.append(step)
        P, free, cov = _backtrack(S, P, free, cov, out, chosen)
    out.P, out.cov, out.free = P, cov, free
    out.prior_std = S.sd if S.prior is not None else None
    return out


def _rank(S: _Search, P: np.ndarray, free: list[int], todo: list[Candidate]):
    """The linearised screen of a round: (ranked, rss0_in, M, r_cur) with ranked the tuples
    (held-out delta AIC, candidate, verdict, p-value, F, Gauss-Newton step), best first."""
    model = S.model
    base_cols = [j for j in free if j < model.n_slots_end]  # refitted baseline and kept candidates
    cand_cols = [j for c in todo for j in model.slot_of[c.key]]
    cols = base_cols + cand_cols
    g = grams(model, S.all, S.parts, P, cols, S.wr + [S.w] * len(S.val), model.steps(S.preps, P))
    D, pg = S.prior_terms(P, cols)
    sel0 = list(range(len(base_cols)))
    test = S.parts.test
    rss0_ho = heldout_rss(g, S.parts, sel0, D, pg)
    rss0_in, _ = insample_rss(g, S.parts, sel0, D, pg, S.diag_parts)
    M = int(g.n_rows[S.diag_parts].sum()) * 3
    r_cur = stack(residuals(model, S.preps, P[None]), S.wr)[0]
    tau = inflation(r_cur)
    ranked = []
    for c in todo:
        pos = [len(base_cols) + cand_cols.index(j) for j in model.slot_of[c.key]]
        if not np.any(g.G[:, :, pos, pos] > 0):
            continue
        q = len(pos)
        v = verdict(rss0_ho, heldout_rss(g, S.parts, sel0 + pos, D, pg), g.den[test], g.n_rows[test], q, tau)
        rss1_in, step = insample_rss(g, S.parts, sel0 + pos, D, pg, S.diag_parts)
        f_stat = ((rss0_in - rss1_in) / q) / (max(rss1_in, 1e-300) / max(M - q, 1)) / tau
        p_val = float(stats.f.sf(f_stat, q, max(M / tau - q, 1))) if f_stat > 0 else 1.0
        ranked.append((v.delta_aic, c, v, p_val, f_stat, step[-q:]))
    ranked.sort(key=lambda x: x[0])
    return ranked, rss0_in, M, r_cur


def _screened(rnd: int, ranked: list) -> dict:
    """The round's screen for the report."""
    return {
        "round": rnd + 1,
        "candidates": [
            {
                "key": c.key,
                "effect": c.effect,
                "heldout_delta_aic": v.delta_aic,
                "heldout_gain": v.gain,
                "runs_improved": f"{v.improved}/{v.n_folds}",
                "worst_fit_drop": v.worst_drop,
                "p_value": p,
                "f": f,
                "estimate": [float(b) for b in beta],
            }
            for _a, c, v, p, f, beta in ranked
        ],
    }


def _round(
    S: _Search, P: np.ndarray, free: list[int], todo: list[Candidate], rnd: int, out: SearchResult, inputs: np.ndarray | None
):
    ranked, rss0_in, M, r_cur = _rank(S, P, free, todo)
    out.screened.append(_screened(rnd, ranked))
    tries = 0
    passed = []
    val0: list[np.ndarray] = []  # the validation runs' RSS at the round's P, once simulated (every try reads it)
    best = ranked[0][1] if ranked else None
    # try first those the linearised held-out test already accepts on every count, then the rest
    for _aic, c, v, p_val, _f, beta in sorted(ranked, key=lambda x: (not x[2].accepted(MUCH_WORSE), x[0])):
        # with validation runs the linearised verdict only orders the candidates: the refitted
        # model is judged on them by simulation (a current or a delay is far from linear). Without
        # them, so is the candidate best by held-out AIC: a 4 s delay's Gauss-Newton step from zero
        # made a left-out run 80 % worse, its refit every run better (its refit is judged again)
        screen_ok = (v.delta_aic < 0 and v.gain > 0) if S.val or c is best else v.accepted(MUCH_WORSE)
        if not (screen_ok and passes(p_val, v.gain, S.n_cand, S.alpha, S.independent)):
            continue
        if tries >= MAX_TRIES:
            break
        tries += 1
        res = _try(S, P, r_cur, free, c, beta, rss0_in, v, M, inputs, val0)
        if isinstance(res, dict):
            out.rejected.append({"round": rnd + 1, "key": c.key, "effect": c.effect, **res})
            continue
        passed.append(res)
        if len(passed) >= MAX_PASSED:
            break
    # the refitted survivors best first on the held-out runs (a delay or a current is far from its
    # linearised score); a delay against a damping term by the residual's phase and the delay profile
    passed.sort(key=lambda r: r[4].delta_aic)
    pick, note = delaycheck.arbitrate(S.model, S.preps, P, passed)
    if note:
        out.notes.append(note)
    return pick or (passed[0] if passed else None)


def _try(
    S: _Search,
    P: np.ndarray,
    r0: np.ndarray,
    free: list[int],
    c: Candidate,
    beta: np.ndarray,
    rss0: float,
    v: Verdict,
    M: int,
    inputs: np.ndarray | None,
    val0: list[np.ndarray] | None = None,
):
    """Nonlinear refit of one candidate from P (weighted residual ``r0``): (candidate, its slots,
    P1, cov1, :class:`Step`, the delay grid's :class:`delaycheck.Profile` or None); a rejection
    entry (``reason``, and the held-out criterion that failed as ``failed``) when it is rejected.
    ``val0``: holds the validation runs' RSS at P once a try of the round has simulated it."""
    model = S.model
    new = model.slot_of[c.key]
    start = _line_start(S, P, new, beta)
    profile = None
    if c.effect == "actuator_delay":
        start[new[0]], profile = delaycheck.grid_delay(model, S.preps, S.wr, P, new[0])
    elif c.key == STEADY_WIND:
        start = windstart.grid_start(model, S.preps, S.wr, start, new[:2])
    P1, cov1, rss1 = S.refit(start, free + new, slot_bounds(model, c, P))
    if not np.isfinite(rss1):
        return {"reason": "the refit diverged (non-finite or exploding simulation): not scored"}
    params = describe(c, model, P1, cov1, free + new)
    ok, why = plausible.check(c.effect, params, model.profile, inputs)
    if not ok:
        return {"reason": f"implausible estimate: {why}", "implausible": why}
    spread = float(np.std(np.concatenate([p.y for p in S.preps])[:, c.slots[0].index])) if c.effect == "sensor_bias" else None
    big, small_why = plausible.practical(c.effect, params, model.profile, _visible(S, P1, new), spread)
    if not big:
        return {"reason": f"too small to matter: {small_why}"}
    if c.effect == "sensor_bias":
        y = np.concatenate([p.y for p in S.preps])[:, c.slots[0].index]
        if abs(P1[new[0]]) >= 0.5 * np.std(y):
            return {
                "reason": "a sensor bias as large as the signal trades off against the initial state (Källström 1977: the initial state estimated with the parameters)"
            }
    f_nl, p_nl, res1 = _lr_test(S, P1, rss0, rss1, len(new), M)
    if not passes(p_nl, v.gain, S.n_cand, S.alpha, S.independent):
        return {"reason": f"the nonlinear refit is not significant (F = {f_nl:.1f}, p = {p_nl:.2g})"}
    if S.val:
        val0 = [] if val0 is None else val0
        if not val0:
            val0.append(S.val_rss(P))
        heldout = verdict(val0[0], S.val_rss(P1), v.den, _val_rows(S), len(new), S.tau)
    else:
        heldout = refit_verdict(model, S.all, S.parts, P1, free + new, S.wr, S.prior_terms, v, len(new), S.tau)
    failed = rejection_entry(heldout, MUCH_WORSE, bool(S.val))
    if failed:
        return failed
    if S.val and heldout.best_gain < plausible.MIN_HELDOUT_FIT_POINTS:
        return {
            "reason": f"too small to matter: it raises no channel of a validation run by {plausible.MIN_HELDOUT_FIT_POINTS:g} "
            f"fit point or more (at best {heldout.best_gain:+.2f})"
        }
    dof_gain = (r0.reshape(-1, 3) ** 2 - res1.reshape(-1, 3) ** 2).sum(axis=0)
    corr = float(np.corrcoef(r0 - res1, r0)[0, 1]) if np.std(r0 - res1) > 0 else 0.0
    step = Step(
        c,
        rss0,
        rss1,
        f_nl,
        p_nl,
        heldout.delta_aic,
        heldout.gain,
        dof_gain,
        corr,
        heldout.table([S.parts.label[t] for t in S.parts.test]),
        why,
    )
    return c, new, P1, cov1, step, profile


def _visible(S: _Search, P1: np.ndarray, own: list[int]) -> float:
    """How far the finding ``own`` moves the simulated outputs of the diagnosed runs: RMS of
    the difference with and without it (the rest as fitted), in noise units (the residual
    weights), largest over the channels."""
    P0 = P1.copy()
    P0[own] = 0.0
    R = stack(residuals(S.model, S.preps, np.stack([P1, P0])), S.wr)
    d = (R[1] - R[0]).reshape(-1, 3)
    return float(np.max(np.sqrt(np.mean(d**2, axis=0))))


def _baseline_verdict(S: _Search, P0: np.ndarray, P: np.ndarray, free: list[int]) -> Verdict:
    """Held-out verdict of the baseline refit itself (against the baseline as given)."""
    model = S.model
    if S.val:
        den = np.array([np.sum(((p.y[1:] - p.y[1:].mean(axis=0)) * S.w) ** 2, axis=0) for p in S.val])
        return verdict(S.val_rss(P0), S.val_rss(P), den, _val_rows(S), len(S.base_free), S.tau)
    P0x = P0.copy()
    P0x[model.x0_params()] = P[model.x0_params()]
    g = grams(model, S.preps, S.parts, P0x, S.base_free, S.wr, model.steps(S.preps, P0x))
    D, pg = S.prior_terms(P0x, S.base_free)
    test = S.parts.test
    rss1 = heldout_rss(g, S.parts, list(range(len(S.base_free))), D, pg)
    return verdict(g.rr[test], rss1, g.den[test], g.n_rows[test], len(S.base_free), S.tau)


def _val_rows(S: _Search) -> np.ndarray:
    return np.array([p.n for p in S.val], float)


def _backtrack(S: _Search, P: np.ndarray, free: list[int], cov: np.ndarray, out: SearchResult, chosen: list[Candidate]):
    """Drop an earlier finding that the later ones made redundant (likelihood-ratio test of it
    given the others, and with validation runs its held-out AIC)."""
    model = S.model
    if len(out.steps) < 2:
        return P, free, cov
    r_with = stack(residuals(model, S.preps, P[None]), S.wr)[0]
    for st in list(out.steps[:-1]):
        own = model.slot_of[st.candidate.key]
        rest = [j for j in free if j not in own]
        P_wo = P.copy()
        P_wo[own] = 0.0
        P2, cov2, rss_wo = S.refit(P_wo, rest, {}, max_iter=4)
        if not np.isfinite(rss_wo):
            continue
        _f, p_b = lr_stats(r_with, rss_wo, float(r_with @ r_with), len(own), len(r_with))
        drop = not passes(p_b, st.cv_gain, S.n_cand, S.alpha, S.independent)
        if not drop and S.val:
            v = verdict(S.val_rss(P2), S.val_rss(P), np.ones((len(S.val), 3)), _val_rows(S), len(own), S.tau)
            drop = v.delta_aic >= 0
        if drop:
            out.steps.remove(st)
            chosen.remove(st.candidate)
            out.rejected.append(
                {
                    "key": st.candidate.key,
                    "effect": st.candidate.effect,
                    "reason": "made redundant by a later finding (backtracking)",
                }
            )
            free, P, cov = rest, P2, cov2
            r_with = stack(residuals(model, S.preps, P[None]), S.wr)[0]
    return P, free, cov


def _lr_test(S: _Search, P1: np.ndarray, rss0: float, rss1: float, q: int, M: int) -> tuple[float, float, np.ndarray]:
    """Likelihood-ratio F test of q added parameters at P1, and P1's weighted residual."""
    res1 = stack(residuals(S.model, S.preps, P1[None]), S.wr)[0]
    f, p = lr_stats(res1, rss0, rss1, q, M)
    return f, p, res1


def _line_start(S: _Search, P: np.ndarray, new: list[int], beta: np.ndarray) -> np.ndarray:
    """Best of a few fractions of the linearised step (a strongly nonlinear misfit can overshoot)."""
    fr = np.array([0.05, 0.15, 0.3, 0.6, 1.0])
    Pb = np.repeat(P[None], len(fr), axis=0)
    Pb[:, new] = P[new] + np.outer(fr, beta)
    R = stack(residuals(S.model, S.preps, Pb), S.wr)
    return Pb[int(np.argmin(np.einsum("ij,ij->i", R, R)))]
