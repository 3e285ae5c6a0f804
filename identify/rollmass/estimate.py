"""Multi-dataset mass and CoG estimation of Linder et al. (2015) section 3, and our improvement.

Three datasets (nominal, calibration with a known load, loaded with an unknown one) share the
ship parameters of (20); each gives its own Tustin-discretised regression (19) and the stacked,
instrument-weighted residual (27)-(28) is minimised over the physical parameters.

Methods:

``ls``        the paper's "constrained least squares" (instruments = regressors), all 9 free.
``paper-iv``  the paper's iterative IV (29)-(32): iteration-0 black-box instruments, then the
              model-refined roll-rate and accelerometer instruments (v' left out, as (31)-(32)
              do), identity weighting, all 9 parameters free from the start values (33).
``oe``        ours, the default: joint output-error / maximum-likelihood fit of the sway-roll-yaw
              model to all three IMU channels of all three datasets (``a_s`` an output, not a
              noisy regressor), ``z_f`` fitted under its prior; see :mod:`identify.rollmass.output_error`.
``improved``  our first attempt, kept for comparison: (i) the exact flat direction (scale of (11) vs ``z_f``) removed by fixing
              ``z_f`` at a prior whose uncertainty is propagated into the confidence intervals;
              (ii) the load enters through its two moments ``m z_m`` and ``m z_m (zbar_m - zbar_s)``,
              in which (10) and ``c`` are linear (no spurious optimum at ``z_m = 0``);
              (iii) instruments = the regressors simulated from the rudder, the accelerometer one
              from a black-box fit of the measured ``a_s``, so it carries ``v'``, the roll rate from
              the model; (iv) refined-IV prefilter ``1/A(q)`` (equation error -> output error)
              times an AR whitening filter, iterated; (v) two-step (HAC-optimal) weighting of the
              moments; (vi) a per-dataset intercept for the roll-gyro bias.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.special import stdtrit  # scipy.optimize imports scipy.special already; scipy.stats would cost ~1 s

from identify.rollmass.fit_path import FitPath
from identify.rollmass.instruments import (
    N_LAGS,
    black_box_instruments,
    diff2,
    instrument_matrix,
    paper_model_sim,
    regression,
)
from identify.rollmass.model import (
    SHIP_PARAMS,
    Known,
    Load,
    RollParams,
    continuous_coefficients,
    discrete_coefficients,
    load_from_moments,
    load_moments,
)
from identify.rollmass.oe_fit import fit_output_error
from identify.rollmass.restoring import DEFAULT_HEEL_REFERENCE, referenced_heel
from identify.rollmass.simulate import RollRecording
from identify.rollmass.speed import followed_speed

PARAMS = SHIP_PARAMS + ("m", "zbar_m")
# the improved estimator fits the loaded dataset's moments (linear in (10) and c), not (m, zbar_m)
MOMENTS = ("mz", "mzs")
METHODS = ("ls", "paper-iv", "improved", "oe")
DEFAULT_METHOD = "oe"
# Start values (33): [k, A_x, d, K_r, K_vdot, K_delta, z_f, m, zbar_m]
PAPER_START = np.array([9.0, 0.5, 0.1, -0.4, 1.0, -0.4, -0.018, 0.0, 0.0])
NOISE_AR = 8  # order of the refined-IV noise prefilter
HAC_LAGS = 100  # Newey-West lags (2 s at 50 Hz): residuals are coloured by the FIR filter and the waves


@dataclass
class MassEstimate:
    """Estimated load ``m`` [kg] at body-frame height ``zbar_m`` [m, z down] and the ship parameters."""

    method: str
    params: dict[str, float]
    m: float
    zbar_m: float
    m_sd: float = float("nan")
    zbar_m_sd: float = float("nan")
    corr: float = float("nan")
    cost: float = float("nan")
    converged: bool = True
    free: tuple[str, ...] = PARAMS
    rel_singular: float = float("nan")  # smallest / largest singular value of the scaled Jacobian
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    m_dof: float = float("inf")  # degrees of freedom of m_sd^2 (oe: sandwich.LoadMoments.dof); inf: a normal interval
    zbar_m_dof: float = float("inf")
    fit_path: FitPath | None = None  # oe: its fit's path (exact, geodesic, continued or forward-difference redo), evaluations

    def critical(self) -> tuple[float, float]:
        """The 95 % interval's critical values of ``m`` and ``zbar_m``: Student's ``t_{0.975, nu}`` with the
        Satterthwaite ``nu`` of each variance (Bell & McCaffrey 2002), 1.96 where no ``nu`` is known."""
        return tuple(float(stdtrit(d, 0.975)) if np.isfinite(d) else 1.96 for d in (self.m_dof, self.zbar_m_dof))

    def ci(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The 95 % intervals of ``m`` and ``zbar_m`` (:meth:`critical` standard errors either side)."""
        cm, cz = self.critical()
        return (
            (self.m - cm * self.m_sd, self.m + cm * self.m_sd),
            (self.zbar_m - cz * self.zbar_m_sd, self.zbar_m + cz * self.zbar_m_sd),
        )


@dataclass
class _Block:
    """One dataset's precomputed products ``Z^T Y``, ``Z^T Phi``, ``Z^T 1`` (rows from N_LAGS on)."""

    ZtY: np.ndarray
    ZtPhi: np.ndarray
    Zt1: np.ndarray
    L: np.ndarray  # weighting factor, W = L L^T
    n: int
    T: float
    Y: np.ndarray
    Phi: np.ndarray
    Z: np.ndarray
    one: np.ndarray | float = 1.0  # the (prefiltered) intercept regressor


def _block(rec: RollRecording, Z: np.ndarray) -> _Block:
    """The paper's block: unfiltered regression (16)-(18), identity weighting, no intercept."""
    Y, Phi = regression(rec)
    s = slice(N_LAGS, None)
    Y, Phi, Z = Y[s], Phi[s], Z[s]
    return _Block(Z.T @ Y, Z.T @ Phi, Z.sum(axis=0), np.eye(Z.shape[1]), len(Y), rec.T, Y, Phi, Z)


class _Problem:
    """The stacked residual (27) over the free physical parameters (plus intercepts)."""

    def __init__(
        self, blocks: list[_Block], kn: Known, cal: Load, free: tuple[str, ...], fixed: dict[str, float], intercept: bool
    ):
        self.blocks, self.kn, self.cal, self.free, self.fixed, self.intercept = blocks, kn, cal, free, fixed, intercept

    def full(self, x: np.ndarray) -> dict[str, float]:
        vals = dict(self.fixed)
        vals.update(zip(self.free, x[: len(self.free)]))
        return vals

    def loads(self, vals: dict[str, float]) -> list:
        if "mz" in vals:
            return [Load(0.0, 0.0), self.cal, (vals["mz"], vals["mzs"])]
        return [Load(0.0, 0.0), self.cal, Load(vals["m"], vals["zbar_m"])]

    def errors(self, x: np.ndarray) -> list[np.ndarray]:
        vals = self.full(x)
        p = RollParams(*(vals[k] for k in SHIP_PARAMS))
        b = x[len(self.free) :] if self.intercept else np.zeros(3)
        out = []
        for i, (blk, load) in enumerate(zip(self.blocks, self.loads(vals))):
            g = discrete_coefficients(continuous_coefficients(p, self.kn, load), blk.T)
            out.append((blk, g, b[i]))
        return out

    def residual(self, x: np.ndarray) -> np.ndarray:
        return np.concatenate([blk.L.T @ ((blk.ZtY - blk.ZtPhi @ g - bi * blk.Zt1) / blk.n) for blk, g, bi in self.errors(x)])

    def moment_cov(self, x: np.ndarray) -> np.ndarray:
        """Newey-West covariance of the stacked weighted moments at ``x`` (datasets independent)."""
        covs = [blk.L.T @ c @ blk.L for blk, c in zip(self.blocks, _block_covs(self, x))]
        out = np.zeros((sum(c.shape[0] for c in covs),) * 2)
        i = 0
        for c in covs:
            out[i : i + len(c), i : i + len(c)] = c
            i += len(c)
        return out


def _solve(prob: _Problem, x0: np.ndarray) -> least_squares:
    return least_squares(prob.residual, x0, x_scale="jac", method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=4000)


def _check(datasets: list[RollRecording]) -> None:
    from primitives.errors import UserError

    if len(datasets) != 3:
        raise UserError(f"need three datasets (nominal, calibration, loaded), got {len(datasets)}")
    T0 = datasets[0].T
    for d in datasets:
        if abs(d.T - T0) > 1e-9 * T0:
            raise UserError(
                f"{d.name}: sample time {d.T:g} s differs from {datasets[0].name}'s {T0:g} s; resample all three to one rate"
            )
        if d.n < 4 * N_LAGS:
            raise UserError(f"{d.name}: only {d.n} samples; need at least {4 * N_LAGS}")
        if np.std(d.delta) < 1e-4:
            raise UserError(f"{d.name}: the rudder does not move; the estimator needs rudder excitation")


def estimate(
    datasets: list[RollRecording],
    kn: Known,
    cal: Load,
    method: str = "improved",
    with_ci: bool = False,
    z_f: float | None = None,
    max_iter: int = 8,
    fix: dict[str, float] | None = None,
    start: dict[str, float] | None = None,
    heel_reference: str = DEFAULT_HEEL_REFERENCE,
) -> MassEstimate:
    """Estimate the loaded dataset's ``m``, ``zbar_m`` from ``[nominal, calibration, loaded]``.

    ``cal`` is the known calibration load. ``z_f`` (improved, oe) overrides the profile prior.
    ``start`` (oe only, required) holds start values of the ship parameters, e.g.
    :func:`identify.rollmass.output_error.start_values` of the profile. ``heel_reference`` (oe only):
    how the roll angle is referenced, one of :data:`restoring.HEEL_REFERENCES`
    (:func:`restoring.referenced_heel`).
    """
    _check(datasets)
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}")
    if method == "oe":
        if start is None:
            raise ValueError("the oe method needs start values (output_error.start_values(profile))")
        return _oe(datasets, kn, cal, with_ci, kn.z_f_prior if z_f is None else z_f, start, heel_reference)
    if method == "improved":
        fixed = {"z_f": kn.z_f_prior if z_f is None else z_f}
        if fix is not None:
            fixed.update(fix)
        return _improved(datasets, kn, cal, with_ci, fixed)
    if method == "ls":
        blocks = [_block(d, regression(d)[1]) for d in datasets]
        return _finish("ls", _Problem(blocks, kn, cal, PARAMS, {}, False), _paper_start(cal), with_ci)
    return _paper_iv(datasets, kn, cal, with_ci, max_iter)


def _paper_start(cal: Load) -> np.ndarray:
    """(33), except ``m, zbar_m`` start at the calibration load: (33)'s ``m = zbar_m = 0`` is a
    stationary point in ``zbar_m`` (its gradient is proportional to ``m``) where our solver stays."""
    return np.r_[PAPER_START[:7], cal.m, cal.zbar]


def _paper_iv(datasets: list[RollRecording], kn: Known, cal: Load, with_ci: bool, max_iter: int) -> MassEstimate:
    bb = [black_box_instruments(d) for d in datasets]
    Zs = [instrument_matrix(y, a, r, d.delta) for (y, a, r), d in zip(bb, datasets)]
    x = _paper_start(cal)
    est = None
    for _ in range(max_iter):
        prob = _Problem([_block(d, Z) for d, Z in zip(datasets, Zs)], kn, cal, PARAMS, {}, False)
        est = _finish("paper-iv", prob, x, with_ci)
        x_new = np.array([est.params[k] for k in PARAMS])
        done = np.allclose(x_new, x, rtol=1e-6, atol=1e-9)
        x = x_new
        if done:
            break
        p = RollParams(*x[:7])
        try:
            loads = [Load(0.0, 0.0), cal, Load(x[7], x[8])]
            sims = [paper_model_sim(p, kn, ld, r, d.delta, d.T) for ld, (_, _, r), d in zip(loads, bb, datasets)]
        except FloatingPointError:
            est.warnings.append("paper-iv: refinement stopped, the current model is unstable")
            break
        Zs = [instrument_matrix(yh, ah, r, d.delta) for (yh, ah), (_, _, r), d in zip(sims, bb, datasets)]
    return est


def _prefilter(x: np.ndarray, filt: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    from scipy.signal import lfilter  # here: for the IV methods only (its import: 2 s of CPU)

    return lfilter(filt[0], filt[1], x, axis=0)


def _noise_ar(e: np.ndarray, order: int = NOISE_AR) -> np.ndarray:
    """AR(order) whitening polynomial of the equation error (the refined-IV prefilter)."""
    X = np.column_stack([np.r_[np.zeros(j), e[:-j]] for j in range(1, order + 1)])
    a, *_ = np.linalg.lstsq(X[order:], e[order:], rcond=None)
    poly = np.r_[1.0, -a]
    roots = np.roots(poly)
    if np.any(np.abs(roots) >= 0.999):
        roots = np.where(np.abs(roots) >= 0.999, 0.99 * roots / np.abs(roots), roots)
        poly = np.real(np.poly(roots))
    return poly


def _improved_blocks(datasets: list[RollRecording], sims: list[tuple], polys: list[np.ndarray], Ls: list | None) -> list[_Block]:
    """Prefiltered regressions with instruments = noise-free regressors simulated from the rudder."""
    blocks = []
    for i, (d, (y_hat, a_hat, r_hat), a) in enumerate(zip(datasets, sims, polys)):
        Z = np.column_stack([-np.r_[0, y_hat[:-1]], -np.r_[0, 0, y_hat[:-2]], diff2(a_hat), diff2(r_hat), diff2(d.delta)])
        Y, Phi = regression(d)
        one = np.ones(len(Y))
        Y, Phi, Z, one = (_prefilter(v, a) for v in (Y, Phi, Z, one))
        s = slice(N_LAGS, None)
        Y, Phi, Z, one = Y[s], Phi[s], np.column_stack([Z[s], one[s]]), one[s]
        n = len(Y)
        L = np.eye(Z.shape[1]) if Ls is None else Ls[i]
        blocks.append(_Block(Z.T @ Y, Z.T @ Phi, Z.T @ one, L, n, d.T, Y, Phi, Z, one))
    return blocks


def _improved(
    datasets: list[RollRecording], kn: Known, cal: Load, with_ci: bool, fixed: dict[str, float], n_iter: int = 4
) -> MassEstimate:
    """Our estimator: z_f fixed, refined IV (noise-model prefilter, model-simulated instruments that
    carry v' through the black-box accelerometer), two-step optimal weighting of the moments."""
    from scipy.signal import lfilter  # here: for the IV methods only (its import: 2 s of CPU)

    free = tuple(k for k in SHIP_PARAMS + MOMENTS if k not in fixed)
    bb = [black_box_instruments(d) for d in datasets]
    sims = bb
    polys = [(np.array([1.0]), np.array([1.0]))] * 3
    start = dict(zip(PARAMS, _paper_start(cal)))
    start.update(
        zip(MOMENTS, load_moments(RollParams(*(start[k] if k != "z_f" else fixed["z_f"] for k in SHIP_PARAMS)), kn, cal))
    )
    x = np.r_[[start[k] for k in free], np.zeros(3)]
    Ls = None
    for it in range(n_iter):
        prob = _Problem(_improved_blocks(datasets, sims, polys, Ls), kn, cal, free, fixed, True)
        res = _solve(prob, x)
        x = res.x
        vals = prob.full(x)
        p = RollParams(*(vals[k] for k in SHIP_PARAMS))
        loads = prob.loads(vals)
        # refine: noise model from the unfiltered equation error, instruments from the model
        polys, sims = [], []
        for d, ld, (y_bb, a_hat, r_hat), bi in zip(datasets, loads, bb, x[len(free) :]):
            Y, Phi = regression(d)
            g = discrete_coefficients(continuous_coefficients(p, kn, ld), d.T)
            # refined IV (Young; Gilson et al. 2006): prefilter by 1/A(q) turns the equation error
            # into an output error (at 50 Hz the AR part is ~(1 - q^-1)^2 and amplifies gyro noise),
            # then whiten what is left with an AR model
            A = np.array([1.0, g[0], g[1]])
            if np.any(np.abs(np.roots(A)) >= 1):
                A = np.array([1.0])
            e_out = lfilter([1.0], A, Y - Phi @ g - bi)[N_LAGS:]
            polys.append((_noise_ar(e_out), A))
            u = diff2(a_hat) + (g[3] * diff2(r_hat) + g[4] * diff2(d.delta)) / g[2]
            y_hat = lfilter([g[2]], [1.0, g[0], g[1]], u) if np.all(np.abs(np.roots([1.0, g[0], g[1]])) < 1) else y_bb
            sims.append((y_hat, a_hat, r_hat))
        if it >= 1:
            # two-step GMM: weight by the inverse HAC covariance of each dataset's moments
            Ls = []
            for covb in _block_covs(prob, x):
                lam, V = np.linalg.eigh(covb)
                keep = lam > 1e-10 * lam[-1]
                Ls.append(V[:, keep] / np.sqrt(lam[keep]))
    prob = _Problem(_improved_blocks(datasets, sims, polys, Ls), kn, cal, free, fixed, True)
    est = _finish("improved", prob, x, with_ci)
    if with_ci and np.isfinite(est.m_sd):
        # z_f is fixed, not known: propagate its prior sd by a finite-difference refit
        h = max(kn.z_f_prior_sd, 1e-3) * 0.5
        other = _finish("improved", _Problem(prob.blocks, kn, cal, free, {**fixed, "z_f": fixed["z_f"] + h}, True), x, False)
        dm, dz = (other.m - est.m) / h, (other.zbar_m - est.zbar_m) / h
        var_m = est.m_sd**2 + (dm * kn.z_f_prior_sd) ** 2
        var_z = est.zbar_m_sd**2 + (dz * kn.z_f_prior_sd) ** 2
        cov = est.corr * est.m_sd * est.zbar_m_sd + dm * dz * kn.z_f_prior_sd**2
        est.m_sd, est.zbar_m_sd, est.corr = float(np.sqrt(var_m)), float(np.sqrt(var_z)), float(cov / np.sqrt(var_m * var_z))
    _warn(est)
    return est


def _oe(
    datasets: list[RollRecording],
    kn: Known,
    cal: Load,
    with_ci: bool,
    z_f: float,
    start: dict[str, float],
    heel_reference: str = DEFAULT_HEEL_REFERENCE,
) -> MassEstimate:
    """Output-error fit with ``z_f`` under its prior ``N(z_f, z_f_prior_sd^2)``; with ``with_ci`` the
    sandwich covariance of every free parameter, ``z_f`` included (:func:`oe_fit.fit_output_error`).
    The recordings' roll angles are first re-referenced to the accelerometer's heel
    (:func:`restoring.referenced_heel`): the AHRS's roll error would read as load through the heel moment.
    A ``u`` the model holds (:func:`speed.followed_speed`: its variation within the positioning's
    error, or not finite) is dropped first, so the heel reference's centripetal ``u r`` takes ``U`` too:
    the column's error would otherwise reach the fit through the roll angle."""
    datasets = [d if d.u is None or followed_speed(d) is not None else replace(d, u=None) for d in datasets]
    datasets = [replace(d, phi=referenced_heel(d, kn.g, kn.U if d.U is None else d.U, heel_reference)) for d in datasets]
    f = fit_output_error(datasets, kn, cal, z_f, start, with_cov=with_ci)
    # K_r of (11) from the fitted K_ur, so the shared parameters read as in the paper's Table 3
    K_r = (f.values["K_ur"] - f.values["K_vdot"]) * kn.U
    params = {**f.values, "K_r": K_r, "z_f": f.z_f}
    est = MassEstimate(
        method="oe",
        params=params,
        m=f.m,
        zbar_m=f.zbar_m,
        converged=f.converged,
        free=tuple(f.values),
        rel_singular=f.rel_singular,
        fit_path=f.path,
    )
    if not f.converged:
        est.warnings.append(f"oe: the fit did not converge ({f.message})")
    if with_ci and f.no_interval:
        est.warnings.append(f"oe: {f.no_interval}")
    if with_ci and np.all(np.isfinite(f.cov_load)):
        est.m_sd, est.zbar_m_sd = float(np.sqrt(f.cov_load[0, 0])), float(np.sqrt(f.cov_load[1, 1]))
        est.corr = float(f.cov_load[0, 1] / (est.m_sd * est.zbar_m_sd))
        est.m_dof, est.zbar_m_dof = (float(d) for d in f.dof)
    _warn(est)
    return est


def _block_covs(prob: _Problem, x: np.ndarray) -> list[np.ndarray]:
    """Newey-West covariance of each dataset's unweighted moments ``Z^T e / n``."""
    out = []
    for blk, g, bi in prob.errors(x):
        e = blk.Y - blk.Phi @ g - bi * blk.one
        h = blk.Z * e[:, None]
        S = h.T @ h
        for lag in range(1, HAC_LAGS + 1):
            G = h[lag:].T @ h[:-lag]
            S += (1 - lag / (HAC_LAGS + 1)) * (G + G.T)
        out.append(S / blk.n**2)
    return out


def _finish(method: str, prob: _Problem, x0: np.ndarray, with_ci: bool) -> MassEstimate:
    res = _solve(prob, x0)
    vals = prob.full(res.x)
    if "mz" in vals:
        p = RollParams(*(vals[k] for k in SHIP_PARAMS))
        ld = load_from_moments(p, prob.kn, vals["mz"], vals["mzs"])
        vals["m"], vals["zbar_m"] = ld.m, ld.zbar
    npar = len(prob.free)
    J = res.jac[:, :npar] * np.maximum(np.abs(res.x[:npar]), 1e-3)
    sv = np.linalg.svd(J, compute_uv=False)
    est = MassEstimate(
        method=method,
        params={k: float(vals[k]) for k in PARAMS},
        m=float(vals["m"]),
        zbar_m=float(vals["zbar_m"]),
        cost=float(res.cost),
        converged=bool(res.success) and np.all(np.isfinite(res.x)),
        free=prob.free,
        rel_singular=float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0,
    )
    if not est.converged:
        est.warnings.append(f"{method}: the fit did not converge ({res.message})")
    if with_ci:
        try:
            cov = moment_sandwich(res.jac, prob.moment_cov(res.x))
        except np.linalg.LinAlgError:
            est.warnings.append(f"{method}: singular Jacobian, no confidence intervals")
            return est
        if "mz" in vals:
            cov = _moments_to_load_cov(prob, vals, cov)
        else:
            idx = [prob.free.index("m"), prob.free.index("zbar_m")]
            cov = cov[np.ix_(idx, idx)]
        est.m_sd, est.zbar_m_sd = float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1]))
        est.corr = float(cov[0, 1] / (est.m_sd * est.zbar_m_sd))
    return est


def moment_sandwich(J: np.ndarray, S: np.ndarray) -> np.ndarray:
    """The moment methods' sandwich ``(J^T J)^-1 J^T S J (J^T J)^-1`` (``S`` the moments' covariance) as ``B S B^T``,
    ``B = R^-1 Q^T`` (``J = Q R``): without forming ``J^T J``, whose condition number is ``cond(J)^2`` (1.8e16 on the
    bundled example's ``ls`` fit, where the inverse erred by 2e-5 of ``sd_i sd_j``; stop 52). Raises
    ``LinAlgError`` for an exactly singular ``R``."""
    Q, R = np.linalg.qr(J)
    B = np.linalg.solve(R, Q.T)  # LU of a triangular R: back substitution in effect
    return B @ S @ B.T


def _moments_to_load_cov(prob: _Problem, vals: dict[str, float], cov: np.ndarray) -> np.ndarray:
    """Delta method from ``(m z_m, m z_m (zbar_m - zbar_s))`` to ``(m, zbar_m)``."""
    idx = [prob.free.index("mz"), prob.free.index("mzs")]
    p = RollParams(*(vals[k] for k in SHIP_PARAMS))
    base = np.array([vals["mz"], vals["mzs"]])
    D = np.zeros((2, 2))
    for j in range(2):
        h = 1e-6 * max(abs(base[j]), 1e-4)
        b = base.copy()
        b[j] += h
        ld = load_from_moments(p, prob.kn, *b)
        D[:, j] = (np.array([ld.m, ld.zbar]) - np.array([vals["m"], vals["zbar_m"]])) / h
    return D @ cov[np.ix_(idx, idx)] @ D.T


def _warn(est: MassEstimate) -> None:
    """Say when the data cannot separate the mass from its height (or cannot give either)."""
    if not (np.isfinite(est.m) and np.isfinite(est.zbar_m)):
        est.warnings.append("the fit diverged: no estimate")
        return
    # m and zbar_m are always strongly correlated (m z_m is what the data fix best); the warning is
    # for when the CIs are too wide to tell a light high load from a heavy low one
    if np.isfinite(est.m_sd) and (est.m_sd > 0.25 * abs(est.m) or est.zbar_m_sd > 0.05):
        est.warnings.append(
            f"the data cannot separate the mass from its height (sd {est.m_sd:.3g} kg, {est.zbar_m_sd * 1000:.0f} mm, "
            f"correlation {est.corr:+.3f}); only the moment m*z_m is determined: record longer or more rudder excitation"
        )
