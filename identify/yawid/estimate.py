"""Output-error estimation of the yaw models (the podded-ship MSc thesis, section 4.1, eq. 4.1-4.4).

The predictor is a simulation of (2.17)/(2.18) driven by the measured inputs (L1215-1216):
``r_hat(k+1) = r_hat(k) + Ts f(r_hat(k), w(k); theta)`` with ``f = (sum_j theta_j phi_j + tau_r) / I_r``
(explicit Euler at the sample time, the kernel's own step). ``theta_hat`` minimises
``V_N = mean (r - r_hat)^2`` (4.2) by Levenberg-Marquardt, with the Jacobian from forward
sensitivities ``S = d r_hat / d theta`` propagated along the same simulation, for a whole batch of
recordings at once. Constraints (section 4.3): I_r > 0 and the damping coefficients <= 0, kept by
projecting each step. Start: the given initial values (the thesis starts at the true values).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identify.yawid import yawloop
from identify.yawid.experiment import YawData
from identify.yawid.model import INPUT_TERMS, NEGATIVE, STATE_TERMS, YawModel
from primitives.zerophase import filtfilt, lowpass


@dataclass
class YawFit:
    """Estimates of one model on a batch of B recordings; a run that did not converge or went
    non-finite is flagged, never averaged (``ok``)."""

    model: YawModel
    theta: np.ndarray  # (B, p) physical units, order model.params
    converged: np.ndarray  # (B,) bool
    finite: np.ndarray  # (B,) bool
    iterations: int
    rms: np.ndarray  # (B,) residual RMS, rad/s
    fit_percent: np.ndarray  # (B,) 100 (1 - |r - r_hat| / |r - mean r|)
    notes: tuple[str, ...] = ()  # the recording reader's (a last row cut short and left out)

    @property
    def ok(self) -> np.ndarray:
        return self.converged & self.finite

    def estimate(self, i: int = 0) -> dict[str, float]:
        return dict(zip(self.model.params, self.theta[i].tolist()))


def _as_batch(data: YawData, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    return {k: np.atleast_2d(np.asarray(data.signals[k], float)) for k in names}


def simulate_yaw(
    model: YawModel,
    theta: np.ndarray,
    w: dict[str, np.ndarray],
    r0: np.ndarray,
    ts: float,
    sensitivities: bool = True,
    extra: dict[str, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Predicted yaw rate (B, N) of (2.17)/(2.18) and its sensitivities (B, N, p) to theta (B, p)
    (None with ``sensitivities=False``), from the measured inputs ``w`` (B, N) and ``r0`` (B,).

    The one yaw-row simulator of the project: the change detector's prior
    (``identify.detect.yawmodel.simulate_r``) is this function on its column layout. Without
    sensitivities it needs memory of the order of the inputs only (a detector's 400 no-change
    records of a long recording); compiled when numba is there and the batch is large, else for
    float64 inputs numpy's loop without per-term calls (:mod:`identify.yawid.yawloop`: the compiled one this loop's
    bits, the numpy one to rounding). ``extra`` per signal, each of its ``w`` signal's (B, N) shape (broadcast views
    are fine), is added to ``w``'s: by blocks inside numpy's loop (:func:`identify.yawid.yawloop.simulate_numpy`), else
    before the simulation (:func:`identify.yawid.yawloop.added`; the same bits either way). The loop is chosen as for the
    sums: ``w`` all float64 (so are the sums), else they are formed first and the loops' own dtype checks decide."""
    doubles = all(np.asarray(x).dtype == np.float64 for x in w.values())
    if extra and (sensitivities or not doubles or not yawloop.stepped(model, w) or yawloop.usable(model, w, *w["u"].shape)):
        w, extra = yawloop.added(w, extra), None
    b, n = w["u"].shape
    p = len(model.params)
    col = {name: j for j, name in enumerate(model.params)}
    theta = np.ascontiguousarray(theta, dtype=float)  # einsum's summation order follows the memory layout
    i_r = theta[:, col["I_r"]]
    # regressor of every non-I_r parameter at each sample: the input terms' now, the state terms' in the loop
    reg = _input_regressors(model, w, col) if sensitivities else None
    if not sensitivities and yawloop.usable(model, w, b, n):  # the same bits, compiled (identify.yawid.yawloop)
        return yawloop.simulate(model, theta, col, w, r0, ts), None
    if not sensitivities and yawloop.stepped(model, w):  # to rounding, without per-term calls (yawloop), by blocks
        forcing = lambda part: _input_forcing(model, theta, part, col, time_major=False)  # noqa: E731
        return yawloop.simulate_numpy(model, theta, col, forcing, w, r0, ts, extra), None
    forcing = _input_forcing(model, theta, w, col, reg)
    r_hat = np.empty((b, n))
    sens = np.zeros((b, n, p)) if sensitivities else None
    r = np.asarray(r0, float).copy()
    s = np.zeros((b, p))
    state = [(col[name], theta[:, col[name]], *STATE_TERMS[name]) for name in model.state_terms]
    state_signals = [key for key in ("u", "v", "phi") if key in w]
    for k in range(n):
        r_hat[:, k] = r
        wk = {key: w[key][:, k] for key in state_signals}
        force = forcing[:, k].copy()
        dfdr = np.zeros(b) if sensitivities else None
        for j, th, val, der in state:
            v = val(r, wk)
            force += th * v
            if sensitivities:
                reg[:, k, j] = v
                dfdr += th * der(r, wk)
        f = force / i_r
        if sensitivities:
            sens[:, k] = s
            dfdth = reg[:, k] / i_r[:, None]
            dfdth[:, col["I_r"]] = -f / i_r
            s = s + ts * (dfdr[:, None] / i_r[:, None] * s + dfdth)
        r = r + ts * f
    return r_hat, sens


def _input_regressors(model: YawModel, w: dict[str, np.ndarray], col: dict[str, int]) -> np.ndarray:
    """(B, N, p) regressors of the terms of (2.17)/(2.18) that do not involve r; zero elsewhere."""
    b, n = w["u"].shape
    reg = np.zeros((b, n, len(model.params)))
    for name in model.input_terms:
        reg[:, :, col[name]] = INPUT_TERMS[name](w)
    return reg


def _input_forcing(
    model: YawModel,
    theta: np.ndarray,
    w: dict[str, np.ndarray],
    col: dict[str, int],
    reg: np.ndarray | None = None,
    time_major: bool = True,
) -> np.ndarray:
    """The terms of (2.17)/(2.18) that do not involve r, plus tau_r: (B, N), summed once outside the
    time loop: from the input regressors ``reg`` of :func:`_input_regressors` when the caller has them,
    else term by term. B is theta's (B, p): an input of one row (1, N) serves every member, its terms
    formed once (the same numbers as the row repeated). Time-major memory, or member-major (C) without
    ``time_major``."""
    b, n = theta.shape[0], w["u"].shape[-1]
    # time-major: the generic time loop reads one sample of every run at a time
    out = np.empty((n, b)).T if time_major else np.empty((b, n))
    if reg is None:
        # without sensitivities no regressor array is needed: each term straight into the sum (a detector's
        # 400 no-change records of a 500 s recording spent a third of their simulation building that array)
        out[:] = w["tau_r"]
        for name in model.input_terms:
            out += theta[:, col[name], None] * INPUT_TERMS[name](w)
        return out
    out[:] = np.einsum("bnp,bp->bn", reg, theta) + w["tau_r"]
    return out


def _project(x: np.ndarray, model: YawModel) -> np.ndarray:
    """Section 4.3 constraints in the scaled parameters x = theta / |theta0|."""
    x = x.copy()
    for j, name in enumerate(model.params):
        if name == "I_r":
            x[:, j] = np.maximum(x[:, j], 1e-3)
        elif name in NEGATIVE:
            x[:, j] = np.minimum(x[:, j], 0.0)
    return x


def prefilter(w: dict[str, np.ndarray], ts: float, cutoff_hz: float, axis: int = -1) -> dict[str, np.ndarray]:
    """Zero-phase 4th-order Butterworth low-pass of the measured inputs (not of r) along ``axis``
    (time): ours, not the thesis's. The inputs enter the predictor as if exact (errors in
    variables, L1882-1884), so their white noise above the manoeuvre's bandwidth only biases the
    estimates (through |v|, |uv|: E|v + e| > |v|) and adds noise to the prediction. scipy's
    filtfilt, compiled for many rows (:func:`primitives.zerophase.filtfilt`, the same bits); on few
    rows :func:`primitives.iir.filtfilt` (scipy's to rounding; its bits for a low ``cutoff_hz``)."""
    b, a = lowpass(4, cutoff_hz, 1.0 / ts)
    return {k: filtfilt(b, a, v, axis=axis) for k, v in w.items()}


def fit_yaw(
    data: YawData,
    model: YawModel,
    theta0: dict[str, float],
    max_iter: int = 200,
    rtol: float = 1e-9,
    prefilter_hz: float | None = None,
) -> YawFit:
    """Output-error fit of ``model`` to each recording of ``data`` (signals (N,) or (B, N)),
    starting from ``theta0`` (physical values by name); ``prefilter_hz`` low-passes the inputs
    (:func:`prefilter`), None uses them as measured (the thesis's method)."""
    w = _as_batch(data, ("r", "tau_r") + model.signals)
    y = w.pop("r")
    if prefilter_hz:
        w = prefilter(w, data.sample_time, prefilter_hz)
    b = y.shape[0]
    ts = data.sample_time
    scale = np.array([abs(theta0[p]) or 1.0 for p in model.params])
    x = np.tile(np.array([theta0[p] for p in model.params]) / scale, (b, 1))
    r0 = y[:, : max(1, int(round(1.0 / ts)))].mean(axis=1)

    def evaluate(xx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        with np.errstate(all="ignore"):
            r_hat, sens = simulate_yaw(model, xx * scale, w, r0, ts)
            e = y - r_hat
            cost = np.mean(e * e, axis=1)
            sens = sens * scale  # a diverging trial step overflows here too; its cost is inf and it is rejected
        cost = np.where(np.isfinite(cost), cost, np.inf)
        return e, sens, cost

    negative = np.array([p in NEGATIVE for p in model.params])
    e, jac, cost = evaluate(x)
    lam = np.full(b, 1e-3)
    done = ~np.isfinite(cost)
    iterations = 0
    for iterations in range(1, max_iter + 1):  # noqa: B007 - the count is reported
        h = np.einsum("bnp,bnq->bpq", jac, jac)
        g = np.einsum("bnp,bn->bp", jac, e)
        diag = np.einsum("bpp->bp", h)
        a = h + lam[:, None, None] * (np.eye(h.shape[1]) * np.maximum(diag, 1e-12)[:, None, :])
        # active set: a parameter on its bound whose gradient points out of the feasible set stays there
        fixed = (x == 0.0) & negative & (g > 0)
        a = np.where(fixed[:, :, None] | fixed[:, None, :], 0.0, a) + fixed[:, :, None] * np.eye(h.shape[1])
        g = np.where(fixed, 0.0, g)
        with np.errstate(all="ignore"):
            dx = np.linalg.solve(a, g[..., None])[..., 0]
        x_new = _project(x + np.where(done[:, None], 0.0, dx), model)
        e_new, jac_new, cost_new = evaluate(x_new)
        better = (cost_new < cost) & ~done
        rel = np.where(better, (cost - cost_new) / np.maximum(cost, 1e-300), 0.0)
        tiny = better & (np.max(np.abs(x_new - x), axis=1) < 1e-7)  # e.g. sliding along a constraint
        x = np.where(better[:, None], x_new, x)
        e = np.where(better[:, None], e_new, e)
        jac = np.where(better[:, None, None], jac_new, jac)
        stalled = ~better & (lam > 1e8)
        cost = np.where(better, cost_new, cost)
        lam = np.where(better, lam / 3.0, lam * 4.0)
        done |= (better & (rel < rtol)) | tiny | stalled
        if done.all():
            break
    theta = x * scale
    finite = np.isfinite(cost) & np.all(np.isfinite(theta), axis=1)
    rms = np.sqrt(cost)
    spread = np.linalg.norm(y - y.mean(axis=1, keepdims=True), axis=1)
    fit = 100.0 * (1.0 - np.linalg.norm(e, axis=1) / np.maximum(spread, 1e-300))
    return YawFit(model, theta, done & finite, finite, iterations, rms, fit)
