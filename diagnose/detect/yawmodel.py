"""Yaw-row prior models of seed 000, full (2.17) and simplified (2.18), fitted by output error (ch. 4).

    I_r r' = -M_v v' + A u r + N_r|r| r|r| + N_r|v| r|v| + N_phiu|r| phi u|r|
             + N_|u|v |u| v + N_phi|uv| phi|uv| + N_phiu|u| phi u|u| + tau_r,act          (2.17)
    I_r r' = A u r + N_r|r| r|r| + N_r|v| r|v| + N_|u|v |u| v + tau_r,act                  (2.18)

The predictor simulates ``r`` from the measured u, v, v', phi and tau_r (L1215-1216): everything
but ``r`` is an input. Parameters are scales ``x`` of the nominal values of the digest's section
3.3, so every column of a vectorised simulation can carry its own parameter set (the Jacobian
and the signatures are one call each).

The nominal values (the scale of every parameter) are the lumped yaw parameters (2.19) of the
shared kernel's ``naval-vessel`` profile (:func:`diagnose.yawid.model.true_parameters`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from diagnose.detect.vessel import base_profile
from diagnose.yawid.model import FULL, MODELS, true_parameters
from primitives.errors import UserError


def _prior_name(name: str) -> str:
    """The prior's name of a yawid parameter: N_phiu|r|, N_phiu|u|, N_phi|uv| are N_fur, N_fuu, N_fuv."""
    return name.replace("N_phi", "N_f")


_TRUE = true_parameters(base_profile())
#: (2.19) of the profile, in the order of the full model (2.17)
NOMINAL = {_prior_name(k): _TRUE[k] for k in FULL.params}
PARAMS = {kind: tuple(map(_prior_name, m.params)) for kind, m in MODELS.items()}
DAMPING = ("A", "N_rr", "N_rv", "N_fur", "N_uv", "N_fuu", "N_fuv")
SIGNALS = {"full": ("u", "v", "v_dot", "phi", "tau_r"), "simplified": ("u", "v", "tau_r")}
#: the candidate changes a detector names (BRIEF effect ``inertia_change`` is "yaw_inertia")
CANDIDATES = ("yaw_inertia", "yaw_damping", "pod_gain")


@dataclass
class YawPrior:
    """A fitted yaw row: its structure, parameter values, and what the fit says about its error."""

    kind: str  # "full" (2.17) or "simplified" (2.18)
    values: dict[str, float]
    sigma: float  # robust standard deviation of the fit residual, rad/s
    cov: np.ndarray  # covariance of the relative parameter errors (ln theta), from the fit's Jacobian
    ar: np.ndarray = field(default_factory=lambda: np.zeros(0))  # AR whitening filter of the block-mean fit residual
    sigma_w: float = 0.0  # robust standard deviation of the whitened block-mean fit residual
    block: int = 10  # samples per block mean (1 s at 10 Hz)
    dt: float = 0.1
    source: str = ""

    @property
    def names(self) -> tuple[str, ...]:
        return PARAMS[self.kind]

    def to_dict(self) -> dict:
        return {"format": "shiptrial-yaw-prior/1", "kind": self.kind, "values": self.values, "sigma": self.sigma,
                "cov": self.cov.tolist(), "ar": self.ar.tolist(), "sigma_w": self.sigma_w, "block": self.block,
                "dt": self.dt, "source": self.source}

    @classmethod
    def from_dict(cls, d: dict, where: str = "prior") -> YawPrior:
        try:
            if d.get("format") != "shiptrial-yaw-prior/1":
                raise KeyError("format")
            kind = d["kind"]
            names = PARAMS[kind]
            values = {k: float(d["values"][k]) for k in names}
            cov = np.asarray(d["cov"], float).reshape(len(names), len(names))
            p = cls(kind, values, float(d["sigma"]), cov, np.asarray(d["ar"], float).ravel(), float(d["sigma_w"]),
                    int(d["block"]), float(d["dt"]), str(d.get("source", "")))
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise UserError(f"{where}: not a yaw prior written by 'shiptrial detect-prior' (field {e}); "
                            "make one with: shiptrial detect-prior NOMINAL.csv --out PRIOR.json") from None
        ok = [np.isfinite(list(values.values())).all(), np.isfinite(cov).all(), np.isfinite(p.ar).all(),
              p.sigma > 0, p.sigma_w > 0, p.block >= 1, p.dt > 0, values["I_r"] > 0]
        if not all(ok):
            raise UserError(f"{where}: the prior holds non-finite or non-physical values (I_r, sigma and dt must be > 0); refit it")
        return p


def _theta(kind: str, x: np.ndarray | dict) -> dict[str, np.ndarray]:
    """Parameter values from scales ``x`` (shape (P,) or (P, cols)) or a dict of values."""
    if isinstance(x, dict):
        return {k: np.asarray(x.get(k, 0.0), float) for k in NOMINAL}
    th = {k: np.asarray(0.0) for k in NOMINAL}
    for i, k in enumerate(PARAMS[kind]):
        th[k] = NOMINAL[k] * np.asarray(x[i], float)
    return th


def simulate_r(kind: str, theta: dict | np.ndarray, sig: dict[str, np.ndarray], dt: float, gain=1.0,
               r0: float = 0.0) -> np.ndarray:
    """Yaw rate predicted by (2.17)/(2.18) from the measured signals ``sig``, from ``r0``.

    The explicit Euler step of the shared kernel (``primitives.simulate``, seed 001 (3.60)): the
    prior is the yaw row of the same discrete-time model, so with the profile's parameters and
    the kernel's own v' and tau_r it reproduces the kernel's yaw rate exactly.

    Signals are (n,) or (n, cols); parameter values (and the actuator ``gain``) scalars or (cols,).
    Terms that do not involve ``r`` are summed once, outside the time loop.
    """
    th = _theta(kind, theta)
    u, v = sig["u"], sig["v"]
    au = np.abs(u)
    c0 = th["N_uv"] * au * v + np.asarray(gain) * sig["tau_r"]
    fur = np.zeros_like(u)
    if kind == "full":
        phi = sig["phi"]
        c0 = c0 - th["M_v"] * sig["v_dot"] + th["N_fuv"] * phi * np.abs(u * v) + th["N_fuu"] * phi * u * au
        fur = phi * u
    a_u = th["A"] * u
    c_rv = th["N_rv"] * np.abs(v)
    shape = np.broadcast_shapes(c0.shape, a_u.shape, np.shape(th["I_r"]))
    c0, a_u, c_rv, fur = (np.broadcast_to(z, shape) for z in (c0, a_u, c_rv, fur))
    inv_i = 1.0 / th["I_r"]
    n_rr, n_fur = th["N_rr"], th["N_fur"]

    def f(k: int, r: np.ndarray) -> np.ndarray:
        ar = np.abs(r)
        return (c0[k] + (a_u[k] + c_rv[k]) * r + n_rr * r * ar + n_fur * fur[k] * ar) * inv_i

    r = np.zeros(shape)
    r[0] = r0
    for k in range(shape[0] - 1):
        r[k + 1] = r[k] + dt * f(k, r[k])
    return r


def _jacobian(kind: str, x: np.ndarray, sig: dict[str, np.ndarray], dt: float, step: float = 1e-3, r0: float = 0.0) -> np.ndarray:
    """d r_hat / d x by forward differences, all columns in one vectorised simulation."""
    p = len(x)
    cols = np.repeat(x[:, None], p + 1, axis=1)
    cols[np.arange(p), np.arange(1, p + 1)] += step
    r = simulate_r(kind, cols, {k: s[:, None] for k, s in sig.items()}, dt, r0=r0)
    return (r[:, 1:] - r[:, :1]) / step


def fit(kind: str, sig: dict[str, np.ndarray], r_meas: np.ndarray, dt: float, source: str = "",
        max_iter: int = 30, estimate: bool = True, segments: int = 4, bootstrap: int = 0, seed: int = 0,
        derive=None) -> YawPrior:
    """Output-error fit of (2.17)/(2.18) from the nominal values (ch. 4, L1231-1243: I_r > 0 and the
    damping coefficients negative), with the residual's robust sigma, whitening filter, and the
    parameter covariance in relative (ln theta) units. ``estimate=False`` keeps the nominal values
    (seed 000's "model 0") and only measures the residual on this data.

    The inputs are measured with noise (errors in variables), so the fit's error on a new
    manoeuvre is larger than ``s^2 (J^T J)^-1`` says. The covariance is therefore scaled by how
    much fits to ``segments`` consecutive parts of the same record disagree beyond their own
    covariances (:func:`segment_inflation`; 1 when they agree), or, with ``bootstrap`` > 0,
    replaced by the second moment of that many parametric-bootstrap refits with noise on every
    input (:func:`bootstrap_cov`; ``derive`` recomputes derived inputs, ``seed`` its noise)."""
    r0 = float(np.mean(r_meas[:5]))
    x = _least_squares(kind, sig, r_meas, dt, np.ones(len(PARAMS[kind])), max_iter, r0) if estimate \
        else np.ones(len(PARAMS[kind]))
    e = simulate_r(kind, x, sig, dt, r0=r0) - r_meas
    if not np.all(np.isfinite(x)) or not np.all(np.isfinite(e)):
        raise UserError(f"{source}: the yaw-row fit diverged; the recording does not excite yaw enough for a prior")
    block = max(1, int(round(1.0 / dt)))
    ar = ar_fit(block_mean(e, block))
    sigma_w = robust_sigma(whiten(block_mean(e, block), ar))
    cov = _covariance(kind, sig, dt, x, r0, block, ar, sigma_w)
    if estimate and bootstrap > 0:
        cov = bootstrap_cov(kind, sig, r_meas, dt, x, bootstrap, seed, derive)
    elif estimate and segments > 1:
        cov = cov * segment_inflation(kind, sig, r_meas, dt, x, segments, block, ar, sigma_w)
    values = {k: float(NOMINAL[k] * xi) for k, xi in zip(PARAMS[kind], x)}
    return YawPrior(kind, values, robust_sigma(e), cov, ar, sigma_w, block, dt, source)


def _least_squares(kind: str, sig: dict, r_meas: np.ndarray, dt: float, x0: np.ndarray, max_iter: int,
                   r0: float) -> np.ndarray:
    lo = np.array([-np.inf if k == "M_v" else 1e-3 for k in PARAMS[kind]])
    return least_squares(lambda x: simulate_r(kind, x, sig, dt, r0=r0) - r_meas, x0,
                         jac=lambda x: _jacobian(kind, x, sig, dt, r0=r0), bounds=(lo, np.inf), x_scale=0.1,
                         max_nfev=max_iter).x


def _covariance(kind: str, sig: dict, dt: float, x: np.ndarray, r0: float, block: int, ar: np.ndarray,
                sigma_w: float) -> np.ndarray:
    """``sigma_w^2 (Jw^T Jw)^-1`` of the whitened 1 s block means, ``J = d r_hat / d ln(theta)``."""
    Jw = whiten(block_mean(_jacobian(kind, x, sig, dt, r0=r0) * x[None, :], block), ar)
    return sigma_w**2 * np.linalg.pinv(Jw.T @ Jw)


def segment_inflation(kind: str, sig: dict, r_meas: np.ndarray, dt: float, x: np.ndarray, segments: int,
                      block: int, ar: np.ndarray, sigma_w: float) -> float:
    """Factor (>= 1) by which fits to ``segments`` consecutive parts of one record scatter more than
    their covariances predict: ``sum_i d_i^T C^+ d_i / ((g - 1) P)`` with ``d_i = ln theta_i -
    mean``, ``C`` the mean segment covariance (its expected value is 1 for a correct model)."""
    n = len(r_meas) // segments
    if n < 100 * block:  # segments shorter than 100 s say too little
        return 1.0
    th, covs = [], []
    for i in range(segments):
        sl = slice(i * n, (i + 1) * n)
        s_i = {k: v[sl] for k, v in sig.items()}
        r0 = float(np.mean(r_meas[sl][:5]))
        xi = _least_squares(kind, s_i, r_meas[sl], dt, x, 20, r0)
        th.append((xi - x) / np.abs(x))  # relative, as ln(theta) to first order
        covs.append(_covariance(kind, s_i, dt, xi, r0, block, ar, sigma_w))
    d = np.array(th) - np.mean(th, axis=0)
    c_inv = np.linalg.pinv(np.mean(covs, axis=0))
    k = float(np.einsum("ij,jk,ik->", d, c_inv, d)) / ((segments - 1) * len(x))
    return max(1.0, k)


def white_noise_sd(x: np.ndarray) -> float:
    """Standard deviation of the white measurement noise on a signal that is smooth at its sample
    rate: robust sigma of the second difference / sqrt(6) (the signal's own curvature is far below
    the noise at 10 Hz)."""
    return robust_sigma(np.diff(np.asarray(x, float), 2)) / np.sqrt(6.0)


def bootstrap_cov(kind: str, sig: dict[str, np.ndarray], r_meas: np.ndarray, dt: float, x: np.ndarray, runs: int,
                  seed: int = 0, derive=None, max_iter: int = 15) -> np.ndarray:
    """Second moment of the relative parameter error ``(x_b - x) / |x|`` over ``runs`` parametric-
    bootstrap refits, errors in variables included (the Jacobian covariance of :func:`fit` knows
    only the noise on r).

    Synthetic truth: the measured inputs smoothed (Savitzky-Golay, 2 s, quadratic), ``r`` simulated
    from them with the fitted ``x``. Synthetic data: truth plus white noise of each signal's own
    level estimated from the nominal data (:func:`white_noise_sd`), refitted from ``x``. With
    ``derive(sig_b, r_b) -> sig_b`` derived inputs (v' from v, tau_r from the motion) are recomputed
    from the noisy synthetic signals, as they were from the measured ones. Only nominal data enter."""
    from scipy.signal import savgol_filter

    win = 2 * int(1.0 / dt) + 1
    smooth = {k: savgol_filter(s, win, 2) if len(s) > win else s for k, s in sig.items()}
    sd = {k: white_noise_sd(s) for k, s in sig.items()}
    sd_r = white_noise_sd(r_meas)
    r0 = float(np.mean(r_meas[:5]))
    r_true = simulate_r(kind, x, smooth, dt, r0=r0)
    rng = np.random.default_rng(seed)
    d = []
    for _ in range(runs):
        r_b = r_true + sd_r * rng.standard_normal(len(r_true))
        s_b = {k: smooth[k] + sd[k] * rng.standard_normal(len(r_true)) for k in sig}
        if derive is not None:
            s_b = derive(s_b, r_b)
        xb = _least_squares(kind, s_b, r_b, dt, x, max_iter, float(np.mean(r_b[:5])))
        if np.all(np.isfinite(xb)):
            d.append((xb - x) / np.maximum(np.abs(x), 1e-6))
    if len(d) < max(2, runs // 2):
        raise UserError("the prior's bootstrap refits diverged; the recording does not excite yaw enough for a prior")
    d = np.array(d)
    return d.T @ d / len(d)


def robust_sigma(e: np.ndarray) -> float:
    """1.4826 median absolute deviation."""
    return 1.4826 * float(np.median(np.abs(e - np.median(e))))


def block_mean(x: np.ndarray, block: int) -> np.ndarray:
    """Means of consecutive ``block`` samples along axis 0 (a trailing partial block is dropped).

    The change signatures are slower than 0.5 Hz, so 1 s means keep their information, while the
    noise that the yaw dynamics low-pass (input noise through the model) becomes short-memory
    enough for a low-order AR whitening filter."""
    x = np.asarray(x, float)
    nb = len(x) // block
    return x[: nb * block].reshape(nb, block, *x.shape[1:]).mean(axis=1)


def ar_fit(e: np.ndarray, order: int = 4) -> np.ndarray:
    """AR(order) coefficients ``a`` of ``e_t = sum a_i e_{t-i} + w_t`` by least squares."""
    e = np.asarray(e, float) - np.mean(e)
    X = np.column_stack([e[order - i - 1: len(e) - i - 1] for i in range(order)])
    a, *_ = np.linalg.lstsq(X, e[order:], rcond=None)
    return a


def whiten(x: np.ndarray, ar: np.ndarray) -> np.ndarray:
    """``x_t - sum a_i x_{t-i}`` along axis 0 (the innovation filter of ``ar_fit``); first samples as is."""
    x = np.asarray(x, float)
    out = x.copy()
    for i, a in enumerate(ar, start=1):
        out[i:] -= a * x[:-i]
    return out


def signatures(prior: YawPrior, sig: dict[str, np.ndarray], rel: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """``(S, Sp)``: ``S`` (n, 3) the change of r_hat per unit relative change of each candidate in
    CANDIDATES (yaw inertia, all damping terms together, actuator gain); ``Sp`` (n, P) the same per
    fitted parameter (what the prior's own parameter error does on this manoeuvre)."""
    names = prior.names
    base = np.array([prior.values[k] / NOMINAL[k] for k in names])
    p = len(names)
    cols = np.repeat(base[:, None], p + 3, axis=1)
    cols[:, 1: p + 1] *= 1 + rel * np.eye(p)
    cols[names.index("I_r"), p + 1] *= 1 + rel
    damp = [names.index(k) for k in DAMPING if k in names]
    cols[damp, p + 2] *= 1 + rel
    gain = np.ones(p + 4)
    gain[-1] = 1 + rel
    cols = np.column_stack([cols, base])
    r = simulate_r(prior.kind, cols, {k: s[:, None] for k, s in sig.items()}, prior.dt, gain=gain)
    d = (r - r[:, :1]) / rel
    return d[:, p + 1:], d[:, 1: p + 1]
