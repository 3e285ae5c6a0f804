"""The time loop shared by output error and maximum likelihood: a Kalman predictor on a sampled
linear model with per-step intervals, scalar sequential measurement updates (R2 is diagonal) and
missing measurements (NaN) skipped, i.e. the innovations form (3.9)/(4.4) of Källström (1977) with a
time-varying gain; with ``update=False`` it is the deterministic simulation of output error
(Kalman gain zero). Compiled with numba when :mod:`primitives.jitloop` says so (numba importable and
loadable, ``SHIPTRIAL_KERNEL`` not ``numpy``); otherwise the same recursion in numpy matrix products
(:func:`_numpy_loop`, about 26 us a step against about 1 us compiled: a 361-sample second-order ML fit
takes about 9 s of CPU instead of 0.7 s).
"""

from __future__ import annotations

import numpy as np

from primitives import jitloop

# A fit runs the loop thousands of times (a Jacobian column per free parameter, per iteration, per start:
# 6,785 calls for a second-order ML fit_model of a 112-sample record): a record's samples times this is
# the work :func:`jitloop.use` weighs against loading the compiler.
CALLS_PER_FIT = 1000


@jitloop.compiled
def _loop(Phi, Gam, Qd, idx, u, y, C, D, R, x0, P0, update):  # pragma: no cover - compiled
    N, ny = y.shape
    n, nu = x0.shape[0], u.shape[1]
    e = np.full((N, ny), np.nan)
    s = np.full((N, ny), np.nan)
    yhat = np.empty((N, ny))
    x = x0.copy()
    P = P0.copy()
    xn = np.empty(n)
    T = np.empty((n, n))
    Ph = np.empty(n)
    for k in range(N):
        if k > 0:
            j = idx[k - 1]
            for i in range(n):
                acc = 0.0
                for m in range(n):
                    acc += Phi[j, i, m] * x[m]
                for m in range(nu):
                    acc += Gam[j, i, m] * u[k - 1, m]
                xn[i] = acc
            x[:] = xn
            if update:  # P = Phi P Phi' + Qd
                for i in range(n):
                    for m in range(n):
                        acc = 0.0
                        for q in range(n):
                            acc += Phi[j, i, q] * P[q, m]
                        T[i, m] = acc
                for i in range(n):
                    for m in range(n):
                        acc = Qd[j, i, m]
                        for q in range(n):
                            acc += T[i, q] * Phi[j, m, q]
                        P[i, m] = acc
        for c in range(ny):
            yh = 0.0
            for i in range(n):
                yh += C[c, i] * x[i]
            for i in range(nu):
                yh += D[c, i] * u[k, i]
            yhat[k, c] = yh
            if np.isnan(y[k, c]):
                continue
            ek = y[k, c] - yh
            e[k, c] = ek
            if not update:
                s[k, c] = 1.0
                continue
            sk = R[c]
            for i in range(n):
                acc = 0.0
                for m in range(n):
                    acc += P[i, m] * C[c, m]
                Ph[i] = acc
                sk += C[c, i] * acc
            s[k, c] = sk
            if sk > 0.0:
                for i in range(n):
                    x[i] += Ph[i] / sk * ek
                for i in range(n):
                    for m in range(n):
                        P[i, m] -= Ph[i] * Ph[m] / sk
    return e, s, yhat


def _numpy_loop(Phi, Gam, Qd, idx, u, y, C, D, R, x0, P0, update):
    """:func:`_loop` without the compiler: the same operations with numpy's small matrix products."""
    N, ny = y.shape
    e = np.full((N, ny), np.nan)
    s = np.full((N, ny), np.nan)
    yhat = np.empty((N, ny))
    x, P = x0.copy(), P0.copy()
    measured = np.isfinite(y).tolist()
    for k in range(N):
        if k > 0:
            j = idx[k - 1]
            x = Phi[j] @ x + Gam[j] @ u[k - 1]
            if update:
                P = Phi[j] @ P @ Phi[j].T + Qd[j]
        if not update:  # no measurement update: every channel predicted from the same state
            yhat[k] = C @ x + D @ u[k]
            e[k] = y[k] - yhat[k]
            s[k, measured[k]] = 1.0
            continue
        for c in range(ny):
            yhat[k, c] = yh = C[c] @ x + D[c] @ u[k]
            if not measured[k][c]:
                continue
            e[k, c] = ek = y[k, c] - yh
            Ph = P @ C[c]
            s[k, c] = sk = R[c] + C[c] @ Ph
            if sk > 0.0:
                x = x + Ph * (ek / sk)
                P = P - np.outer(Ph, Ph) / sk
    return e, s, yhat


def predict(Phi, Gam, Qd, idx, u, y, C, D, R, x0, P0, update: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Innovations e (N, ny), their variances s (N, ny) (NaN where not measured) and the predicted
    outputs (N, ny); ``update=False``: simulation errors, s = 1."""
    f = np.ascontiguousarray
    loop = _loop if jitloop.use(y.shape[0] * CALLS_PER_FIT) else _numpy_loop
    return loop(
        f(Phi),
        f(Gam),
        f(Qd),
        f(idx),
        f(u),
        f(y),
        f(C),
        f(D),
        f(R, dtype=float),
        f(x0, dtype=float),
        f(P0, dtype=float),
        bool(update),
    )
