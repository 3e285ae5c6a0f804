"""The output-error refinement of an estimate (:func:`output_error`): a prediction-error fit on the
simulated output, Levenberg-Marquardt on the Gauss-Newton moments of :mod:`expdesign.oekernel`
(compiled) or of :func:`_gauss_newton_moments_numpy`, started from the IV estimate of
:mod:`expdesign.estimators` (which imports the names below from here too).

Named ``oerefine``, not ``output_error``: the function keeps that name, and the load estimator's
own output-error fit is :mod:`identify.rollmass.output_error` (a different model and fit).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from expdesign import oekernel, sensloop
from expdesign.errors import DesignError
from primitives.regressors import block_mask, predictor_regressors
from primitives.ship import ShipProfile
from primitives.simulate import SPEED, model_signals, signals_read, simulate
from primitives.terms import TermSet, signals_used

_OE_EXPLODE = 1e6  # a simulated output beyond this has exploded: the step is rejected
# Stop when the Newton decrement (the step's length in standard errors, squared) is below this: 0.1 standard error
OE_TOL = 0.01
_LM_START, _LM_MAX = 1e-3, 1e8  # Levenberg-Marquardt damping: first value, give up above
_LM_MIN, _LM_FACTOR = 1e-12, 10.0  # damping floor; divided by the factor after a better step, multiplied after a worse
_FD_STEP = 1e-7  # relative forward-difference step of the state Jacobian (see _state_jacobian)
_WEIGHT_FLOOR = 1e-12  # a DOF's mean square is floored at this fraction of the largest: its weight stays finite


@dataclass
class OEData:
    """One experiment (or sub-experiment) of a batch of B runs: inputs (B, N, m), or (1, N, m)
    where every run plays the same ones, the known start state nu0 (B, 3) and the measured
    velocities y (B, N+1, 3)."""

    inputs: np.ndarray
    nu0: np.ndarray
    y: np.ndarray

    def inputs_of(self, idx: np.ndarray) -> np.ndarray:
        """The inputs (len(idx), N, m) of the runs ``idx``."""
        return np.broadcast_to(self.inputs, (self.y.shape[0],) + self.inputs.shape[1:])[idx]


@dataclass
class OEResult:
    """theta (B, p); cost_start / cost (B,) the weighted sum of squared output errors (a
    chi-square: weights 1/sigma_i^2) at the start estimate and at the result (inf where the start
    estimate's simulation diverged: theta is then the start, unchanged); iterations (B,)
    candidate steps tried; converged (B,) stopped on the tolerance (False: iteration limit, or
    the damping ran out without a better step)."""

    theta: np.ndarray
    cost_start: np.ndarray
    cost: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray


def output_error_unsupported(profile: ShipProfile, terms: TermSet | None = None) -> str | None:
    """Why :func:`output_error` cannot refine this model, or None when it can: the sensitivity
    recursion is written for planar (u, v, r) models whose increments are linear in theta (no
    rigid-body transform) and do not read the heading."""
    terms = terms or profile.predictor
    if profile.n_dof != 3 or terms.n_dof != 3:
        return "the output-error refinement handles planar (u, v, r) models only"
    if profile.rigid_body is not None:
        return "the output-error refinement does not handle rigid-body (physical-force) profiles"
    if "psi" in signals_used(terms.terms):
        return "the output-error refinement does not handle terms that read the heading"
    return None


def _simulated(profile: ShipProfile, terms, data: Sequence[OEData], theta: np.ndarray, idx: np.ndarray):
    """Noise-free outputs of the runs ``idx`` per experiment: [(nu (b, N+1, 3), psi (b, N+1))]."""
    out = []
    with np.errstate(all="ignore"):
        for d in data:
            res = simulate(profile, d.inputs_of(idx), theta[idx], terms=terms, nu0=d.nu0[idx], batch=len(idx), positions=False)
            out.append((res.nu, res.eta[..., 2]))
    return out


def _mean_squares(data: Sequence[OEData], sims, idx: np.ndarray) -> np.ndarray:
    """Mean squared output error per DOF (b, 3) of the runs ``idx`` over all experiments
    (samples 1..N: the start state is known); inf for a run whose simulation exploded. The sums
    are per run on arrays whose shape does not depend on the batch."""
    n = sum(d.y.shape[1] - 1 for d in data)
    ms = np.zeros((len(idx), 3))
    with np.errstate(invalid="ignore", over="ignore"):
        bad = np.logical_or.reduce([~(np.abs(nu) < _OE_EXPLODE).all(axis=(1, 2)) for nu, _ in sims])
    good = np.flatnonzero(~bad)
    for d, (nu, _) in zip(data, sims):
        e = d.y[idx[good], 1:] - nu[good, 1:]
        ms[good] += np.sum(e * e, axis=1)  # over the samples one after the other, per run and DOF
    ms[good] /= n
    ms[bad] = np.inf
    return ms


def _weighted(ms: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted cost per run, sum_i w_i ms_i, written out (no BLAS dot)."""
    with np.errstate(invalid="ignore"):
        return ms[:, 0] * w[:, 0] + ms[:, 1] * w[:, 1] + ms[:, 2] * w[:, 2]


def _state_jacobian(profile: ShipProfile, terms, nu: np.ndarray, psi: np.ndarray, in_sig: dict, theta: np.ndarray) -> np.ndarray:
    """d(increment)/d(nu) along the simulated trajectory nu (b, N+1, 3), in single precision:
    forward differences of the increment function from the trajectory's own increments
    nu(k+1) - nu(k), for all samples at once (no time loop). Computed and laid out time-major,
    (N, col, b, i), so that the recursion reads each step's Jacobian columns as one contiguous
    block (every operation is elementwise: the layout does not change a number). The step
    1e-7 (1 + |nu|) leaves a relative error of about 1e-7 in the Gauss-Newton direction, never in
    the cost that decides a step."""
    inc = terms.increment_function()
    coef = [theta[:, j] for j in range(theta.shape[1])]  # (b,): broadcast over the time axis
    nu_t = np.ascontiguousarray(nu.transpose(1, 2, 0))  # (N+1, 3, b)
    x0, base = nu_t[:-1], nu_t[1:] - nu_t[:-1]
    exo = {k: v.T for k, v in in_sig.items()} | {"psi": psi[:, :-1].T}  # (N, b)
    speed = SPEED in signals_read(terms)
    jac = np.empty((x0.shape[0], 3, x0.shape[2], 3), np.float32)
    for col in range(3):
        h = _FD_STEP * (1.0 + np.abs(x0[:, col]))
        x = x0.copy()
        x[:, col] += h
        sig = model_signals(profile, x.transpose(0, 2, 1), exo["psi"], exo, speed=speed)
        f = inc(sig, coef)
        for i in range(3):
            jac[:, col, :, i] = (f[i] - base[:, i]) / h  # rounded to single precision on assignment
    return jac


def _gauss_newton_moments_numpy(
    profile: ShipProfile, terms, data: Sequence[OEData], sims, theta: np.ndarray, idx: np.ndarray, w: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """H = sum_k S(k)^T W S(k) and g = sum_k S(k)^T W (y(k) - y_hat(k)) per run of ``idx``, with
    the output sensitivity S(k) = d y_hat(k) / d theta from the recursion
    S(k+1) = (I + d inc/d nu) S(k) + Phi(k) (block-diagonal (9.2)), S(0) = 0. The recursion is
    elementwise over the runs (time-major arrays, no allocation per step) and the sums are per
    run on contiguous copies, so a run's numbers do not depend on which runs share its batch."""
    p, b = theta.shape[1], len(idx)
    hess = np.zeros((b, p, p))
    grad = np.zeros((b, p))
    mask = block_mask(terms)[[terms.offsets[i] for i in range(3)]].astype(np.float32)  # (3, p): DOF i's columns
    for d, (nu, psi) in zip(data, sims):
        inputs = d.inputs_of(idx)
        n = inputs.shape[1]
        in_sig = {k: np.broadcast_to(v, (b, n)) for k, v in profile.generalized_forces(inputs).items()}
        with np.errstate(all="ignore"):
            jac = _state_jacobian(profile, terms, nu, psi, in_sig, theta[idx])
            phi = np.moveaxis(predictor_regressors(profile, nu, inputs, psi, terms=terms)[0], 1, 0).astype(np.float32)
        # time-major: each step reads and writes contiguous blocks; single precision: the recursion
        # is the estimator's inner loop (half the bytes per step: faster, the more so the larger
        # the batch) and S only steers the step, the cost that accepts it is computed in double precision
        sens = np.empty((n + 1, b, 3, p), np.float32)
        sens[0] = 0.0
        with np.errstate(all="ignore"):  # an unstable estimate's sensitivities overflow: its step is then rejected
            np.multiply(phi[:, :, None, :], mask, out=sens[1:])  # Phi(k) in the rows of its DOF (times 0 or 1: exact)
            sensloop.recurse(sens, jac)
        sk = np.empty((p, n, 3))
        for a, r in enumerate(idx):
            sw = np.sqrt(w[r])
            # (p, N*3) contiguous: the same layout whatever the batch; c_einsum, no BLAS: no
            # thread-count rounding
            np.multiply(sens[1:, a].transpose(2, 0, 1), sw, out=sk)  # float32 * float64: exact widening, then the product
            skf = sk.reshape(p, -1)
            e = ((d.y[r, 1:] - nu[a, 1:]) * sw).reshape(-1)
            with np.errstate(all="ignore"):
                hess[a] += np.einsum("pk,qk->pq", skf, skf)
                grad[a] += np.einsum("pk,k->p", skf, e)
    return hess, grad


def _lm_steps(hess: np.ndarray, grad: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Levenberg-Marquardt steps (b, p) of the runs' hess (b, p, p), grad (b, p), lam (b,) with
    Marquardt's diagonal scaling (the parameters differ by four orders of magnitude); NaN for a
    run whose system is singular. One LAPACK solve per run in a stacked call (numpy's solve
    loops over the stack: a run's numbers do not depend on the batch); a stack LAPACK rejects
    is redone run by run."""
    b, p = grad.shape
    step = np.full((b, p), np.nan)
    with np.errstate(invalid="ignore"):
        d = np.sqrt(np.diagonal(hess, axis1=1, axis2=2))
        ok = np.flatnonzero(np.isfinite(d).all(axis=1) & (d > 0).all(axis=1))
    if not ok.size:
        return step
    d = d[ok]
    a = hess[ok] / (d[:, :, None] * d[:, None, :]) + lam[ok, None, None] * np.eye(p)
    rhs = grad[ok] / d
    try:
        step[ok] = np.linalg.solve(a, rhs[..., None])[..., 0] / d
    except np.linalg.LinAlgError:
        for j, k in enumerate(ok):
            try:
                step[k] = np.linalg.solve(a[j], rhs[j]) / d[j]
            except np.linalg.LinAlgError:
                pass
    return step


def _cost(ms: np.ndarray, w: np.ndarray, valid: np.ndarray, n: int) -> np.ndarray:
    """Weighted sum of squared output errors per run, n sum_i w_i ms_i (a chi-square); inf
    where ``valid`` is False or the simulation exploded."""
    good = valid & np.isfinite(ms).all(axis=1)
    return np.where(good, n * _weighted(np.where(good[:, None], ms, 0.0), w), np.inf)


class _Sims:
    """The output-error iterations' simulations, their mean squares and Gauss-Newton moments:
    on the compiled path (:func:`expdesign.oekernel.calm_runs`) time-major outputs passed between
    compiled passes, else the numpy functions on (nu, psi) batch-major pairs; the same numbers
    either way but for the moments' order of sums (:mod:`expdesign.oekernel`)."""

    def __init__(self, profile: ShipProfile, terms: TermSet, data: Sequence[OEData], compiled: bool = True):
        self.profile, self.terms, self.data = profile, terms, data
        self.calm = oekernel.calm_runs(profile, terms, data) if compiled else None

    def simulate(self, theta: np.ndarray, idx: np.ndarray) -> tuple[list, np.ndarray]:
        """The runs ``idx``'s simulations and their mean squared errors (:func:`_mean_squares`)."""
        if self.calm is not None:
            return oekernel.simulate(self.calm, theta, idx, _OE_EXPLODE)
        sims = _simulated(self.profile, self.terms, self.data, theta, idx)
        return sims, _mean_squares(self.data, sims, idx)

    def moments(self, sims: list, theta: np.ndarray, idx: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.calm is not None:
            return oekernel.moments_t(self.calm, sims, theta, idx, w, _FD_STEP)
        return _gauss_newton_moments_numpy(self.profile, self.terms, self.data, sims, theta, idx, w)

    def select(self, sims: list, keep: np.ndarray) -> list:
        """The simulations of the runs where ``keep`` (over the runs simulated) is True (the same
        arrays when it is True for every run: read only, no copy)."""
        if keep.all():
            return sims
        if self.calm is not None:
            return [np.compress(keep, nu, axis=2) for nu in sims]
        return [(nu[keep], psi[keep]) for nu, psi in sims]


def _start(sim: _Sims, theta: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """At the start estimate: which runs simulate (ok (B,)), the fixed weights w = 1/sigma_i^2
    from their residuals (B, 3), the cost (B,) and the simulated outputs of the ok runs."""
    bsz = theta.shape[0]
    finite = np.flatnonzero(np.isfinite(theta).all(axis=1))
    ms = np.full((bsz, 3), np.inf)
    sims, ms[finite] = sim.simulate(theta, finite)
    ok = np.isfinite(ms).all(axis=1)
    w = np.ones((bsz, 3))
    w[ok] = 1.0 / np.maximum(ms[ok], _WEIGHT_FLOOR * ms[ok].max(axis=1, keepdims=True) + 1e-300)
    cost = _cost(ms, w, ok, n)
    return ok, w, cost, sim.select(sims, ok[finite])


def _decrement(step: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """Newton decrement g^T step per run, summed in a fixed order elementwise over the runs (no
    batch-dependent rounding)."""
    decrement = np.zeros(len(step))
    with np.errstate(all="ignore"):
        for j in range(step.shape[1]):
            decrement += step[:, j] * grad[:, j]
    return decrement


def output_error(
    profile: ShipProfile,
    data: Sequence[OEData],
    theta_start: np.ndarray,
    *,
    terms: TermSet | None = None,
    max_iter: int = 10,
    tol: float = OE_TOL,
) -> OEResult:
    """Output-error (prediction-error) estimate started from ``theta_start`` (B, p), e.g. the IV estimate.

    Minimises per run V(theta) = sum_k sum_i w_i (y_i(k) - y_hat_i(k; theta))^2 over the
    noise-free simulation y_hat of the predictor (9.2) from the known start state, by
    Levenberg-Marquardt (Gauss-Newton with the output sensitivities, a step taken only when it
    lowers V). With white measurement noise and a small process disturbance this is the
    maximum-likelihood estimator (Ljung 1999, section 7.4, the output-error model): the noisy
    velocities enter only the residual, never the regressors, so it has no errors-in-variables
    loss, where the IV estimate (2.18) pays for the noise in its regressors with variance.

    The weights w_i = 1/sigma_i^2 come from the start estimate's residuals and stay fixed, so V
    is a chi-square and the Gauss-Newton matrix H = sum S^T W S approximates the inverse
    covariance of the estimate. A run stops when the Gauss-Newton step's predicted decrease
    g^T H^-1 g (the Newton decrement: the step's length in standard errors, squared) is below
    ``tol`` (0.01: a tenth of a standard error), after ``max_iter`` candidate steps, or when the
    damping exceeds 1e8 without a better step. A run whose start simulation diverges keeps its
    start estimate (cost inf). Runs are independent: a run's result does not depend on the batch.
    """
    terms = terms or profile.predictor
    why = output_error_unsupported(profile, terms)
    if why:
        raise DesignError(
            f"{why} ({profile.name!r}): use the IV estimate, `shiptrial design --mc-estimator iv` "
            "(estimator='iv' in the Monte Carlo)"
        )
    theta = np.array(theta_start, float)
    bsz, p = theta.shape
    n = sum(d.y.shape[1] - 1 for d in data)
    sim = _Sims(profile, terms, data)
    ok, w, cost, cur = _start(sim, theta, n)
    cost_start = cost.copy()
    active = ok.copy()
    iters = np.zeros(bsz, dtype=np.int64)
    converged = np.zeros(bsz, dtype=bool)
    lam = np.full(bsz, _LM_START)
    hess, grad = np.zeros((bsz, p, p)), np.zeros((bsz, p))
    fresh = np.flatnonzero(active)  # runs whose moments need computing at their current theta
    while True:
        if fresh.size:
            hess[fresh], grad[fresh] = sim.moments(cur, theta, fresh, w)
        idx = np.flatnonzero(active & (iters < max_iter))
        step = _lm_steps(hess[idx], grad[idx], lam[idx])
        decrement = _decrement(step, grad[idx])
        done = np.isfinite(decrement) & (decrement < tol) & (lam[idx] <= _LM_START)
        converged[idx[done]] = True
        active[idx[done]] = False
        idx, step = idx[~done], step[~done]
        if not idx.size:
            break
        cand = theta.copy()
        cand[idx] += step
        csims, cms = sim.simulate(cand, idx)
        ccost = _cost(cms, w[idx], np.isfinite(step).all(axis=1), n)
        iters[idx] += 1
        better = ccost < cost[idx]
        theta[idx[better]], cost[idx[better]] = cand[idx[better]], ccost[better]
        fresh = idx[better & (iters[idx] < max_iter)]  # no moments for a run that may not step again
        lam[idx[better]] = np.maximum(lam[idx[better]] / _LM_FACTOR, _LM_MIN)
        rej = idx[~better]
        lam[rej] *= _LM_FACTOR
        active[rej[lam[rej] > _LM_MAX]] = False
        cur = sim.select(csims, np.isin(idx, fresh))
    return OEResult(theta, cost_start, cost, iters, converged)
