"""Output-error fitting of the augmented model (:class:`diagnose.model.AugmentedModel`): open-loop
residuals, their Jacobian (forward differences, or forward sensitivities where they apply) and
Levenberg-Marquardt within bounds with a Gaussian prior (the OE method of Källström (1977)); moved
from :mod:`diagnose.model`, which still exports every name."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from diagnose.sensitivity import residual_jacobian

if TYPE_CHECKING:
    from diagnose.model import AugmentedModel, Prepared


def residuals(
    model: AugmentedModel, preps: list[Prepared], P: np.ndarray | list[np.ndarray], escapes: list[np.ndarray] | None = None
) -> list[np.ndarray]:
    """Open-loop residuals y - y_hat per recording, each (B, N+1, 3) (``P`` as :meth:`AugmentedModel.simulate_many`).
    ``escapes``: a list that receives, per recording, whether each member's simulation left it
    (:func:`escaped`, (B,) bools), judged before the simulation becomes the residual."""
    out = []
    with np.errstate(all="ignore"):
        for p, yh in zip(preps, model.simulate_many(preps, P)):
            top = _top(yh)
            if escapes is not None:
                escapes.append(_escaped_top(p, top))
            r = np.subtract(p.y[None], yh, out=yh if yh.flags.writeable else None)  # the simulation is not used again
            # |y - y_hat| <= max|y| + max|y_hat|: below the clip's 1e6 (and finite) the clip changes nothing
            if not np.max(top, initial=0.0) + _span(p)[1] < 0.5e6:  # a NaN fails the test too
                bad = ~np.isfinite(r)
                np.clip(r, -1e6, 1e6, out=r)
                r[bad] = 1e6  # a non-finite residual counts as a large one, either sign
            out.append(r)
    return out


def stack(res: list[np.ndarray], w: np.ndarray | list[np.ndarray], masks: list[np.ndarray] | None = None) -> np.ndarray:
    """Weighted residuals flattened to (B, M) (samples of each mask only); ``w`` one weight per
    output, or a list of them, one per recording."""
    parts = []
    for i, r in enumerate(res):
        rr = r[:, 1:] * (w[i] if isinstance(w, list) else w)  # sample 0 is the initial state
        if masks is not None:
            rr = rr[:, masks[i][1:]]
        parts.append(rr.reshape(r.shape[0], -1))
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)  # one part: already a new array


def jacobian(
    model: AugmentedModel,
    preps: list[Prepared],
    P: np.ndarray,
    free: list[int],
    w: np.ndarray,
    masks: list[np.ndarray] | None = None,
    h: np.ndarray | None = None,
    at_P: list[np.ndarray] | None = None,
    analytic: bool = False,
    tail: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(r0 (M,), J (M, len(free))) of the weighted residual; with ``tail`` (T, len(free)), J with
    those rows below (M + T, len(free): a fit's prior rows, stacked without copying J); with ``analytic``, by forward
    sensitivities (:mod:`diagnose.sensitivity`) where they apply. Else by forward differences, one batched
    simulation, a batch per recording. A recording's initial-state parameters move that recording alone:
    they are stepped on it only, their columns zero on the others (the zeros the differences of
    two equal simulations give, without simulating them: a quarter to a half of the members of a
    diagnosis's refits, whose free parameters are mostly initial states). ``at_P``: the
    residuals (1, N_i+1, 3) per recording at P when already simulated (not simulated again)."""
    if analytic:
        res = at_P if at_P is not None else residuals(model, preps, P[None])
        got = residual_jacobian(model, preps, P, free, w, [q[0] for q in res], masks)
        if got is not None:
            J = np.concatenate([J.reshape(-1, len(free)) for _R, J in got] + ([] if tail is None else [tail]))
            return np.concatenate([R.ravel() for R, _J in got]), J
    h = model.steps(preps, P) if h is None else h
    owner = _initial_state_owner(model, preps, free)
    shared = [k for k, o in enumerate(owner) if o == -1]
    first = 0 if at_P is None else 1  # row 0 of the batch is P itself unless given
    batches, own = [], []
    for i in range(len(preps)):
        cols = shared + [k for k, o in enumerate(owner) if o == i]
        js = [free[k] for k in cols]
        Pb = np.repeat(P[None], len(cols) + 1 - first, axis=0)
        Pb[np.arange(1 - first, len(cols) + 1 - first), js] += h[js]
        batches.append(Pb)
        own.append((cols, js))
    rows = [3 * (p.n if masks is None else int(np.count_nonzero(masks[i][1:]))) for i, p in enumerate(preps)]
    at = np.cumsum([0] + rows)
    n_tail = 0 if tail is None else len(tail)
    r0, J = np.empty(at[-1]), np.zeros((at[-1] + n_tail, len(free)))  # each recording's rows written in place
    if n_tail:
        J[at[-1] :] = tail
    for i, res in enumerate(residuals(model, preps, batches)):  # every recording's batch in one simulation
        cols, js = own[i]
        wi, mi = [w[i] if isinstance(w, list) else w], None if masks is None else [masks[i]]
        if at_P is not None:  # P's residual stacked apart: the same rows as stacked with the batch
            R0, Rb = stack([at_P[i]], wi, mi)[0], stack([res], wi, mi)
        else:
            R = stack([res], wi, mi)
            R0, Rb = R[0], R[1:]
        r0[at[i] : at[i + 1]] = R0
        # the differences in place in the batch's own rows (Rb is this call's array, apart from R0), then
        # written by runs of adjacent columns: the same quotients as (Rb - R0).T / h, without the
        # temporaries and the fancy-indexed transposed write (a third of that line's CPU)
        D = np.subtract(Rb, R0, out=Rb)
        D /= h[js][:, None]
        for k, c, n in _column_runs(cols):
            J[at[i] : at[i + 1], c : c + n] = D[k : k + n].T
    return r0, J


def _column_runs(cols: list[int]) -> list[tuple[int, int, int]]:
    """``cols`` as runs of adjacent columns: (position in ``cols``, first column, length)."""
    runs: list[tuple[int, int, int]] = []
    for k, c in enumerate(cols):
        if runs and runs[-1][1] + runs[-1][2] == c:
            runs[-1] = (runs[-1][0], runs[-1][1], runs[-1][2] + 1)
        else:
            runs.append((k, c, 1))
    return runs


def _initial_state_owner(model: AugmentedModel, preps: list[Prepared], free: list[int]) -> list[int]:
    """Per free parameter, the position in ``preps`` of the one recording whose initial state it
    is, -1 for a parameter that may move every recording, -2 for another recording's initial state
    (one not among ``preps``: it moves none of them). An index two recordings share moves both: -1."""
    idx = [p.index for p in preps if p.index is not None and p.index < model.n_rec]
    pos = {p.index: i for i, p in enumerate(preps) if p.index in idx}
    own = {i: (pos[i] if idx.count(i) == 1 else -1) for i in pos}
    return [-1 if j < model.n_slots_end else own.get((j - model.n_slots_end) // 3, -2) for j in free]


def _prior_rows(P: np.ndarray, free: list[int], prior: tuple[np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray]:
    """Regularisation towards the profile (a Gaussian prior, Källström 1977: parameters held near model-test values): residual rows
    (P_j - ref_j) / sd_j for the free parameters with a finite sd, and their Jacobian."""
    if prior is None:
        return np.zeros(0), np.zeros((0, len(free)))
    ref, sd = prior
    rows = [k for k, j in enumerate(free) if np.isfinite(sd[j]) and sd[j] > 0]
    J = np.zeros((len(rows), len(free)))
    for n, k in enumerate(rows):
        J[n, k] = 1.0 / sd[free[k]]
    r = np.array([(P[free[k]] - ref[free[k]]) / sd[free[k]] for k in rows])
    return r, J


def fit(
    model: AugmentedModel,
    preps: list[Prepared],
    P: np.ndarray,
    free: list[int],
    w: np.ndarray,
    masks: list[np.ndarray] | None = None,
    max_iter: int = 10,
    bounds: dict[int, tuple[float, float]] | None = None,
    tol: float = 1e-5,
    prior: tuple[np.ndarray, np.ndarray] | None = None,
    patience: int = 1,
    analytic: bool = False,
    need_cov: bool = True,
    project: bool = True,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Output-error Levenberg-Marquardt over the ``free`` parameters within ``bounds``, with an
    optional Gaussian ``prior`` (ref, sd) per parameter. Returns (P, cov, rss); rss is the data
    part only, and ``inf`` when the refit diverged (a non-finite or exploding simulation).
    It stops after ``patience`` accepted steps in a row that each lower the objective by less
    than ``tol`` of it (one short step may be a dip, or a step the damping just raised held back).

    Each iteration tries four damping values in one batched simulation. ``analytic``: the
    Jacobians by forward sensitivities where they apply (:func:`jacobian`). Without ``need_cov``
    the returned cov is NaN: a fit that ends at ``max_iter`` then skips the Jacobian at its final P,
    which only the covariance reads (P and rss are the same bits). ``project``: a parameter at a
    bound the descent pushes it past stays there while the others step (:func:`_trials`); without
    it every step is solved unbounded and clipped, as before issue 30's stop 50.
    """
    P = np.asarray(P, float).copy()
    bounds = bounds or {}
    h = model.steps(preps, P)

    trial: list[list[np.ndarray]] = []  # the last trial's residuals per recording, for the next Jacobian
    esc: list[np.ndarray] = []  # whether each trial member's simulation left a recording (escaped_members)
    left = None  # whether the accepted P's simulation left a recording (None: P not simulated in a trial)

    def total(Pb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        esc.clear()
        trial[:] = [residuals(model, preps, Pb, esc)]
        R = stack(trial[0], w, masks)
        data = np.einsum("ij,ij->i", R, R)
        pri = np.array([float(np.sum(_prior_rows(p, free, prior)[0] ** 2)) for p in Pb])
        return data, data + pri

    rp, Jp = _prior_rows(P, free, prior)  # Jp is the same at every P: the Jacobians are made with it below them
    r, Ja = jacobian(model, preps, P, free, w, masks, h, analytic=analytic, tail=Jp)
    rss = float(r @ r)
    obj = rss + float(rp @ rp)
    lam = 1e-3
    lams = np.array([0.1, 1.0, 10.0, 1000.0])
    short = 0  # accepted steps in a row under tol
    for it in range(max_iter):
        if not np.all(np.isfinite(Ja[: len(r)])):
            break
        ra = np.concatenate([r, rp]) if len(rp) else r
        g = Ja.T @ ra
        cand = _trials(P, free, Ja.T @ Ja, g, lams * lam, bounds if project else {}, bounds)
        if cand is None:
            break  # every parameter at a bound the descent pushes it past: nothing left to move
        data_c, obj_c = total(cand)
        k = int(np.argmin(obj_c))
        if not obj_c[k] < obj:
            lam *= 1e4
            if lam > 1e8:
                break
            continue
        rel = (obj - obj_c[k]) / max(obj, 1e-300)
        P, rss, obj = cand[k], float(data_c[k]), float(obj_c[k])
        left = bool(any(e[k] for e in esc))
        lam = max(lam * lams[k] / 10, 1e-9)
        short = short + 1 if rel < tol else 0
        if short >= patience or (not need_cov and it == max_iter - 1):
            break  # (the last iteration's Jacobian would serve the covariance alone)
        rp = _prior_rows(P, free, prior)[0]
        r, Ja = jacobian(model, preps, P, free, w, masks, h, at_P=[q[k : k + 1] for q in trial[0]], analytic=analytic, tail=Jp)
    dof = max(len(r) - len(free), 1)
    try:
        cov = np.linalg.pinv(Ja.T @ Ja) * (rss / dof) if need_cov else np.full((len(free), len(free)), np.nan)
    except (np.linalg.LinAlgError, ValueError):
        cov = np.full((len(free), len(free)), np.nan)
    # the accepted trial's simulation says whether P diverges (the same test, not simulated again)
    if not np.all(np.isfinite(P)) or (diverges(model, preps, P) if left is None else left):
        return P, cov, float("inf")
    return P, cov, rss


def _trials(
    P: np.ndarray,
    free: list[int],
    A: np.ndarray,
    g: np.ndarray,
    lams: np.ndarray,
    hold: dict[int, tuple[float, float]],
    bounds: dict[int, tuple[float, float]],
) -> np.ndarray | None:
    """The Levenberg-Marquardt trial points (len(lams), n_params) from P: the damped Gauss-Newton steps
    of the normal equations (A = J^T J, gradient ``g``), scaled to A's diagonal (Marquardt 1963), one per
    damping of ``lams``, clipped into ``bounds``. A parameter at a bound of ``hold`` the descent pushes it past
    (:func:`_held_at_bound`) stays there and the others' step is solved without it (projected
    Levenberg-Marquardt): solved with it, their step assumed it moved and the clip then undid that,
    which left the fit crawling along the bound. None when every free parameter is so held."""
    d = np.sqrt(np.diag(A))
    d = np.where(d > 1e-150, d, 1.0)  # a parameter the data do not see (zero column) is held by the damping alone
    An = A / np.outer(d, d)
    held = _held_at_bound(P, free, hold, g)
    if held.size and held.all():
        return None
    cand = np.repeat(P[None], len(lams), axis=0)
    fo, An_o, gd_o, d_o = free, An, g / d, d  # no parameter held: the unconstrained step, clipped
    if held.any():
        on = np.flatnonzero(~held)
        fo, An_o, gd_o, d_o = [free[i] for i in on], An[np.ix_(on, on)], gd_o[on], d[on]
    for k, lk in enumerate(lams):
        try:
            cand[k, fo] += -np.linalg.lstsq(An_o + lk * np.eye(len(fo)), gd_o, rcond=None)[0] / d_o
        except np.linalg.LinAlgError:
            cand[k] = P
    for j, (lo, hi) in bounds.items():
        cand[:, j] = np.clip(cand[:, j], lo, hi)
    return cand


def _held_at_bound(P: np.ndarray, free: list[int], bounds: dict[int, tuple[float, float]], g: np.ndarray) -> np.ndarray:
    """Per free parameter, whether it sits at a bound of ``bounds`` that the steepest descent (-``g``,
    the objective's gradient over ``free``) pushes it past: the active set of a bound-constrained
    least-squares step (Kanzow, Yamashita & Fukushima 2004, projected Levenberg-Marquardt)."""
    out = np.zeros(len(free), bool)
    for k, j in enumerate(free):
        if j in bounds:
            lo, hi = bounds[j]
            out[k] = (P[j] <= lo and g[k] > 0) or (P[j] >= hi and g[k] < 0)
    return out


def diverges(model: AugmentedModel, preps: list[Prepared], P: np.ndarray) -> bool:
    """True when the simulation at P is non-finite or leaves the recorded range by far
    (an unstable refit: positive damping, a blown-up inertia)."""
    with np.errstate(all="ignore"):  # every recording in one simulation
        return any(escaped(p, y[0]) for p, y in zip(preps, model.simulate_many(preps, np.atleast_2d(P))))


def escaped(p: Prepared, yh: np.ndarray) -> bool:
    """True when the simulated outputs ``yh`` of recording ``p`` are non-finite or leave its
    recorded range by far (the test of :func:`diverges`, for a simulation already made)."""
    return bool(escaped_members(p, yh[None])[0])


def escaped_members(p: Prepared, yh: np.ndarray) -> np.ndarray:
    """:func:`escaped` of each member of a batch ``yh`` (B, N+1, 3): (B,) bools, the same test."""
    return _escaped_top(p, _top(yh))


def _top(yh: np.ndarray) -> np.ndarray:
    """(B, 3) largest |y_hat| of each member and channel: NaN where a channel holds a NaN, inf
    where an inf (max propagates both)."""
    return np.max(np.abs(yh), axis=1)


def _escaped_top(p: Prepared, top: np.ndarray) -> np.ndarray:
    """:func:`escaped_members` from each member's :func:`_top`."""
    return ~np.all(np.isfinite(top), axis=1) | np.any(top > 20.0 * _span(p)[0], axis=1)


def _span(p: Prepared) -> tuple[np.ndarray, float]:
    """(the recorded range per channel that a simulation escapes at 20 times, the largest |y|),
    once per recording."""

    def make() -> tuple[np.ndarray, float]:
        return np.max(np.abs(p.y), axis=0) + 3.0 * np.std(p.y, axis=0) + 1e-9, float(np.max(np.abs(p.y), initial=0.0))

    return p.cached("span", None, make)
