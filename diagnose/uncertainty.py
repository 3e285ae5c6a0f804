"""Covariance of the findings under coloured residuals (Källström 1977: output error with a noise model).

The search fits by output error on noise-weighted residuals, as if they were white. They are
not: coloured measurement noise (AR(1), 0.9, in the battery) and the baseline's own misfit make
neighbouring residuals alike, so the white-noise covariance ``(J^T J)^-1 s^2`` claims several
times the real precision. Following Kallstrom's maximum-likelihood treatment (a noise model
fitted with the dynamics), each residual channel is modelled as AR(1),
``e(k) = rho e(k-1) + eps(k)`` (rho and var(eps) per channel, from the final residuals), and the
covariance of the (penalised) least-squares estimate is the sandwich

    C = H^-1 (J^T Sigma J) H^-1,   H = J^T J + D

with ``Sigma`` the AR(1) covariance and ``D`` the fit's Gaussian prior; ``J^T Sigma J`` is
``Z^T Z`` with ``Z`` the sensitivities run backwards through the AR(1) filter.

A baseline fitted on --fit-on runs is an estimate too: its parameters are held there and the
finding is measured against them. Their error (the same sandwich for the --fit-on fit) moves the
finding by ``dA/dtheta = -H_aa^-1 G_a,theta`` (the refit of the free parameters ``a`` after a
change of the held ``theta``), so that covariance is added: ``C + (dA/dtheta) C_theta (dA/dtheta)^T``.
On the MMG battery's model-scale 3 s delay (AR(1) noise) it is about a third of the variance.

Model error common to every run is neither noise nor run-to-run spread. The --fit-on runs measure
it: they hold none of the effects looked for, so a finding refitted with the baseline on them
(linearised, from the baseline as fitted there) should come out zero; what it comes out as,
``delta``, is what the model's structural misfit alone puts on that finding's parameters. Its
excess over what the noise of those runs would put there (``delta delta^T`` against the same
sandwich, :func:`excess`) is a third part of the covariance, ``reference``: a misspecification
term in the sense of White (1982), measured on the one set of runs known to hold no effect.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import lfilter

from diagnose.interval95 import BLOCKS_PER_RUN, half_width_95, small_sample  # noqa: F401  (half_width_95: diagnose.uncertainty's, as before)
from diagnose.model import AugmentedModel, Prepared, fit, residuals
from diagnose.sensitivity import residual_jacobian


def sensitivities(
    model: AugmentedModel,
    preps: list[Prepared],
    P: np.ndarray,
    cols: list[int],
    w: np.ndarray,
    analytic: bool = False,
    h: np.ndarray | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per recording (weighted residual (N, 3), its sensitivity to ``cols`` (c, N, 3)) at P,
    from one batched simulation (forward differences, the fit's steps); with ``analytic``, by
    forward sensitivities where they apply (:mod:`diagnose.sensitivity`: the baseline's
    coefficients and initial states where no candidate is switched on), the other columns (a
    candidate's slots) by forward differences as before. ``h``: the differences' steps (default
    the fit's at P, :meth:`AugmentedModel.steps`)."""
    if analytic:
        exact = [k for k, j in enumerate(cols) if j < model.n_base or j >= model.n_slots_end]
        rest = [k for k in range(len(cols)) if k not in exact]
        got = residual_jacobian(model, preps, P, [cols[k] for k in exact], w, [q[0] for q in residuals(model, preps, P[None])])
        if got is not None:
            fd = sensitivities(model, preps, P, [cols[k] for k in rest], w, h=h) if rest else None
            out = []
            for i, (R, J) in enumerate(got):
                Js = np.moveaxis(J, 2, 0)
                if fd is not None:  # the columns in their order: exact ones and differenced ones
                    Js = np.concatenate([Js, fd[i][1]])[np.argsort(exact + rest, kind="stable")]
                out.append((R, Js))
            return out
    h = model.steps(preps, P) if h is None else h
    Pb = np.repeat(P[None], len(cols) + 1, axis=0)
    for k, j in enumerate(cols):
        Pb[k + 1, j] += h[j]
    out = []
    for res in residuals(model, preps, Pb):
        R = res[:, 1:] * w  # sample 0 is the initial state
        out.append((R[0], (R[1:] - R[0]) / h[cols][:, None, None]))
    return out


def ar1(pairs: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """AR(1) coefficient and innovation variance per channel of the residuals (pooled over runs)."""
    num = sum((r[1:] * r[:-1]).sum(axis=0) for r, _J in pairs)
    den = sum((r[:-1] ** 2).sum(axis=0) for r, _J in pairs)
    rho = np.clip(num / np.maximum(den, 1e-300), 0.0, 0.99)
    n = sum(len(r) - 1 for r, _J in pairs)
    s2 = sum(((r[1:] - rho * r[:-1]) ** 2).sum(axis=0) for r, _J in pairs) / max(n, 1)
    return rho, s2


def run_grams(pairs: list[tuple[np.ndarray, np.ndarray]], rho: np.ndarray, s2: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per run, (J^T J, J^T Sigma J) summed over channels, Sigma the AR(1) noise covariance. Only
    the columns a run moves are filtered (another run's initial state is zero there)."""
    out = []
    for _r, J in pairs:
        c = J.shape[0]
        act = np.flatnonzero(np.any(J != 0, axis=(1, 2)))
        G, M = np.zeros((c, c)), np.zeros((c, c))
        ix = np.ix_(act, act)
        for ch in range(J.shape[2]):
            Jc = J[act, :, ch]
            G[ix] += Jc @ Jc.T
            # Sigma = A A^T with A the AR(1) filter (innovation std sqrt(s2)): A^T J runs it backwards
            Z = lfilter([np.sqrt(s2[ch])], [1.0, -rho[ch]], Jc[:, ::-1], axis=1)[:, ::-1]
            M[ix] += Z @ Z.T
        out.append((G, M))
    return out


def ar1_grams(pairs: list[tuple[np.ndarray, np.ndarray]], rho: np.ndarray, s2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(J^T J, J^T Sigma J) summed over runs and channels, Sigma the AR(1) noise covariance."""
    per = run_grams(pairs, rho, s2)
    return sum(g for g, _m in per), sum(m for _g, m in per)


def finite_or_nan(X: np.ndarray) -> np.ndarray:
    """``X`` with every non-finite entry (inf from an overflow) as NaN: one mark of a failure."""
    return np.where(np.isfinite(X), X, np.nan)


def inverse_or_pinv(A: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(A)


def sandwich(
    pairs: list[tuple[np.ndarray, np.ndarray]],
    prior_D: np.ndarray | None = None,
    per_run: list[tuple[np.ndarray, np.ndarray]] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(covariance, H) of a penalised least-squares fit with AR(1) residuals (module docstring);
    ``per_run``: the runs' grams (:func:`run_grams`) when already computed."""
    if per_run is None:
        per_run = run_grams(pairs, *ar1(pairs))
    G, M = sum(g for g, _m in per_run), sum(m for _g, m in per_run)
    H = G + (np.diag(prior_D) if prior_D is not None else 0.0)
    Hi = inverse_or_pinv(H)
    return Hi @ M @ Hi, H


def prior_hessian_diag(sd: np.ndarray | None, n: int) -> np.ndarray:
    """Hessian diagonal of a Gaussian prior of std ``sd`` (0 where there is none: inf, nan, 0)."""
    if sd is None:
        return np.zeros(n)
    sd = np.asarray(sd, float)
    ok = np.isfinite(sd) & (sd > 0)
    return np.where(ok, 1.0 / np.where(ok, sd, 1.0) ** 2, 0.0)


def jackknife(
    pairs: list[tuple[np.ndarray, np.ndarray]],
    nf: int,
    prior_D: np.ndarray | None = None,
    per_run: list[tuple[np.ndarray, np.ndarray]] | None = None,
) -> tuple[np.ndarray, np.ndarray] | None:
    """Linearised leave-one-run-out covariance of the first ``nf`` sensitivity columns, and its
    expected value were the runs' residuals AR(1) noise alone (None with fewer than two runs).

    At the fit's optimum the prior's gradient cancels the data's, so leaving run i out moves the
    estimate by ``d_i = A_i g_i``, ``A_i = (H - H_i)^-1`` (one Gauss-Newton step; ``H_i``,
    ``g_i`` run i's Gram matrix and gradient); a column only run i informs (its initial state)
    stays where it is in that fold. Jackknife covariance ``(n-1)/n sum (d_i - mean d)^2``. Under
    noise alone ``g_i = u_i - H_i H^-1 sum_j u_j`` with independent ``u_j`` of covariance
    ``J_j^T Sigma J_j``, so ``d_i = sum_j B_ij u_j`` and the expectation follows exactly; with
    runs of unequal information it exceeds the noise covariance of the estimate (the jackknife's
    known upward bias), which is why the excess is measured against it. ``per_run``: the runs'
    grams of these columns (:func:`run_grams`) when already computed."""
    n = len(pairs)
    if n < 2:
        return None
    if per_run is None:
        per_run = run_grams([(r, J[:nf]) for r, J in pairs], *ar1(pairs))
    Hs = [g for g, _m in per_run]
    gs = [np.einsum("anc,nc->a", J[:nf], r) for r, J in pairs]
    H = sum(Hs) + (np.diag(prior_D) if prior_D is not None else 0.0)
    Hi = inverse_or_pinv(H)
    scale = float(np.max(np.abs(np.diag(H)))) if nf else 0.0
    A = np.zeros((n, nf, nf))
    for i in range(n):
        Hm = H - Hs[i]
        act = np.diag(Hm) > 1e-9 * max(scale, 1e-300)
        if np.any(act):
            A[i][np.ix_(act, act)] = inverse_or_pinv(Hm[np.ix_(act, act)])
    dev = np.einsum("iab,ib->ia", A, np.array(gs))
    dev -= dev.mean(axis=0)
    V = (n - 1) / n * dev.T @ dev
    E = (n - 1) / n * _noise_spread(A, A @ np.array(Hs) @ Hi, np.array([M for _g, M in per_run]))
    return finite_or_nan(V), finite_or_nan(E)


def _noise_spread(A: np.ndarray, AH: np.ndarray, M: np.ndarray) -> np.ndarray:
    """``sum_j sum_i B_ij M_j B_ij^T`` of :func:`jackknife`, ``B_ij = A_i delta_ij - AH_i`` centred
    over i (``AH_i = A_i H_i H^-1``), in closed form: with ``K_i = mean(AH) - AH_i`` (summing to
    zero) and ``Q_j = K_j - A_j / n`` the centred ``B_ij = A_i delta_ij + K_i - A_j / n``, and the
    double sum is ``sum_i K_i (sum_j M_j) K_i^T + sum_j [(1 + 1/n) A_j M_j A_j^T + A_j M_j Q_j^T
    + Q_j M_j A_j^T]`` (``M_j`` symmetric): n matrix products instead of the double sum's n^2
    (the within-run jackknife's 104 blocks of benchmarks/run.py's 13-run case: its whole diagnosis
    45 -> 9.5 s CPU)."""
    n = len(A)
    K = AH.mean(axis=0) - AH
    Q = K - A / n
    KT = K.transpose(0, 2, 1)
    AM = A @ M
    X = (AM @ Q.transpose(0, 2, 1)).sum(axis=0)
    return (K @ M.sum(axis=0) @ KT).sum(axis=0) + (1.0 + 1.0 / n) * (AM @ A.transpose(0, 2, 1)).sum(axis=0) + X + X.T


def excess(V: np.ndarray | None, C: np.ndarray) -> np.ndarray:
    """The part of the between-run covariance ``V`` the noise covariance ``C`` does not explain
    (zero when the runs agree within their noise): ``V - C`` where positive, in the coordinates
    that whiten ``C`` (invariant to the parameters' units: ``V x = lambda C x``, the excess
    ``C^1/2 (Lambda - 1)_+ C^1/2``); on the diagonal alone when ``C`` is singular."""
    if V is None or not len(C) or not (np.all(np.isfinite(V)) and np.all(np.isfinite(C))):
        return np.zeros_like(C)
    try:
        L = np.linalg.cholesky(0.5 * (C + C.T))
    except np.linalg.LinAlgError:
        return np.diag(np.maximum(np.diag(V) - np.diag(C), 0.0))
    Li = np.linalg.inv(L)
    lam, U = np.linalg.eigh(Li @ (0.5 * (V + V.T)) @ Li.T)
    B = L @ U
    return (B * np.maximum(lam - 1.0, 0.0)) @ B.T


@dataclass
class FindingCov:
    """Covariance of the fitted parameters, split by source (module docstring)."""

    noise: np.ndarray  # measurement noise (AR(1) sandwich), held baseline's noise carried in
    model: np.ndarray  # run-to-run model misfit beyond the noise over the diagnosed runs
    n_runs: int  # runs the between-run spread was measured over (0: none, or it failed)
    fit_on: bool = False  # the noise of a baseline fitted on --fit-on runs is carried in
    runs_given: int = 0  # runs the covariance was computed over (diagnosed and joint --fit-on)
    reference_runs: int = 0  # of those, --fit-on runs fitted jointly (a ReferencedModel)
    misfit_failed: bool = False  # the leave-one-run-out spread was not finite: no misfit term
    reference: np.ndarray | None = None  # --fit-on runs' misfit on the findings (module docstring)
    reference_keys: frozenset[str] = frozenset()  # findings (candidate keys) that misfit was measured for
    within: np.ndarray | None = None  # misfit within the runs beyond the run-to-run part (:func:`with_within`)
    heldout: np.ndarray | None = (
        None  # held-out runs' misfit beyond the parts above (:func:`diagnose.heldout_interval.with_heldout`)
    )
    heldout_runs: int = 0  # fewest held-out runs a finding's misfit was measured over (its degrees of freedom)
    heldout_along: dict = field(default_factory=dict)  # key -> each held-out run's own estimate / the diagnosis's

    @property
    def runs(self) -> np.ndarray:
        """Noise and run-to-run misfit: the part the "includes no effect" rule judges by."""
        return self.noise + self.model

    @property
    def total(self) -> np.ndarray:
        extra = [X for X in (self.reference, self.within, self.heldout) if X is not None]
        return self.runs + sum(extra, np.zeros_like(self.noise))


def propagated(
    pairs: list[tuple[np.ndarray, np.ndarray]],
    nf: int,
    prior_D: np.ndarray | None = None,
    held_cov: np.ndarray | None = None,
    model_cols: list[int] | None = None,
) -> FindingCov:
    """Covariance of the first ``nf`` sensitivity columns (the fitted parameters) under AR(1)
    residuals, plus the effect of the remaining columns' parameters (held at values estimated
    elsewhere, covariance ``held_cov``) through the refit: ``dA/dtheta = -H^-1 G_a,theta``.
    The model part, on the columns ``model_cols`` (default all): the jackknife over the runs
    beyond its noise expectation (:func:`jackknife`, :func:`excess`), widened for the few runs
    it is measured on (:func:`small_sample`)."""
    own = [(r, J[:nf]) for r, J in pairs]
    per_run = run_grams(own, *ar1(own))
    cov, H = sandwich(own, prior_D, per_run)
    cols = list(range(nf)) if model_cols is None else list(model_cols)
    model = np.zeros_like(cov)
    VE = jackknife(own, nf, prior_D, per_run)
    failed = False
    if VE is not None and cols:
        ix = np.ix_(cols, cols)
        # a diverging run makes the spread non-finite: say so, never a zero misfit term
        failed = not (np.all(np.isfinite(VE[0][ix])) and np.all(np.isfinite(VE[1][ix])))
        if not failed:
            model[ix] = small_sample(len(pairs)) * excess(VE[0][ix], VE[1][ix])
    if held_cov is not None and len(held_cov):
        G_ah = sum(np.einsum("anc,bnc->ab", J[:nf], J[nf:]) for _r, J in pairs)
        dA = -inverse_or_pinv(H) @ G_ah
        cov = cov + dA @ held_cov @ dA.T
    return FindingCov(
        finite_or_nan(cov),
        finite_or_nan(model),
        len(pairs) if VE is not None and not failed else 0,
        held_cov is not None and len(held_cov) > 0,
        len(pairs),
        misfit_failed=failed,
    )


def prior_and_findings(model: AugmentedModel, free: list[int], prior_sd: np.ndarray | None) -> tuple[np.ndarray, list[int]]:
    """The prior's Hessian diagonal over ``free`` and the positions among ``free`` of the findings'
    (candidate slots') parameters."""
    D = prior_hessian_diag(None if prior_sd is None else np.asarray(prior_sd, float)[free], len(free))
    return D, [k for k, j in enumerate(free) if model.n_base <= j < model.n_slots_end]


def finding_cov(
    model: AugmentedModel,
    preps: list[Prepared],
    w: np.ndarray,
    P: np.ndarray,
    free: list[int],
    prior_sd: np.ndarray | None = None,
    held: list[int] | None = None,
    held_cov: np.ndarray | None = None,
    pairs: list[tuple[np.ndarray, np.ndarray]] | None = None,
) -> FindingCov:
    """Covariance of the ``free`` parameters at P (coloured residuals; the fit's prior std
    ``prior_sd`` per parameter), plus the propagated covariance ``held_cov`` of the parameters
    ``held`` (fixed at P, estimated on other runs), and the run-to-run model misfit of the
    findings' parameters (the candidate slots among ``free``) over ``preps``. ``pairs``: the
    runs' :func:`sensitivities` to ``free`` and then ``held`` at P when already computed
    (:func:`finding_pairs`)."""
    held = list(held or []) if held_cov is not None else []
    pairs = finding_pairs(model, preps, w, P, free, held, held_cov) if pairs is None else pairs
    D, cols = prior_and_findings(model, free, prior_sd)
    out = propagated(pairs, len(free), D, held_cov if held else None, cols)
    out.reference_runs = sum(id(p) in getattr(model, "reference_ids", ()) for p in preps)
    return out


def finding_pairs(
    model: AugmentedModel,
    preps: list[Prepared],
    w: np.ndarray,
    P: np.ndarray,
    free: list[int],
    held: list[int] | None = None,
    held_cov: np.ndarray | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The runs' :func:`sensitivities` :func:`finding_cov` reads (to ``free``, then to ``held`` when
    ``held_cov`` is given); their first ``len(free)`` columns are those :func:`with_within` reads
    at the same P and weights (each batch member is simulated on its own: the same bits)."""
    held = list(held or []) if held_cov is not None else []
    return sensitivities(model, preps, P, list(free) + held, w)


def baseline_cov(
    model: AugmentedModel, preps: list[Prepared], w: np.ndarray, idx: list[int], sd: np.ndarray, mse: bool = False
) -> np.ndarray:
    """Covariance (len(idx) x len(idx)) of the baseline parameters ``idx`` as fitted on the
    --fit-on runs ``preps`` (``model`` at their fitted values, one initial-state correction
    per run, refitted here; prior std ``sd`` per parameter, inf for none): the sandwich of
    that penalised fit, the initial states as nuisance parameters. (Its jackknife over those
    runs, carried into the finding, was tried as a measure of the baseline's misfit: linearised
    over a many-parameter fit that loses a whole manoeuvre type per fold, it put 5-18 s on a
    delay of the MMG battery; not used.) With ``mse`` the prior's expected bias is added, as the
    mean square error of a ridge estimate (Hoerl & Kennard 1970) with the true parameters drawn
    from the prior: ``H^-1 (J^T Sigma J + D) H^-1`` (D the prior's Hessian; ``H^-1`` for white
    noise): the sandwich alone gives a direction the data leave to the prior a variance near zero."""
    x0 = model.x0_params()
    P, _cov, _rss = fit(model, preps, model.p0(), x0, w, max_iter=5, analytic=True, need_cov=False)
    pairs = sensitivities(model, preps, P, list(idx) + x0, w, analytic=True)
    D = prior_hessian_diag(np.concatenate([np.asarray(sd, float)[idx], np.full(len(x0), np.inf)]), len(idx) + len(x0))
    cov, H = sandwich(pairs, D)
    if mse:
        Hi = inverse_or_pinv(H)
        cov = cov + Hi @ np.diag(D) @ Hi
    return cov[: len(idx), : len(idx)]


def reference_misfit(
    model: AugmentedModel,
    calm: list[Prepared],
    w: np.ndarray,
    P0: np.ndarray,
    own: list[int],
    base_free: list[int],
    prior_sd: np.ndarray | None = None,
) -> np.ndarray | None:
    """Covariance term (len(own) x len(own)) of the model error the --fit-on runs ``calm`` put on
    one finding's parameters ``own`` (module docstring): the linearised refit on those runs, from
    ``P0`` (the baseline as fitted there, no findings), of ``own`` with the baseline parameters
    the diagnosis refits (``base_free``) under the diagnosis's prior (std ``prior_sd`` per
    parameter; centred on P0, so its gradient is zero there) gives ``delta``; the term is the
    excess of ``delta delta^T`` over the noise covariance of that refit. Parameters the runs do
    not move (a wind where none was recorded) get none; None when no parameter is moved or the
    refit is not finite."""
    cols = list(base_free) + list(own)
    D = prior_hessian_diag(None if prior_sd is None else np.asarray(prior_sd, float)[cols], len(cols))
    # the baseline's columns by forward sensitivities (P0 switches no candidate on), the finding's differenced
    return misfit_term(sensitivities(model, calm, P0, cols, w, analytic=True), len(base_free), D)


def misfit_term(pairs: list[tuple[np.ndarray, np.ndarray]], nb: int, prior_D: np.ndarray | None = None) -> np.ndarray | None:
    """The --fit-on misfit term of :func:`reference_misfit` from those runs' (residual,
    sensitivity) pairs at the baseline fitted there: columns ``:nb`` the baseline's refitted
    parameters, the rest the finding's. The Gauss-Newton step ``d = -H^-1 J^T r`` (H with the
    prior's Hessian ``prior_D``), its finding part ``delta`` and the excess of ``delta delta^T``
    over that part's noise covariance (AR(1) sandwich). None when no finding column is moved."""
    G = sum(np.einsum("anc,bnc->ab", J, J) for _r, J in pairs)
    g = sum(np.einsum("anc,nc->a", J, r) for r, J in pairs)
    k = len(g) - nb
    act = np.flatnonzero(np.diag(G) > 1e-12 * max(float(np.max(np.diag(G))), 1e-300))
    pos = np.flatnonzero(act >= nb)  # act is sorted: the finding columns moved are its entries past the baseline's
    own_act = (act[pos] - nb).tolist()
    if not own_act:
        return None
    C, H = sandwich([(r, J[act]) for r, J in pairs], None if prior_D is None else np.asarray(prior_D)[act])
    d = -inverse_or_pinv(H) @ g[act]
    delta, C_d = d[pos], C[np.ix_(pos, pos)]
    if not (np.all(np.isfinite(delta)) and np.all(np.isfinite(C_d))):
        return None
    out = np.zeros((k, k))
    out[np.ix_(own_act, own_act)] = excess(np.outer(delta, delta), C_d)
    return out


def with_reference(
    cov: FindingCov,
    model: AugmentedModel,
    calm: list[Prepared],
    w: np.ndarray,
    free: list[int],
    keys: list[str],
    prior_sd: np.ndarray | None = None,
) -> FindingCov:
    """``cov`` with the --fit-on runs' misfit (:func:`reference_misfit`) of each finding ``keys``
    (candidate keys, their slots among ``free``; the baseline parameters among ``free`` refitted
    with it, prior std ``prior_sd``) as its ``reference`` part, one block per finding (each
    refitted alone on those runs); ``reference_keys`` the findings it was measured for (not one
    those runs do not move, such as a wind where they recorded none)."""
    base_free = [j for j in free if j < model.n_base]
    R = np.zeros_like(cov.noise)
    P0 = model.p0()
    measured = set()
    for key in keys:
        own = list(model.slot_of[key])
        term = reference_misfit(model, calm, w, P0, own, base_free, prior_sd)
        if term is not None:
            pos = [free.index(j) for j in own]
            R[np.ix_(pos, pos)] = term
            measured.add(key)
    cov.reference = finite_or_nan(R)
    cov.reference_keys = frozenset(measured)
    return cov


def positive_part(A: np.ndarray) -> np.ndarray:
    """The positive semi-definite part of a symmetric matrix (its negative eigenvalues set to 0)."""
    lam, U = np.linalg.eigh(0.5 * (A + A.T))
    return (U * np.maximum(lam, 0.0)) @ U.T
