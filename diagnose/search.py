"""Forward selection of candidate physics (seed 004: residual tests, likelihood ratio / AIC).

Each round:
1. one batched simulation gives the output-error sensitivities of every untried candidate at
   the current model (a Gauss-Newton linearisation: the score test of each augmentation);
2. per candidate, a linearised least-squares fit gives the drop in the noise-weighted residual
   sum of squares; its F statistic uses an effective sample count corrected for residual
   colour (Bartlett), and the BIC must improve;
3. time-block cross-validation (fit on even blocks, test on odd blocks and vice versa) must
   show the candidate also improves data it was not fitted on;
4. the best survivor is refitted by output error (nonlinear), jointly with those already kept,
   and kept if the nonlinear likelihood-ratio F test confirms it.
Rounds repeat until nothing significant is left. The control (no missing physics) must end
with no finding.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from diagnose.candidates import Candidate
from diagnose.model import AugmentedModel, Prepared, fit, jacobian, residuals, stack

ALPHA = 1e-6  # family-wise significance per round (Bonferroni over candidates); strict because
# open-loop residuals carry coloured process noise that the inflation factor only approximates
N_BLOCKS = 8
MIN_CV_GAIN = 0.002  # held-out weighted RSS must drop by at least 0.2 %
STRONG_CV_GAIN = 0.10  # ... or by 10 %, which then needs only p < 0.01 (coloured real-data residuals)
ALPHA_STRONG = 1e-2


def _passes(p_value: float, cv_gain: float, n_cand: int, alpha: float = ALPHA) -> bool:
    """Significant on the estimation data AND better on held-out blocks (seed 004: AIC plus
    cross-validation between parts). Either very significant with any held-out gain, or a large
    held-out gain with ordinary significance."""
    return (p_value < alpha / n_cand and cv_gain > MIN_CV_GAIN) or (p_value < ALPHA_STRONG / n_cand and cv_gain > STRONG_CV_GAIN)


@dataclass
class Step:
    candidate: Candidate
    rss_before: float
    rss_after: float
    f_stat: float
    p_value: float
    delta_bic: float
    cv_gain: float
    dof_gain: np.ndarray  # RSS drop per DOF (weighted)
    correlation: float


@dataclass
class SearchResult:
    P: np.ndarray
    cov: np.ndarray
    free: list[int]
    steps: list[Step] = field(default_factory=list)
    screened: list[dict] = field(default_factory=list)


def inflation(res: np.ndarray, n_dof: int = 3, max_lag: int = 30) -> float:
    """Variance inflation of coloured residuals (largest over the DOFs).

    ``res`` is noise-weighted, so a DOF whose RMS is near 1 is at the noise level: its colour is
    process noise (slow drift a short window misses), and the inflation is the larger of the
    Bartlett sum 1 + 2 sum (1 - k/K) rho_k and the AR(1) value (1 + rho_1) / (1 - rho_1). A DOF
    far above the noise is coloured by deterministic misfit: Bartlett only (held-out blocks
    guard that case).
    """
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


def block_masks(preps: list[Prepared], n_blocks: int = N_BLOCKS) -> tuple[list[np.ndarray], list[np.ndarray]]:
    even, odd = [], []
    for p in preps:
        blk = (np.arange(p.n + 1) * n_blocks) // (p.n + 1)
        even.append(blk % 2 == 0)
        odd.append(blk % 2 == 1)
    return even, odd


def _ls(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    try:
        beta, *_ = np.linalg.lstsq(J, r, rcond=1e-10)
    except np.linalg.LinAlgError:
        return np.zeros(J.shape[1])
    return beta


def _physical(c: Candidate, model: AugmentedModel, P: np.ndarray, idx: list[int], preps: list[Prepared] | None = None) -> bool:
    """Reject estimates no physical cause produces (a negative delay, a sensor bias as large as
    the signal itself - seed 004 lesson 4: such a bias trades off against other parameters)."""
    if c.effect == "actuator_delay":
        return P[idx[0]] > 0.25 * model_ts(model)
    if c.effect == "sensor_bias" and preps:
        y = np.concatenate([p.y for p in preps])[:, c.slots[0].index]
        return abs(P[idx[0]]) < 0.5 * np.std(y) + 1e-12
    if c.effect == "inertia_change":
        return -0.8 < P[idx[0]] < 4.0
    return True


def model_ts(model: AugmentedModel) -> float:
    return model.profile.sample_time


def select(model: AugmentedModel, preps: list[Prepared], w: np.ndarray, *,
           base_free: list[int] | None = None, max_rounds: int = 5, alpha: float = ALPHA) -> SearchResult:
    """Forward selection over ``model.candidates``; returns the final parameters and the steps."""
    P = model.p0()
    free: list[int] = list(base_free or []) + model.x0_params()
    chosen: list[Candidate] = []
    steps: list[Step] = []
    screened: list[dict] = []
    even, _odd = block_masks(preps)
    # even/odd time blocks over the stacked residual rows (cross-validation)
    m_even = stack([np.broadcast_to(e[None, :, None], (1, len(e), 3)).astype(float) for e in even], np.ones(3))[0] > 0
    m_odd = ~m_even
    x0 = set(model.x0_params())
    n_cand = max(len(model.candidates), 1)
    cov = np.zeros((len(free), len(free)))
    if free:  # a baseline fitted from data is refitted here, so a finding is structure, not parameter error
        P, cov, _ = fit(model, preps, P, free, w, max_iter=20)
    for _round in range(max_rounds):
        todo = [c for c in model.candidates if c not in chosen]
        if not todo:
            break
        cols = [j for c in todo for j in model.slot_of[c.key]]
        r0, J_all = jacobian(model, preps, P, free + cols, w)
        Jf, J = J_all[:, : len(free)], J_all[:, len(free):]
        cv_cols = [k for k, j in enumerate(free) if j not in x0]
        M = len(r0)
        rss0 = float(r0 @ r0)
        ranked = []
        for c in todo:
            idx = [cols.index(j) for j in model.slot_of[c.key]]
            Jc = J[:, idx]
            if not np.any(np.abs(Jc) > 0):
                continue
            Jx = np.hstack([Jf, Jc])
            beta = _ls(Jx, r0)
            r1 = r0 - Jx @ beta
            beta = beta[len(free):]
            rss1 = float(r1 @ r1)
            q = len(idx)
            tau = inflation(r1)
            n_eff = M / tau
            f_stat = ((rss0 - rss1) / q) / (rss1 / max(M - q, 1)) / tau
            p_val = float(stats.f.sf(f_stat, q, max(n_eff - q, 1)))
            dbic = n_eff * np.log(rss0 / max(rss1, 1e-300)) - q * np.log(n_eff)
            cv0 = cv1 = 0.0
            Jfc = Jf[:, cv_cols]  # the initial state lives in the first block only: not cross-validated
            Jxc = np.hstack([Jfc, Jc])
            for fit_m, test_m in ((m_even, m_odd), (m_odd, m_even)):
                b = _ls(Jxc[fit_m], r0[fit_m])
                rt = r0[test_m] - Jxc[test_m] @ b
                r_ref = r0[test_m] - Jfc[test_m] @ _ls(Jfc[fit_m], r0[fit_m]) if cv_cols else r0[test_m]
                cv0 += float(r_ref @ r_ref)
                cv1 += float(rt @ rt)
            cv_gain = (cv0 - cv1) / max(cv0, 1e-300)
            dof_gain = (r0.reshape(-1, 3) ** 2 - r1.reshape(-1, 3) ** 2).sum(axis=0)
            fit_part = Jc @ beta
            corr = float(np.corrcoef(fit_part, r0)[0, 1]) if np.std(fit_part) > 0 else 0.0
            ranked.append((f_stat, c, rss1, p_val, dbic, cv_gain, dof_gain, corr, beta, idx))
        ranked.sort(key=lambda x: -x[0])
        screened.append({"round": _round + 1, "candidates": [
            {"key": x[1].key, "effect": x[1].effect, "f": x[0], "p_value": x[3], "delta_bic": x[4], "cv_gain": x[5],
             "estimate": [float(b) for b in x[8]]} for x in ranked[:8]]})
        best = None
        for f_stat, c, _rss1, p_val, dbic, cv_gain, _dg, corr, beta, _idx in ranked[:3]:
            if f_stat < 0.05 * ranked[0][0]:
                continue
            if not (dbic > 0 and _passes(p_val, cv_gain, n_cand, alpha)):
                continue
            new = model.slot_of[c.key]
            start = _line_start(model, preps, P, new, beta, w)
            if c.effect == "actuator_delay":
                start[new[0]] = _grid_delay(model, preps, P, new[0], w)
            bounds = {new[0]: (0.0, 50 * model_ts(model))} if c.effect == "actuator_delay" else None
            P1, cov1, rss1 = fit(model, preps, start, free + new, w, bounds=bounds)
            if not _physical(c, model, P1, new, preps) or not np.isfinite(rss1):
                continue
            f_nl, p_nl, res1 = _lr_test(model, preps, P1, w, rss0, rss1, len(new), M)
            if not _passes(p_nl, cv_gain, n_cand, alpha):
                continue
            if best is None or rss1 < best[3]:
                dof_gain = (r0.reshape(-1, 3) ** 2 - res1.reshape(-1, 3) ** 2).sum(axis=0)
                step = Step(c, rss0, rss1, f_nl, p_nl, float(dbic), cv_gain, dof_gain, corr)
                best = (c, new, P1, rss1, cov1, step)
        if best is None:
            break
        c, new, P, _rss, cov, step = best
        chosen.append(c)
        free += new
        steps.append(step)
    # backward check: drop a kept candidate that the others made redundant
    if len(steps) > 1:
        for st in list(steps):
            c = st.candidate
            own = model.slot_of[c.key]
            rest = [j for j in free if j not in own]
            P_wo = P.copy()
            P_wo[own] = 0.0
            P2, cov2, rss_wo = fit(model, preps, P_wo, rest, w, max_iter=4)
            r_with = stack(residuals(model, preps, P[None]), w)[0]
            f_b, p_b, _ = _lr_test(model, preps, P, w, rss_wo, float(np.sum(r_with**2)), len(own), len(r_with))
            if not _passes(p_b, st.cv_gain, n_cand, alpha):
                steps.remove(st)
                free, P, cov = rest, P2, cov2
    return SearchResult(P, cov, free, steps, screened)


def _lr_test(model: AugmentedModel, preps: list[Prepared], P1: np.ndarray, w: np.ndarray, rss0: float, rss1: float,
             q: int, M: int) -> tuple[float, float, np.ndarray]:
    """Likelihood-ratio F test of q added parameters, effective sample count from residual colour."""
    res1 = stack(residuals(model, preps, P1[None]), w)[0]
    tau = inflation(res1)
    n_eff = M / tau
    f = ((rss0 - rss1) / q) / (rss1 / max(M - q, 1)) / tau
    p = float(stats.f.sf(f, q, max(n_eff - q, 1))) if f > 0 else 1.0
    return float(f), p, res1


def _line_start(model: AugmentedModel, preps: list[Prepared], P: np.ndarray, new: list[int], beta: np.ndarray,
                w: np.ndarray) -> np.ndarray:
    """Best of a few fractions of the linearised step (a strongly nonlinear misfit can overshoot)."""
    fr = np.array([0.05, 0.15, 0.3, 0.6, 1.0])
    Pb = np.repeat(P[None], len(fr), axis=0)
    Pb[:, new] = np.outer(fr, beta)
    R = stack(residuals(model, preps, Pb), w)
    return Pb[int(np.argmin(np.einsum("ij,ij->i", R, R)))]


def _grid_delay(model: AugmentedModel, preps: list[Prepared], P: np.ndarray, j: int, w: np.ndarray, max_samples: int = 12) -> float:
    """Grid search over whole-sample delays 0..max_samples in one batched simulation."""
    ts = model_ts(model)
    grid = np.arange(max_samples + 1) * ts
    Pb = np.repeat(P[None], len(grid), axis=0)
    Pb[:, j] = grid
    R = stack(residuals(model, preps, Pb), w)
    return float(grid[int(np.argmin((R**2).sum(axis=1)))]) or 0.5 * ts
