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
- Standard errors: the sandwich H^-1 B H^-1 (the form of White 1982), H the Gauss-Newton information (OE)
  or the Fisher information of the innovations (ML, scoring form, the scale profiled out), B the
  Newey-West (1987) long-run covariance of the per-sample scores with Andrews' (1991) automatic lag:
  residuals a mismatched model leaves coloured widen the intervals instead of being assumed white. H is
  the expected information, not the Hessian of -log L, so the result is robust to coloured residuals but
  not White's full misspecification-robust covariance.
- AIC = 2 (-log L) + 2 nu (Akaike 1974; Källström's (3.4)), nu counting the estimated variances.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from identify.steering.kalman import predict
from identify.steering.models import RHO, Structure, discretize, intervals, measurement_variances

LN2PI = float(np.log(2 * np.pi))
LN_BOUND = 12.0
# |atanh rho| of the process noise's correlation: |rho| <= 0.9993 (at 1 the filter's R1 is singular)
RHO_BOUND = 4.0
# A standard error this many times a parameter's typical size (Param.scale) means the records do not
# determine it (a near-singular information matrix inverts to huge but finite variances).
UNDETERMINED = 1e3


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
        prev = np.concatenate([self.delta[:1], self.delta[:-1]])
        self.u = np.column_stack([self.delta, np.ones_like(self.delta), prev])

    @property
    def n_obs(self) -> int:
        return int(np.isfinite(self.y).sum())

    def window(self, i0: int, i1: int) -> SteeringData:
        return SteeringData(self.t[i0:i1], self.delta[i0:i1], self.y[i0:i1], self.channels, self.source)


@dataclass
class Fit:
    """One identified model on one or more records (dynamics and noise shared, biases and initial state per
    record, named ``name@i`` when there are several): estimates, standard errors, likelihood, AIC and the
    prediction and simulation residuals of every record."""

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
    records: list[SteeringData]
    e_pred: list[np.ndarray]  # one-step prediction errors (ML) or simulation errors (OE), (N, ny) per record
    e_sim: list[np.ndarray]  # simulation errors per record
    y_sim: list[np.ndarray]

    @property
    def undetermined(self) -> tuple[str, ...]:
        """The free dynamics, bias and initial-state parameters the records do not determine: no finite,
        positive standard error, or one over :data:`UNDETERMINED` times the parameter's typical size (a noise
        intensity or delay held at its bound has no standard error and is not counted)."""
        qs = {q.name: q for q in self.structure.params}
        out = []
        for k in self.free:
            q = qs[k.split("@")[0]]
            if q.role in ("noise", "delay"):
                continue
            sd = self.std[k]
            if not (np.isfinite(sd) and 0 < sd < UNDETERMINED * q.scale):
                out.append(k)
        return tuple(out)

    @property
    def ok(self) -> bool:
        """Converged, finite likelihood and every dynamics, bias and initial-state parameter determined."""
        return bool(self.converged and np.isfinite(self.neg_log_lik) and not self.undetermined)

    def fit_percent(self, sim: bool = True) -> list[list[float]]:
        """Per record and channel 100 (1 - |e| / |y - mean y|) of the simulation (or prediction) errors."""
        es = self.e_sim if sim else self.e_pred
        return [_fit_percent(e, d.y) for e, d in zip(es, self.records)]


def _record_params(p: dict[str, float], i: int, n: int) -> dict[str, float]:
    if n == 1:
        return dict(p)
    out = {k: v for k, v in p.items() if "@" not in k}
    out.update({k.split("@")[0]: v for k, v in p.items() if k.endswith(f"@{i}")})
    return out


def _fit_percent(e: np.ndarray, y: np.ndarray) -> list[float]:
    out = []
    for c in range(y.shape[1]):
        ok = np.isfinite(e[:, c])
        yc = y[ok, c]
        out.append(float(100 * (1 - np.linalg.norm(e[ok, c]) / max(np.linalg.norm(yc - yc.mean()), 1e-300))))
    return out


def run(structure: Structure, data: SteeringData, p: dict[str, float], ml: bool):
    """(e, s, yhat) of the predictor (``ml``) or the simulation for parameter values ``p``."""
    A, B, C, D, x0, Qc = structure.system(p)
    Phi, Gam, Qd = discretize(A, B, Qc if ml else np.zeros_like(Qc), data.h, float(np.clip(p.get("T_D", 0.0), 0.0, data.h.min())))
    R = measurement_variances(structure, p)
    D3 = np.column_stack([D, np.zeros(len(D))])
    return predict(Phi, Gam, Qd, data.idx, data.u, data.y, C, D3, R, x0, np.zeros_like(A), ml)


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
    """Free parameters in scaled units (value / typical size) -> residual vectors and likelihoods over records."""

    def __init__(self, structure: Structure, records: list[SteeringData], p0: dict[str, float], free: tuple[str, ...], ml: bool):
        self.st, self.records, self.base, self.free, self.ml = structure, records, dict(p0), free, ml
        sc = {q.name: q.scale for q in structure.params}
        self.scale = np.array([sc[k.split("@")[0]] for k in free])
        self.weights = np.ones(len(records[0].channels))
        self.ok = [np.isfinite(d.y) for d in records]

    def params(self, z: np.ndarray) -> dict[str, float]:
        p = dict(self.base)
        p.update(zip(self.free, (np.asarray(z) * self.scale).tolist()))
        return p

    def z0(self) -> np.ndarray:
        return np.array([self.base[k] for k in self.free]) / self.scale

    def evaluate(self, z: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        p = self.params(z)
        n = len(self.records)
        with np.errstate(all="ignore"):
            return [run(self.st, d, _record_params(p, i, n), self.ml) for i, d in enumerate(self.records)]

    def stacked(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured-sample errors and variances of every record, (n_obs, ny) with NaN where not measured."""
        out = self.evaluate(z)
        return np.concatenate([o[0] for o in out]), np.concatenate([o[1] for o in out])

    def residuals(self, z: np.ndarray) -> np.ndarray:
        e, s = self.stacked(z)
        ok = np.concatenate(self.ok)
        if self.ml:
            ss = s[ok]
            if not np.all(np.isfinite(ss)) or np.any(ss <= 0):
                return np.full(ok.sum(), 1e6)
            r = e[ok] / np.sqrt(ss) * np.exp(0.5 * np.mean(np.log(ss)))
        else:
            r = (e * self.weights)[ok]
        return np.where(np.isfinite(r), r, 1e6)

    def neg_log_lik(self, z: np.ndarray) -> float:
        e, s = self.stacked(z)
        return ml_neg_log_lik(e, s) if self.ml else oe_neg_log_lik(e)


def _bounds(free: tuple[str, ...], scale: np.ndarray, h_min: float) -> tuple[np.ndarray, np.ndarray]:
    """ln-variances within e^+-LN_BOUND of their references (beyond, the filter degenerates: a rate measured
    exactly against unbounded process noise); the delay within [0, shortest interval] (Källström's
    T_D = T (1 - |sin theta_34|) bounds it the same way); the process noise's correlation within +-tanh(RHO_BOUND)."""
    b = {"T_D": (0.0, h_min), RHO: (-RHO_BOUND, RHO_BOUND)}
    lo = np.array([-LN_BOUND if k.startswith("ln_") else b.get(k, (-np.inf, np.inf))[0] for k in free])
    hi = np.array([LN_BOUND if k.startswith("ln_") else b.get(k, (-np.inf, np.inf))[1] for k in free])
    return lo / scale, hi / scale


def _obs_times(prob: _Problem) -> np.ndarray:
    """For each measured value in stacked order (time-major), the index of its sample over all records."""
    rows, off = [], 0
    for ok in prob.ok:
        rows.append(np.nonzero(ok)[0] + off)
        off += ok.shape[0]
    return np.concatenate(rows)


def _ml_information(prob: _Problem, z: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fisher information of the innovations likelihood with the scale profiled out (scoring form, first
    derivatives by central differences): sum_k de_k' de_k / (lambda s_k) + 1/2 [sum g g' - (sum g)(sum g)'/N_m],
    g_k = d log s_k / d theta; and each measured value's score eps_k de_k/sqrt(lambda s_k) + (1 - eps_k^2) g_k / 2."""
    e0, s0 = prob.stacked(z)
    ok = np.concatenate(prob.ok)
    lam = np.mean(e0[ok] ** 2 / s0[ok])
    de, dg = [], []
    for i in keep:
        h = 1e-5 * max(1.0, abs(z[i]))
        zp, zm = z.copy(), z.copy()
        zp[i] += h
        zm[i] -= h
        ep, sp = prob.stacked(zp)
        em, sm = prob.stacked(zm)
        de.append(((ep - em)[ok] / (2 * h)) / np.sqrt(lam * s0[ok]))
        dg.append((np.log(sp[ok]) - np.log(sm[ok])) / (2 * h))
    J, G = np.array(de).T, np.array(dg).T
    gs = G.sum(axis=0)
    eps = e0[ok] / np.sqrt(lam * s0[ok])
    scores = eps[:, None] * J + 0.5 * (1.0 - eps[:, None] ** 2) * (G - gs / ok.sum())
    return J.T @ J + 0.5 * (G.T @ G - np.outer(gs, gs) / ok.sum()), scores


def andrews_lag(S: np.ndarray) -> int:
    """Andrews (1991) automatic Bartlett bandwidth from AR(1) fits to each score series, eq. (6.4):
    alpha(1) = sum 4 rho^2 sigma^4 / ((1 - rho)^6 (1 + rho)^2) / sum sigma^4 / (1 - rho)^4,
    lag = 1.1447 (alpha(1) n)^(1/3). A lag set by the residuals' own correlation, not by the sample count:
    1 s samples of a ship whose time constant is 80 s need a lag of tens of samples, not floor(4 (n/100)^(2/9))."""
    n = len(S)
    a, b = S[1:], S[:-1]
    den = np.einsum("ij,ij->j", b, b)
    rho = np.clip(np.einsum("ij,ij->j", a, b) / np.where(den > 0, den, 1.0), -0.97, 0.97)
    sig2 = np.mean((a - rho * b) ** 2, axis=0)
    num = np.sum(4 * rho**2 * sig2**2 / ((1 - rho) ** 6 * (1 + rho) ** 2))
    d = np.sum(sig2**2 / (1 - rho) ** 4)
    alpha = num / d if d > 0 else 0.0
    return int(min(n - 1, np.floor(1.1447 * (alpha * n) ** (1.0 / 3.0))))


def _hac(scores: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Newey and West (1987): the long-run covariance of the per-sample scores (Bartlett weights, the lag of
    :func:`andrews_lag`), so that residuals a mismatched model leaves correlated widen the interval."""
    n_t = int(times.max()) + 1
    S = np.zeros((n_t, scores.shape[1]))
    np.add.at(S, times, scores)
    S = S[np.any(S != 0, axis=1)]
    lag = andrews_lag(S)
    B = S.T @ S
    for k in range(1, lag + 1):
        G = S[k:].T @ S[:-k]
        B += (1 - k / (lag + 1)) * (G + G.T)
    return B


def _covariance(prob: _Problem, z: np.ndarray, jac: np.ndarray, at_bound: np.ndarray) -> np.ndarray:
    """Sandwich covariance H^-1 B H^-1 of the free parameters (White 1982's form with the information for his
    Hessian, and the Newey-West long-run B of the scores); a noise intensity or delay at its bound is held
    there and gets no variance (NaN) instead of making H singular."""
    n = len(z)
    keep = np.flatnonzero(~at_bound)
    if prob.ml:
        H, scores = _ml_information(prob, z, keep)
    else:
        Jk = jac[:, keep]
        H = Jk.T @ Jk
        scores = prob.residuals(z)[:, None] * Jk
    out = np.full((n, n), np.nan)
    try:
        if not np.all(np.isfinite(H)) or not np.all(np.isfinite(scores)) or np.linalg.eigvalsh(H).min() <= 0:
            return out
        Hi = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return out
    cov_z = Hi @ _hac(scores, _obs_times(prob)) @ Hi
    out[np.ix_(keep, keep)] = cov_z * np.outer(prob.scale[keep], prob.scale[keep])
    return out


def free_names(structure: Structure, n_records: int, estimator: str, fixed: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The estimated parameters: dynamics and noise shared, biases, wind and initial state per record (``name@i``)."""
    out = []
    for q in structure.params:
        if q.name in fixed or (estimator != "ml" and q.role == "noise"):
            continue
        if n_records > 1 and q.role in ("bias", "initial", "wind"):  # the wind's direction differs by record
            out += [f"{q.name}@{i}" for i in range(n_records)]
        else:
            out.append(q.name)
    return tuple(out)


@threadpool_limits.wrap(limits=1)
@np.errstate(all="ignore")  # a trial step into overflow is rejected by the optimiser
def fit(
    structure: Structure,
    data: SteeringData | list[SteeringData],
    start: dict[str, float],
    estimator: str = "ml",
    fixed: tuple[str, ...] = (),
    max_nfev: int = 300,
) -> Fit:
    """Fit ``structure`` to one record or several (pooled) by output error (``"oe"``) or maximum likelihood
    (``"ml"``) from ``start`` (every parameter; a per-record ``name@i`` falls back to ``name``); the names in
    ``fixed`` and, for OE, the noise parameters are held. BLAS runs single-threaded here: the optimiser's
    SVDs of a tall, thin Jacobian are about 40 times slower on several threads of a shared machine."""
    records = [data] if isinstance(data, SteeringData) else list(data)
    ml = estimator == "ml"
    free = free_names(structure, len(records), estimator, fixed)
    p0 = dict(start)
    for k in free:
        p0.setdefault(k, start.get(k.split("@")[0], 0.0))
    prob = _Problem(structure, records, p0, free, ml)
    z = prob.z0()
    lo, hi = _bounds(free, prob.scale, min(float(d.h.min()) for d in records))
    z = np.clip(z, lo, hi)
    res = None
    for _ in range(1 if ml else 3):
        if not ml:
            e, _ = prob.stacked(z)
            rms = np.sqrt(np.nanmean(e**2, axis=0))
            prob.weights = 1.0 / np.where(np.isfinite(rms) & (rms > 0), rms, 1.0)
        res = least_squares(prob.residuals, z, bounds=(lo, hi), x_scale=1.0, max_nfev=max_nfev, method="trf")
        z = res.x
    p = prob.params(z)
    outs = prob.evaluate(z)
    sims = [run(structure, d, _record_params(p, i, len(records)), False) for i, d in enumerate(records)]
    nll = prob.neg_log_lik(z)
    # a noise intensity at a bound is negligible (or degenerate) for this record: the likelihood is flat in
    # it, so it is held and gets no variance
    at_bound = np.array([k.startswith("ln_") for k in free]) & (np.abs(z * prob.scale) >= LN_BOUND - 0.1)
    at_bound |= np.array([k in ("T_D", RHO) for k in free]) & ((z <= lo + 1e-4) | (z >= hi - 1e-4))
    # a correlation with a negligible process noise (at its lower bound) has nothing to correlate: flat likelihood
    nil = np.array([k.startswith("ln_q") for k in free]) & (z * prob.scale <= -LN_BOUND + 0.1)
    at_bound |= np.array([k == RHO for k in free]) & bool(nil.any())
    cov = _covariance(prob, z, res.jac, at_bound)
    std = {k: float(np.sqrt(cov[i, i])) if np.isfinite(cov[i, i]) and cov[i, i] > 0 else float("nan") for i, k in enumerate(free)}
    nu = len(free) + (1 if ml else len(records[0].channels))
    return Fit(
        structure,
        estimator,
        p,
        free,
        std,
        cov,
        nll,
        nu,
        2 * nll + 2 * nu,
        sum(d.n_obs for d in records),
        bool(res.status > 0 and np.isfinite(nll)),
        str(res.message),
        records,
        [o[0] for o in outs],
        [o[0] for o in sims],
        [o[2] for o in sims],
    )
