"""Held-out fit per run and channel, before and after a diagnosis, and the per-run guard that
drops findings a held-out run does not support (issue 13)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from diagnose.heldout import RUN_RISE, fit_pct, grams, heldout_rss, make_parts
from diagnose.model import AugmentedModel, Prepared, fit, fit_percent
from diagnose.plausible import MIN_VISIBLE
from diagnose.search import MUCH_WORSE
from primitives.ship import DOFS

FIT_FLOOR = -999.0  # below this an NRMSE fit only says that the simulation left the run


def fit_str(v: float, signed: bool = False, decimals: int = 0) -> str:
    """A fit percentage as a reader can use it: bounded below, a diverged value "n/a" (what "< -999 %"
    and "n/a" mean is said once, in the report's glossary, not at each of the many places they occur)."""
    if not np.isfinite(v):
        return "n/a"
    if v < FIT_FLOOR:
        return f"< {FIT_FLOOR:.0f} %"
    return f"{v:+.{decimals}f} %" if signed else f"{v:.{decimals}f} %"


def short_label(label: str) -> str:
    """A held-out run or block label without the directories ("run.csv block 2/5" stays whole)."""
    src, sep, rest = label.partition(" block ")
    return Path(src).name + sep + rest


def _spread_sq(p: Prepared, w: np.ndarray) -> np.ndarray:
    """Each output's noise-weighted sum of squares about its mean (``w`` the inverse noise scale)."""
    return np.sum(((p.y - p.y.mean(axis=0)) * w) ** 2, axis=0)


def noise_spread(p: Prepared, w: np.ndarray) -> dict[str, float]:
    """Each output's RMS about its mean in noise units (``w`` the inverse noise scale): a fit point
    is worth ``noise_spread / 100`` noise stds (RMS) there, as ``fit = 100 (1 - |e| / |y - mean y|)``."""
    return _per_dof_rms(_spread_sq(p, w), len(p.y))


def _per_dof_rms(sq: np.ndarray, n: int) -> dict[str, float]:
    """Each output's RMS from its sum of squares ``sq`` over ``n`` samples."""
    return dict(zip(DOFS, np.sqrt(sq / max(n, 1)).tolist()))


def _table(preps: list[Prepared], role: str, f0: np.ndarray, f1: np.ndarray, w: np.ndarray) -> list[dict]:
    """Rows of the per-run table; each run's noise-weighted spread of each output (``w`` the
    inverse noise scale) gives its weighted misfit (summed over the channels) from the fit, and
    its RMS about the mean in noise units (``noise_spread``) what a fit point is worth in noise
    (:func:`channel_slack`)."""
    rows = []
    for p, a, b in zip(preps, f0, f1):
        dn = _spread_sq(p, w)
        w0, w1 = (float(np.sum((1 - f / 100.0) ** 2 * dn)) for f in (a, b))
        rows.append(
            {
                "run": p.rec.source,
                "role": role,
                "before": dict(zip(DOFS, a.tolist())),
                "after": dict(zip(DOFS, b.tolist())),
                "weighted_misfit_before": w0,
                "weighted_misfit_after": w1,
                "noise_spread": _per_dof_rms(dn, len(p.y)),  # dn: the same sums, made above
            }
        )
    return rows


def per_run_fits(
    model: AugmentedModel,
    preps: list[Prepared],
    val_preps: list[Prepared],
    w: np.ndarray,
    P0: np.ndarray,
    P: np.ndarray,
    free: list[int],
    w_fit: np.ndarray | None = None,
) -> tuple[list[dict], str]:
    """Fit before/after per run and channel. With validation runs: by simulation. Otherwise each
    diagnosed run is held out in turn: the model refitted without it (a Gauss-Newton step of the
    free parameters from the final fit, weighted by ``w_fit``, the weights P was fitted with,
    default ``w``) is simulated on it (leave one run out, linearised). The weighted misfit of
    the table always weighs by ``w`` (the noise scale), so before and after compare."""
    if val_preps:
        f0 = np.array([fit_percent(p.y, model.simulate(p, P0)[0]) for p in val_preps])
        f1 = np.array([fit_percent(p.y, model.simulate(p, P)[0]) for p in val_preps])
        return _table(val_preps, "validation", f0, f1, w), "validation runs, simulated"
    f0 = np.array([fit_percent(p.y, model.simulate(p, P0)[0]) for p in preps])
    cols = [j for j in free if j < model.n_slots_end]
    if len(preps) < 2 or not cols:
        f1 = np.array([fit_percent(p.y, model.simulate(p, P)[0]) for p in preps])
        return _table(preps, "diagnosed", f0, f1, w), "diagnosed runs, in-sample"
    parts = make_parts(preps, [])
    # the step from P's own optimum: with other weights it would also move P towards their optimum
    g = grams(model, preps, parts, P, cols, w if w_fit is None else w_fit, model.steps(preps, P))
    rss = heldout_rss(g, parts, list(range(len(cols))), np.zeros(len(cols)), np.zeros(len(cols)))
    f1 = fit_pct(rss, g.den)
    return _table(preps, "left out", f0, f1, w), "leave one run out (linearised refit)"


GUARD_SLACK = 1.0  # fit points a validation run may lose on one channel after the diagnosis, at least (channel_slack)


def channel_slack(row: dict) -> dict[str, float]:
    """Fit points each channel of a validation run (a :func:`per_run_fits` row) may lose and count
    as no worse: GUARD_SLACK, or the points a rise of its residual by a fifth of the noise (RMS,
    plausible.MIN_VISIBLE, the size the diagnosis calls visible) is worth there, whichever is larger.
    A fit is 100 (1 - |e| / |y - mean y|), so a residual rising by d noise units (RMS) costs
    100 d / s points on a channel whose spread is s noise units: on a channel spread over few
    noise units a point is less than the noise (MMG battery, gyro-bias: surge on a 10/10 zig-zag
    spreads over 8.3 noise units, where the bias's 0.09 of the noise cost 1.2 points). A relevance
    tolerance, not a test: the output change behind such a rise is at least d (|rms e1 - rms e0| <=
    rms(y1 - y0)) and, beside a residual near the noise, up to about three times d; the run's
    noise-weighted misfit over its channels still may not rise (:func:`guard`)."""
    spread = row.get("noise_spread") or {}
    return {
        k: max(GUARD_SLACK, 100.0 * MIN_VISIBLE / s) if s and s > 0 else GUARD_SLACK
        for k, s in ((k, spread.get(k)) for k in DOFS)
    }


def without(model: AugmentedModel, P: np.ndarray, free: list[int], key: str) -> tuple[np.ndarray, list[int]]:
    """P and the free parameters without the finding ``key``: its slots zeroed and held (the
    one way every rule that drops a finding takes it out; the caller refits)."""
    own = model.slot_of[key]
    P = P.copy()
    P[own] = 0.0
    return P, [j for j in free if j not in own]


def guard(
    model: AugmentedModel,
    preps: list[Prepared],
    val_preps: list[Prepared],
    w: np.ndarray,
    P0: np.ndarray,
    P: np.ndarray,
    free: list[int],
    steps: list,
    base_free: list[int],
    w_fit: np.ndarray | None = None,
):
    """Per-run acceptance: no validation run may fit worse overall (noise-weighted misfit) nor
    lose more than its slack on a channel (:func:`channel_slack`); no left-out run may get more than RUN_RISE
    worse overall or MUCH_WORSE points on a channel. Findings are dropped, last kept first,
    until that holds. No finding left: the model is the baseline as given (no refit).
    ``w_fit``: the channel weights P was estimated with (default ``w``), those of the
    left-out refits and of the refit after a drop; the misfit is weighed by ``w``."""
    wf = w if w_fit is None else w_fit
    rise = 0.0 if val_preps else RUN_RISE
    dropped = []
    while True:
        if not steps:
            table, method = per_run_fits(model, preps, val_preps, w, P0, P0, [])
            return P0, [], [], table, method, dropped
        table, method = per_run_fits(model, preps, val_preps, w, P0, P, free, wf)
        worst = min(row["after"][k] - row["before"][k] for row in table for k in DOFS)
        worse_run = max(row["weighted_misfit_after"] / max(row["weighted_misfit_before"], 1e-300) - 1.0 for row in table)
        slack = [channel_slack(row) if val_preps else dict.fromkeys(DOFS, MUCH_WORSE) for row in table]
        within = all(row["after"][k] - row["before"][k] >= -sl[k] for row, sl in zip(table, slack) for k in DOFS)
        if within and worse_run <= rise:
            return P, free, steps, table, method, dropped
        st = steps.pop()  # the last kept is the weakest
        P, free = without(model, P, free, st.candidate.key)
        # the baseline keeps the values fitted with the finding (a refit without its prior could diverge)
        P, _cov, rss = fit(model, preps, P, [j for j in free if j not in base_free], wf, max_iter=6, need_cov=False)
        dropped.append(
            {
                "key": st.candidate.key,
                "effect": st.candidate.effect,
                "reason": f"a held-out run fits worse with it ({method}: weighted misfit {100 * worse_run:+.1f} %, "
                f"worst channel {worst:+.1f} points)",
            }
        )
        if not np.isfinite(rss):
            steps = []
