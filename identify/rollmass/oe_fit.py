"""The output-error fit's driver: Levenberg-Marquardt on the exact sensitivity Jacobian with a
forward-difference fallback, the Gauss-Newton finish to a stationary point, the AR reweighting and
the load's leverage-corrected sandwich covariance (the model and its residual are in :mod:`identify.rollmass.output_error`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import OptimizeResult, least_squares
from threadpoolctl import threadpool_limits

from identify.rollmass.fit_path import Counted, FitPath, PathTally
from identify.rollmass.geodesic import geodesic_lm
from identify.rollmass.gyro_bias import speed_terms
from identify.rollmass.model import Known, Load
from identify.rollmass.output_error import (
    INTERVAL_LAG_S,
    NOISE_AR,
    SANDWICH_LAG_S,
    SWAY_MASS_PRIOR_SD,
    OEFit,
    _measured,
    _Problem,
    _simulate,
    shared_parameters,
)
from identify.rollmass.restoring import heel_gain
from identify.rollmass.sandwich import LoadBasis, UnresolvedLoad, load_basis, load_decrement, load_interval
from identify.rollmass.sensitivity import fir
from identify.rollmass.simulate import RollRecording
from identify.rollmass.speed import followed_speed

# load decrement below which the fit is stationary (a further step < 0.1 of the plain sandwich's standard error; the
# reported one is leverage-corrected, stop 51, about 1.1 times larger), and the
# Gauss-Newton steps allowed to get there after LM, whose step-size test can stop it well short
STATIONARY = 0.01
FINISH_STEPS = 10
LM_NFEV = 200
# evaluation cap of the exact-Jacobian LM (:func:`_lm_exact`): on the three Table 3 cases of the bundled
# example it needed 4-26 evaluations a call; reaching the cap means it is creeping along a nuisance ridge. A capped
# call's point goes on as the next stage's start (stop 55; until then the cap abandoned the path for the redo)
LM_NFEV_EXACT = 60
# evaluation cap of stop 56's exact continuation (:func:`_continued` with CONTINUATION "exact"; the default is stop 59's
# geodesic LM, below): where the exact path ends unconverged, one more
# exact LM on its last stage from where it stopped, then the finish again. On the 7 basin-truth fits (of 105) whose exact
# path ended unconverged at stop 55, 2 then converged in 46 and 116 evaluations (14.5 and 21.1 s a fit, against 116 and
# 89 s redone: single runs at different loads, the later one's ordinary fits 1.15 times slower, far less than this gap) and 5 crept to this cap too and are redone (docs/mass-accuracy.md, stop 56)
LM_NFEV_CONTINUE = 200
# the continuation's walk (stop 59): "geodesic", the geodesic-acceleration LM (identify.rollmass.geodesic) capped at
# GEODESIC_STEPS proposed steps (a step costs up to 2 residuals and, accepted, 1 Jacobian: at most 1,201 residuals and
# 601 Jacobians; the diagnostic's --geodesic N and stop 57's figures count steps too), or "exact", stop 56's exact LM
# above (kept for the benches' comparison). Why: those ends creep along a curved valley (stop 57), where a plain LM's
# accepted steps stay short
CONTINUATION = "geodesic"
GEODESIC_STEPS = 600
# estimate each recording's yaw-rate gyro bias for the turn input (identify.rollmass.gyro_bias) from the
# second stage on, rather than take the recording's mean yaw rate (the first stage's)
GYRO_BIAS = True
# follow the speed's variation in the sway velocity's terms too, (u/U - 1)(Y_v, K_v, n_v) v with v the model's own
# sway velocity at the last stage's parameters (identify.rollmass.gyro_bias.sway_velocity); needs GYRO_BIAS
SWAY_TERM = True


def _whitener(e: np.ndarray, order: int) -> np.ndarray:
    """Stable AR(order) whitening polynomial of one residual channel (least squares)."""
    if order == 0:
        return np.ones(1)
    X = np.column_stack([np.r_[np.zeros(j), e[:-j]] for j in range(1, order + 1)])[order:]
    a, *_ = np.linalg.lstsq(X, e[order:], rcond=None)
    roots = np.roots(np.r_[1.0, -a])
    big = np.abs(roots) >= 0.98
    if big.any():  # keep the whitener's inverse stable
        roots[big] *= 0.98 / np.abs(roots[big])
    return np.real(np.poly(roots))


def _lm(prob: _Problem, x0: np.ndarray, tol: float) -> OptimizeResult:
    """Levenberg-Marquardt on forward differences, capped at :data:`LM_NFEV` evaluations: along the
    mass-height ridge it can creep (597 evaluations, 39 s cpu on ``mass-sim --case case1 --seed 3`` at
    0.3 length) where the Gauss-Newton finish of :func:`fit_output_error` converges in a few steps.
    The fallback path of :func:`fit_output_error`."""
    return least_squares(prob.residual, x0, x_scale="jac", method="lm", xtol=tol, ftol=tol, gtol=tol, max_nfev=LM_NFEV)


# an LM of the fit: (problem, start, tolerance) -> scipy's result; :func:`_lm_exact` or :func:`_lm`
_LM = Callable[[_Problem, np.ndarray, float], OptimizeResult]


def _lm_exact(prob: _Problem, x0: np.ndarray, tol: float, cap: int | None = None) -> OptimizeResult:
    """Levenberg-Marquardt on the sensitivity Jacobian (:meth:`_Problem.jacobian`, a third of the cost
    of forward differences and exact), capped at ``cap`` evaluations (None: :data:`LM_NFEV_EXACT`, read at the call so
    a test can change it, on the exact path; :data:`LM_NFEV_CONTINUE` in its continuation; status 0 there: the call's
    point is kept, see :func:`fit_output_error`)."""
    cap = LM_NFEV_EXACT if cap is None else cap
    return least_squares(
        prob.residual, x0, jac=prob.jacobian, x_scale="jac", method="lm", xtol=tol, ftol=tol, gtol=tol, max_nfev=cap
    )


def _tallied(lm: _LM, tally: PathTally) -> _LM:
    """``lm`` with each call's evaluations and status (0: its cap; -1: the result has none) added to ``tally``."""

    def run(prob: _Problem, x0: np.ndarray, tol: float) -> OptimizeResult:
        res = lm(prob, x0, tol)
        tally.lm.append((int(res.get("nfev", 0)), int(res.get("status", -1))))  # a test's stub may carry neither
        return res

    return run


def _best_start(
    datasets: list[RollRecording],
    kn: Known,
    cal: Load,
    z_f: float,
    z_f_sd: float,
    start: dict[str, float],
    w: np.ndarray,
    lm: _LM,
    xv_prior: tuple[float, float] | None = None,
    tally: PathTally | None = None,
) -> OptimizeResult:
    """Two starts for the joint fit, the one with the lower unweighted cost kept: ``start`` itself,
    and the ship parameters fitted to the two runs whose loads are known (nominal, calibration).
    From a poor start the joint fit can otherwise settle in a local minimum (a wrong sway row with
    a negative or huge load), as a few per cent of the fits from start values 20 % off did.
    Returns the kept joint fit (unwhitened, on the weights ``w``); ``tally`` counts its evaluations."""
    tally = PathTally() if tally is None else tally
    try:
        for load, rec in zip((Load(0.0, 0.0), cal), datasets):
            _simulate(start, kn, z_f, load, rec)
    except FloatingPointError:
        raise ValueError(
            "the start values give an unstable ship with the known loads (roll restoring "
            "k + M g z_g + m g z_m <= 0?); check the profile's GM_T, [roll] and [sway_yaw]"
        ) from None
    shared = shared_parameters(datasets, kn)
    ship = shared + (("z_f",) if z_f_sd > 0 else ())
    x_ship = np.array([start[k] if k != "kappa" else start.get(k, heel_gain(kn)) for k in shared] + ([z_f] if z_f_sd > 0 else []))
    pair = _Problem(datasets[:2], kn, cal, z_f, ship, w[:2], z_f_sd=z_f_sd, xv_prior=xv_prior)
    fitted = lm(Counted(pair, tally), x_ship, 1e-8).x
    prob = Counted(_Problem(datasets, kn, cal, z_f, ship + ("m", "zbar_m"), w, z_f_sd=z_f_sd, xv_prior=xv_prior), tally)
    best = None
    for x in (x_ship, fitted):
        res = lm(prob, np.r_[x, cal.m, cal.zbar], 1e-8)
        if best is None or res.cost < best.cost:
            best = res
    return best


@dataclass
class _Ended:
    """A path's end: the fit (its ``noise``: the last stage's (weights, whiteners)), that stage's problem and the point
    the fit ended at; where the exact path ends unconverged, :func:`_continued` goes on from here."""

    fit: OEFit
    prob: Counted
    x: np.ndarray


@dataclass
class _Finish:
    """What a fit ends with: its Jacobian, its verdict and message, the load's decrement, covariance and dof, and why
    it has no interval (empty when it has one or none was asked for)."""

    J: np.ndarray
    ok: bool
    message: str
    dec: float = float("nan")
    cov_load: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))
    dof: np.ndarray = field(default_factory=lambda: np.full(2, np.inf))
    no_interval: str = ""


def _finish(prob: _Problem, x: np.ndarray, fin: _Finish) -> tuple[np.ndarray, _Finish]:
    """The Gauss-Newton finish (:func:`_gauss_newton`), its stationarity verdict and the load's interval from the
    final Jacobian's one QR."""
    datasets = prob.datasets
    lags = max(1, round(SANDWICH_LAG_S / datasets[0].T))
    x, basis, fin.dec, f = _gauss_newton(prob, x, FINISH_STEPS, lags)
    fin.J = basis.J
    if not fin.dec < STATIONARY:
        fin.ok = False
        fin.message = f"{fin.message}; not at a stationary point after {FINISH_STEPS} Gauss-Newton steps " + (
            f"(a further step would move the load by {np.sqrt(fin.dec):.2g} of its standard errors)"
            if np.isfinite(fin.dec)
            else "(the load's covariance is singular there)"
        )
    try:
        # f: the residual at x; the leverage-corrected covariance and the interval's t_{0.975, nu} (Bell &
        # McCaffrey 2002) from the decrement's QR of this J: one factorisation of the final Jacobian
        # over INTERVAL_LAG_S, not the stationarity check's window (stop 62)
        interval = load_interval(basis, f, [d.n for d in datasets], max(1, round(INTERVAL_LAG_S / datasets[0].T)))
        fin.cov_load, fin.dof = interval.cov, interval.dof
    except UnresolvedLoad as err:  # an interval rounding would decide: none, and the estimate says why; the
        fin.no_interval = str(err)  # point stays this fit's (converged is stationarity's alone: no redo)
    except np.linalg.LinAlgError:
        pass
    return x, fin


def _gauss_newton(prob: _Problem, x: np.ndarray, steps: int, lags: int) -> tuple[np.ndarray, LoadBasis, float, np.ndarray]:
    """Finish a fit with up to ``steps`` Gauss-Newton steps (the sensitivity Jacobian, step halving) until
    the load's step in its sandwich standard errors (:func:`load_decrement`) is below
    :data:`STATIONARY`; returns ``x``, its Jacobian's QR (:class:`LoadBasis`, which the interval reuses),
    that decrement and the residual at ``x``."""
    lengths = [d.n for d in prob.datasets]
    f = prob.residual(x)
    J = prob.jacobian(x)
    basis = load_basis(J)
    dec = load_decrement(basis, f, lengths, lags)
    for _ in range(steps):
        if dec < STATIONARY:
            break
        dx = -np.linalg.lstsq(J, f, rcond=None)[0]
        cost = f @ f
        for _ in range(12):
            f_new = prob.residual(x + dx)
            if f_new @ f_new < cost:
                break
            dx *= 0.5
        else:
            break  # no descent along the Gauss-Newton direction: leave it to the decrement to say so
        x, f = x + dx, f_new
        J = prob.jacobian(x)
        basis = load_basis(J)
        dec = load_decrement(basis, f, lengths, lags)
    return x, basis, dec, f


# one BLAS thread: the fit's products are tall and thin ((3 n, 21) at most), and on the 2-core machine
# under load OpenBLAS's threads made a Jacobian 5 times slower (0.30 s against 0.057 s)
@threadpool_limits.wrap(limits=1)
def fit_output_error(
    datasets: list[RollRecording],
    kn: Known,
    cal: Load,
    z_f: float,
    start: dict[str, float],
    n_reweight: int = 2,
    ar_order: int = NOISE_AR,
    with_cov: bool = True,
    z_f_sd: float | None = None,
) -> OEFit:
    """Fit :data:`SHARED`, ``z_f`` and the loaded ``m, zbar_m`` by output error on ``p, a_s, r`` of all datasets.

    ``start`` holds start values of :data:`SHARED`; ``m, zbar_m`` start at the calibration load.
    ``z_f`` has the Gaussian prior ``N(z_f, z_f_sd^2)`` (``z_f_sd`` defaults to the profile's
    ``z_f_prior_sd``; 0 holds ``z_f`` fixed): the fit maximises the posterior. Weights: 1/sd of each
    dataset's channel residual, re-estimated ``n_reweight`` times. The last fit is finished by
    Gauss-Newton steps to a stationary point (:func:`load_decrement`); ``converged`` is false when
    it is not reached. Where a recording's speed is followed (``speed.followed_speed``) the sway
    mass has a prior too (``output_error.SWAY_MASS_PRIOR_SD``). Without ``with_cov`` the sandwich covariance is left NaN and no finishing
    steps are taken.

    LM runs on the sensitivity Jacobian (:func:`_lm_exact`). Where that path ends unconverged (not
    stationary after the finish), its last stage is first continued from where it stopped (:func:`_continued`,
    stop 56; since stop 59 by the geodesic-acceleration LM, :mod:`identify.rollmass.geodesic`, which follows the
    curved valley those ends creep along, docs/mass-accuracy.md "Stop 59"); where that is not stationary either, the whole fit is redone on forward differences (:func:`_lm`), the path
    the fit took before the exact Jacobian, so the answer there is that path's; ``path`` of the result
    records which path it took and each path's evaluations (:class:`fit_path.FitPath`). An exact LM at its
    cap :data:`LM_NFEV_EXACT` no longer abandons the path (stop 55): its point is the best start's candidate
    or the next stage's start, and the finish judges (without ``with_cov``, no finish: a capped exact LM still
    sends the fit to the redo, as before stop 55). On the basin truth family 24 of 105 fits had been
    redone, every one from a capped LM (27-167 s CPU); going on, 17 of them end on the exact path at the
    redo's load (within 0.2 % and 0.4 mm) at 4-10 s, and 7 end unconverged and are redone as before
    (docs/mass-accuracy.md, stop 55). Why a redo at all: on short low-noise data
    (tests/test_rollmass.py's 0.3-length case 1) the cost is flat along a nuisance ridge (the sway row's
    coefficients and the roll row's sway couplings grow together: the first joint fit ends at X_v 1,020 on
    forward differences and at 40,000 on the exact Jacobian, truth 20, at the same cost), the
    exact-Jacobian LM walks along it and the reweighted fits creep from there (0.150 kg, not
    stationary), while the forward-difference path stops near the start and comes back (0.167 kg,
    stationary). On the bundled example's three cases the exact path gives the same optimum (load within
    3e-5 kg and 3e-5 m) at a third of the cpu.
    """
    args = (datasets, kn, cal, z_f, start, n_reweight, ar_order, with_cov, z_f_sd)
    path = FitPath()
    end = _fit(*args, lm=_lm_exact, tally=path.exact)
    fit = end.fit
    # Without with_cov there is no finish to judge a capped LM's point stationary, so main's rule holds there: any
    # exact LM at its cap sends the fit to the redo (estimate(with_ci=False), as benchmarks/bench_rollmass.py runs oe)
    capped = not with_cov and any(s == 0 for _, s in path.exact.lm)
    if not fit.converged and with_cov and np.isfinite(fit.decrement):
        # the finish judged the exact path's end short of stationary (a finite decrement: its LM ended well, the finish
        # ran, the point is finite): it crept along the flat mass-height ridge and stopped short (stop 56), so go on
        # from where it stopped. An end the finish never judged (a diverged LM) goes to the redo from both starts
        path.why = f"not converged: {fit.message}"
        path.continued = PathTally()
        fit = _continued(end, z_f, path.continued)
        if fit.converged:
            path.path = "geodesic" if CONTINUATION == "geodesic" else "continued"
    if fit.converged and not capped:
        fit.path = path
        return fit
    if capped:
        path.why = "an exact LM at its cap, no finish to judge it (with_cov off)"
    elif path.continued is None:
        path.why = f"not converged: {fit.message}"
    else:
        path.why += f"; continued ({CONTINUATION}), still not converged: {fit.message}"
    path.path, path.redo = "redo", PathTally()
    fit = _fit(*args, lm=_lm, tally=path.redo).fit
    fit.path = path
    return fit


def _lm_continue(prob: _Problem, x0: np.ndarray, tol: float) -> OptimizeResult:
    """:func:`_lm_exact` with the continuation's cap :data:`LM_NFEV_CONTINUE` (a name of its own so a test can stub it)."""
    return _lm_exact(prob, x0, tol, cap=LM_NFEV_CONTINUE)


def _lm_geodesic(prob: _Problem, x0: np.ndarray, tol: float, cap: int | None = None) -> OptimizeResult:
    """:func:`geodesic.geodesic_lm` as the continuation's LM (stop 59), capped at ``cap`` proposed steps (None:
    :data:`GEODESIC_STEPS`, read at the call) and stopped early by the finish's own rule (the load's decrement below
    :data:`STATIONARY`, checked every 5 accepted steps: along this valley the sway scale walks on while the load has
    stopped); status 0 at its cap, 2 otherwise, ``nfev`` / ``njev`` its residual / Jacobian evaluations."""
    lengths = [d.n for d in prob.datasets]
    lags = max(1, round(SANDWICH_LAG_S / prob.datasets[0].T))

    def stationary(x: np.ndarray, f: np.ndarray, J: np.ndarray) -> bool:
        return bool(load_decrement(load_basis(J), f, lengths, lags) < STATIONARY)

    g = geodesic_lm(prob, x0, GEODESIC_STEPS if cap is None else cap, xtol=tol, stationary=stationary)
    msg = f"geodesic LM {g.status} after {g.steps} steps"
    return OptimizeResult(
        x=g.x,
        cost=g.f @ g.f / 2,
        jac=g.J,
        nfev=g.residuals,
        njev=g.jacobians,
        status=2 if g.converged else 0,
        success=g.converged,
        message=msg,
        nit=g.steps,
    )


def _continued(end: _Ended, z_f: float, tally: PathTally) -> OEFit:
    """The exact path's last stage continued from where it ended unconverged (stop 56): on that stage's problem (same
    weights and whiteners, so the same cost), counted in ``tally``, the geodesic LM (:func:`_lm_geodesic`, stop 59) or,
    with :data:`CONTINUATION` ``"exact"``, one exact LM of at most :data:`LM_NFEV_CONTINUE` evaluations; then the
    finish (:func:`_finish`) judges again. Why not the redo at once: on the basin truth its five forward-difference
    LMs ran to their caps (61-141 s CPU a fit); on waves/6/case1 the redo reached the point the exact walk reaches
    (+23.88 against +23.84 % mass), and on imu_mount/6/case3 it did not converge where that walk does."""
    prob = end.prob.recounted(tally)
    res = _tallied(_lm_geodesic if CONTINUATION == "geodesic" else _lm_continue, tally)(prob, end.x, 1e-10)
    sd = np.array([e.std(axis=0) for e in prob.errors(res.x)])
    return _conclude(prob, res, sd, end.fit.noise, True, z_f).fit


def _reweighted(
    errs: list[np.ndarray], ar: list[list[np.ndarray]] | None, ar_order: int
) -> tuple[list[list[np.ndarray]], np.ndarray, np.ndarray]:
    """Iterated ML's next weights: each channel's output error whitened (waves are narrow-band process noise that
    reaches the outputs coloured; the new whitener is convolved with the last stage's ``ar``), then weighted by its
    innovation sd. ``errs`` are :meth:`output_error._Problem.errors`, already whitened by ``ar``: the innovation sd is
    the new factor's output on them, i.e. the composite whitener's on the raw error (stop 61; main's bits up to stop 61
    applied the composite to the whitened errors, ``ar`` twice, an sd sqrt(1 + a^2) too large on an AR(1) channel of
    pole a). Stage 1 (``ar`` None) is the same either way; the sandwich uses the weights actually applied. Returns the
    whiteners, the innovation sds and the weights."""
    new = [[_whitener(e[:, j], ar_order) for j in range(3)] for e in errs]
    composite = [[new[i][j] if ar is None else np.convolve(new[i][j], ar[i][j]) for j in range(3)] for i in range(len(errs))]
    sd = np.array([[fir(new[i][j], e[:, j]).std() for j in range(3)] for i, e in enumerate(errs)])
    return composite, sd, 1.0 / np.maximum(sd, 1e-12)


def _fit(
    datasets: list[RollRecording],
    kn: Known,
    cal: Load,
    z_f: float,
    start: dict[str, float],
    n_reweight: int,
    ar_order: int,
    with_cov: bool,
    z_f_sd: float | None,
    lm: _LM,
    tally: PathTally,
) -> _Ended:
    """:func:`fit_output_error` along one LM (``_lm_exact`` or ``_lm``), its evaluations counted in ``tally``."""
    lm = _tallied(lm, tally)
    z_f_sd = kn.z_f_prior_sd if z_f_sd is None else z_f_sd
    free = shared_parameters(datasets, kn) + (("z_f",) if z_f_sd > 0 else ()) + ("m", "zbar_m")
    w = np.array([1.0 / np.maximum(_measured(d, kn.g).std(axis=0), 1e-12) for d in datasets])
    ar = None
    # the sway mass's prior (output_error.SWAY_MASS_PRIOR_SD) where a speed is followed: there the sway row walked its
    # nearly free scale without converging (stop 50); a run at constant speed keeps main's fit bit for bit
    followed = any(followed_speed(d) is not None for d in datasets)
    xv_prior = (start["X_v"], SWAY_MASS_PRIOR_SD) if followed and SWAY_MASS_PRIOR_SD > 0 else None
    first = _best_start(datasets, kn, cal, z_f, z_f_sd, start, w, lm, xv_prior, tally=tally)
    x = first.x
    r_bias: list[float | None] = [None] * len(datasets)
    sway: list[np.ndarray | None] = [None] * len(datasets)
    for it in range(n_reweight + 1):
        prob = Counted(_Problem(datasets, kn, cal, z_f, free, w, ar, z_f_sd, r_bias, sway, xv_prior), tally)
        # _best_start has just solved the first problem (same weights, no whitening); its optimum only
        # seeds the reweighted fits, which run to the tight tolerance below
        res = first if it == 0 and n_reweight > 0 else lm(prob, x, 1e-10)
        x = res.x
        if it < n_reweight and GYRO_BIAS:
            # the gyro's bias at this stage's parameters (identify.rollmass.gyro_bias), before the whiteners
            # are fitted, so that they are fitted to the residual without the mean turning's structure
            v = prob.values(x)
            r_bias, sway = speed_terms(v, kn, v.get("z_f", z_f), prob.loads(v), datasets, r_bias, sway, SWAY_TERM)
            prob = Counted(_Problem(datasets, kn, cal, z_f, free, w, ar, z_f_sd, r_bias, sway, xv_prior), tally)
        errs = prob.errors(x)
        sd = np.array([e.std(axis=0) for e in errs])
        if it < n_reweight:
            ar, sd, w = _reweighted(errs, ar, ar_order)
    return _conclude(prob, res, sd, (w, ar), with_cov, z_f)


def _conclude(prob: Counted, res: OptimizeResult, sd: np.ndarray, noise: tuple, with_cov: bool, z_f: float) -> _Ended:
    """The last stage's LM result ``res`` on ``prob`` finished (:func:`_finish`, with ``with_cov``) into an :class:`OEFit`;
    ``sd`` and ``noise`` are the stage's residual sds and (weights, whiteners)."""
    x = res.x
    # an LM stopped by its evaluation cap is judged by the stationarity check below (with_cov), not by its flag
    ok = (bool(res.success) or (with_cov and res.status == 0)) and bool(np.all(np.isfinite(x))) and float(res.cost) < 1e5
    fin = _Finish(res.jac, ok, str(res.message))
    if with_cov and ok:
        x, fin = _finish(prob, x, fin)
    J = fin.J
    v = prob.values(x)
    scale = np.sqrt(np.maximum(np.einsum("ij,ij->j", J, J), 1e-300))
    sv = np.linalg.svd(J / scale, compute_uv=False)
    fit = OEFit(
        values=v,
        m=v["m"],
        zbar_m=v["zbar_m"],
        z_f=v.get("z_f", z_f),
        cov_load=fin.cov_load,
        converged=fin.ok,
        message=fin.message,
        decrement=fin.dec,
        rel_singular=float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0,
        noise_sd=sd,
        noise=noise,
        dof=fin.dof,
        no_interval=fin.no_interval,
    )
    return _Ended(fit, prob, x)
