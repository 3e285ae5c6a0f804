"""Output error and maximum likelihood for the steering structures (Källström 1977, section 3).

- Output error (OE): the model simulated from the rudder alone (Kalman gain zero), each channel's
  residual variance concentrated out: -log L = sum_c N_c/2 (log(SSE_c / N_c) + 1 + log 2 pi).
  Minimised by weighted least squares whose weights are re-estimated (three passes).
- Maximum likelihood (ML) in innovations form: a Kalman predictor with time-varying gain on the
  exactly sampled model (any sampling, missing measurements skipped), innovations e_k with variances
  lambda s_k. One variance is fixed (the heading's, R_REF) because R1, R2 and P0 scaled together
  give the same gain (Källström's remark on identifiability); the common scale lambda is
  concentrated out: -log L = N_m/2 (log lambda + 1 + log 2 pi) + 1/2 sum log s_k, lambda = mean(e^2/s).
  Minimised as the sum of squares of rho_k = g e_k / sqrt(s_k), g = exp(mean(log s)/2), a monotone
  transform of -log L (so least squares finds the ML estimate).
- Standard errors: OE from the Gauss-Newton Jacobian (white residuals assumed); ML from the Fisher
  information of the innovations (scoring form, the scale profiled out) at the estimate.
- AIC = 2 (-log L) + 2 nu (Akaike 1974; Källström's (3.4)), nu counting the estimated variances.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from identify.steering.kalman import predict
from identify.steering.models import Structure, discretize, intervals, measurement_variances

LN2PI = float(np.log(2 * np.pi))


@dataclass
class SteeringData:
    """One record: times t [s] (increasing, any spacing), rudder delta [rad] held between samples, measured
    channels y (N, ny) in the order of ``channels`` (v [m/s], r [rad/s], psi [rad]; NaN = not measured)."""

    t: np.ndarray
    delta: np.ndarray
    y: np.ndarray
    channels: tuple[str, ...]
    source: str = ""

    def __post_init__(self) -> None:
        self.h, self.idx = intervals(self.t)
        self.u = np.column_stack([self.delta, np.ones_like(self.delta)])

    @property
    def n_obs(self) -> int:
        return int(np.isfinite(self.y).sum())

    def window(self, i0: int, i1: int) -> SteeringData:
        return SteeringData(self.t[i0:i1], self.delta[i0:i1], self.y[i0:i1], self.channels, self.source)


@dataclass
class Fit:
    """One identified model: estimates, standard errors, likelihood, AIC and both residual sets."""

    structure: Structure
    estimator: str
    p: dict[str, float]
    free: tuple[str, ...]
    std: dict[str, float]
    cov: np.ndarray
    neg_log_lik: float
    nu: int
    aic: float
    n_obs: int
    converged: bool
    message: str
    e_pred: np.ndarray  # one-step prediction errors (ML) or simulation errors (OE), (N, ny)
    e_sim: np.ndarray  # simulation errors (N, ny)
    y_sim: np.ndarray
    s_pred: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def ok(self) -> bool:
        """Converged, finite likelihood and finite, positive standard errors for every free parameter."""
        return (
            self.converged
            and np.isfinite(self.neg_log_lik)
            and all(np.isfinite(self.std[k]) and self.std[k] > 0 for k in self.free if self.structure_role(k) != "noise")
        )

    def structure_role(self, name: str) -> str:
        return next(q.role for q in self.structure.params if q.name == name)

    def fit_percent(self, sim: bool = True) -> dict[str, float]:
        """Per channel 100 (1 - |e| / |y - mean y|) of the simulation (or prediction) errors."""
        return _fit_percent(self.e_sim if sim else self.e_pred, self._y)

    _y: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _fit_percent(e: np.ndarray, y: np.ndarray) -> dict[str, float]:
    out = []
    for c in range(y.shape[1]):
        ok = np.isfinite(e[:, c])
        yc = y[ok, c]
        out.append(float(100 * (1 - np.linalg.norm(e[ok, c]) / max(np.linalg.norm(yc - yc.mean()), 1e-300))))
    return out


def run(structure: Structure, data: SteeringData, p: dict[str, float], ml: bool):
    """(e, s, yhat) of the predictor (``ml``) or the simulation for parameter values ``p``."""
    A, B, C, D, x0, Qc = structure.system(p)
    Phi, Gam, Qd = discretize(A, B, Qc if ml else np.zeros_like(Qc), data.h)
    R = measurement_variances(structure, p)
    return predict(Phi, Gam, Qd, data.idx, data.u, data.y, C, D, R, x0, np.zeros_like(A), ml)


def oe_neg_log_lik(e: np.ndarray) -> float:
    """-log L of output error with each channel's variance concentrated out."""
    total = 0.0
    for c in range(e.shape[1]):
        ec = e[np.isfinite(e[:, c]), c]
        if len(ec) == 0:
            continue
        total += 0.5 * len(ec) * (np.log(np.mean(ec**2)) + 1 + LN2PI)
    return float(total)


def ml_neg_log_lik(e: np.ndarray, s: np.ndarray) -> float:
    """-log L of the innovations with the common scale concentrated out."""
    ok = np.isfinite(e)
    if np.any(s[ok] <= 0):
        return float("inf")
    lam = np.mean(e[ok] ** 2 / s[ok])
    return float(0.5 * ok.sum() * (np.log(lam) + 1 + LN2PI) + 0.5 * np.sum(np.log(s[ok])))


class _Problem:
    """Free parameters in scaled units (value / typical size) -> residual vectors and likelihoods."""

    def __init__(self, structure: Structure, data: SteeringData, p0: dict[str, float], free: tuple[str, ...], ml: bool):
        self.st, self.data, self.base, self.free, self.ml = structure, data, dict(p0), free, ml
        sc = {q.name: q.scale for q in structure.params}
        self.scale = np.array([sc[k] for k in free])
        self.weights = np.ones(len(data.channels))

    def params(self, z: np.ndarray) -> dict[str, float]:
        p = dict(self.base)
        p.update(zip(self.free, (np.asarray(z) * self.scale).tolist()))
        return p

    def z0(self) -> np.ndarray:
        return np.array([self.base[k] for k in self.free]) / self.scale

    def evaluate(self, z: np.ndarray):
        with np.errstate(all="ignore"):
            return run(self.st, self.data, self.params(z), self.ml)

    def residuals(self, z: np.ndarray) -> np.ndarray:
        e, s, _ = self.evaluate(z)
        ok = np.isfinite(self.data.y)
        if self.ml:
            ss = s[ok]
            if not np.all(np.isfinite(ss)) or np.any(ss <= 0):
                return np.full(ok.sum(), 1e6)
            r = e[ok] / np.sqrt(ss) * np.exp(0.5 * np.mean(np.log(ss)))
        else:
            r = (e * self.weights)[ok]
        return np.where(np.isfinite(r), r, 1e6)

    def neg_log_lik(self, z: np.ndarray) -> float:
        e, s, _ = self.evaluate(z)
        return ml_neg_log_lik(e, s) if self.ml else oe_neg_log_lik(e)


def _bounds(free: tuple[str, ...], scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo = np.array([-30.0 if k.startswith("ln_") else -np.inf for k in free])
    hi = np.array([30.0 if k.startswith("ln_") else np.inf for k in free])
    return lo / scale, hi / scale


def _fisher(prob: _Problem, z: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Fisher information of the innovations likelihood with the scale profiled out (scoring form, first
    derivatives only, by central differences):  sum_k de_k' de_k / (lambda s_k) + 1/2 [sum g g' - (sum g)(sum g)'/N_m],
    g_k = d log s_k / d theta. Better conditioned than a finite-difference Hessian of -log L."""
    e0, s0, _ = prob.evaluate(z)
    ok = np.isfinite(prob.data.y)
    lam = np.mean(e0[ok] ** 2 / s0[ok])
    de, dg = [], []
    for i in keep:
        h = 1e-5 * max(1.0, abs(z[i]))
        zp, zm = z.copy(), z.copy()
        zp[i] += h
        zm[i] -= h
        ep, sp, _ = prob.evaluate(zp)
        em, sm, _ = prob.evaluate(zm)
        de.append(((ep - em)[ok] / (2 * h)) / np.sqrt(lam * s0[ok]))
        dg.append((np.log(sp[ok]) - np.log(sm[ok])) / (2 * h))
    J, G = np.array(de).T, np.array(dg).T
    gs = G.sum(axis=0)
    return J.T @ J + 0.5 * (G.T @ G - np.outer(gs, gs) / ok.sum())


def _covariance(prob: _Problem, z: np.ndarray, jac: np.ndarray, at_bound: np.ndarray) -> np.ndarray:
    """Covariance of the free parameters; a noise intensity driven to its bound (a variance that is zero
    for this record) is held there and gets no variance (NaN) instead of making the Hessian singular."""
    n = len(z)
    keep = np.flatnonzero(~at_bound)
    if prob.ml:
        H = _fisher(prob, z, keep)
    else:
        H = (jac.T @ jac)[np.ix_(keep, keep)]
    out = np.full((n, n), np.nan)
    try:
        w = np.linalg.eigvalsh(H)
        if not np.all(np.isfinite(H)) or w.min() <= 1e-12 * max(w.max(), 1e-300):
            return out
        cov_z = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return out
    out[np.ix_(keep, keep)] = cov_z * np.outer(prob.scale[keep], prob.scale[keep])
    return out


def fit(
    structure: Structure,
    data: SteeringData,
    start: dict[str, float],
    estimator: str = "ml",
    fixed: tuple[str, ...] = (),
    max_nfev: int = 400,
) -> Fit:
    """Fit ``structure`` to ``data`` by output error (``"oe"``) or maximum likelihood (``"ml"``) from ``start``
    (every parameter of the structure; the names in ``fixed`` and, for OE, the noise parameters are held)."""
    ml = estimator == "ml"
    roles = {q.name: q.role for q in structure.params}
    free = tuple(k for k in structure.names if k not in fixed and (ml or roles[k] != "noise"))
    prob = _Problem(structure, data, start, free, ml)
    z = prob.z0()
    lo, hi = _bounds(free, prob.scale)
    z = np.clip(z, lo, hi)
    res = None
    passes = 1 if ml else 3
    for _ in range(passes):
        if not ml:
            e, _, _ = prob.evaluate(z)
            rms = np.sqrt(np.nanmean(e**2, axis=0))
            prob.weights = 1.0 / np.where(np.isfinite(rms) & (rms > 0), rms, 1.0)
        res = least_squares(prob.residuals, z, bounds=(lo, hi), x_scale=1.0, max_nfev=max_nfev, method="trf")
        z = res.x
    p = prob.params(z)
    e, s, _ = prob.evaluate(z)
    e_sim, _, y_sim = run(structure, data, p, False)
    nll = prob.neg_log_lik(z)
    # a noise intensity below e^-15 of its reference (or at a bound) is negligible for this record: the
    # likelihood is flat in it, so it is held and gets no variance
    at_bound = np.array([k.startswith("ln_") for k in free]) & ((z * prob.scale <= -15.0) | (z >= hi - 1e-6))
    cov = _covariance(prob, z, res.jac, at_bound)
    std = {k: float(np.sqrt(cov[i, i])) if np.isfinite(cov[i, i]) and cov[i, i] > 0 else float("nan") for i, k in enumerate(free)}
    nu = len(free) + (1 if ml else len(data.channels))
    f = Fit(
        structure,
        estimator,
        p,
        free,
        std,
        cov,
        nll,
        nu,
        2 * nll + 2 * nu,
        data.n_obs,
        bool(res.status > 0 and np.isfinite(nll)),
        str(res.message),
        e,
        e_sim,
        y_sim,
        s,
    )
    f._y = data.y
    return f
