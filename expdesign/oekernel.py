"""The output-error estimator's Gauss-Newton moments in one compiled pass over the samples (numba,
when :mod:`primitives.jitloop` has it loaded; the runs are the inner loop of every stage), replacing the numpy path's four array stages (state
Jacobian, regressors, sensitivity recursion, sums) of :func:`expdesign.estimators._gauss_newton_moments`.

Per run and step k of the noise-free simulated trajectory nu(k): the regressors Phi(k) (Ljungberg
(2022) (9.2)), the state Jacobian d inc / d nu by forward differences with the step 1e-7 (1 + |nu|) from
the trajectory's own increment nu(k+1) - nu(k), the output sensitivities
S(k+1) = (I + d inc/d nu) S(k) + Phi(k) in single precision, and the sums
H += S(k+1)^T W S(k+1), g += S(k+1)^T W (y(k+1) - nu(k+1)) in double precision. The operations on
each number are the numpy path's (the same factors in the same order, the same float32 roundings of
the Jacobian and of S), so S is the numpy path's to the bit (but where a term reads the speed U or a
power other than 1, 2, -1: the C library's hypot and pow against numpy's, a last-bit difference, see
:mod:`primitives.jitloop`); the order of the sums over the samples differs (numpy's einsum pairs and vectorises them), which moves H and g by rounding (measured
up to 3e-13 relative for H, 1.4e-11 of the largest entry for g, near the optimum where g cancels;
tests/test_oekernel.py checks 1e-9 against the numpy path).

Applies to planar models without pods, rigid body or heading terms, simulated in calm water (the
output-error model); otherwise :func:`moments` returns None and the numpy path runs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from primitives import jitloop
from primitives.simulate import MIN_SPEED, SPEED, _time_major_forces, signals_read

_N_STATE = jitloop.N_STATE
_HELPERS: list[str] = []  # compiled inline into the pass on first use (see _compile_helpers)


def moments(profile, terms, data: Sequence, sims, theta: np.ndarray, idx: np.ndarray, w: np.ndarray, fd_step: float):
    """(hess (b, p, p), grad (b, p)) of the runs ``idx`` as
    :func:`expdesign.estimators._gauss_newton_moments` computes them, or None when the compiled
    pass does not apply (no compiler loaded or worth loading, pods, roll, heading terms)."""
    b, n_work = len(idx), sum(len(idx) * d.inputs.shape[1] for d in data)
    if profile.pods or profile.n_dof != 3 or profile.rigid_body is not None or not jitloop.use(n_work):
        return None
    _compile_helpers()
    p = theta.shape[1]
    hess, grad = np.zeros((b, p, p)), np.zeros((b, p))
    mask = np.zeros((3, p), np.float32)
    for i in range(3):
        mask[i, terms.dof_slice(i)] = 1.0
    coef = np.ascontiguousarray(theta[idx].T)
    sw = np.ascontiguousarray(np.sqrt(w[idx]).T)
    speed = SPEED in signals_read(terms)
    for d, (nu, _) in zip(data, sims):
        names, in_t = _time_major_forces(profile, d.inputs[idx])
        prog = jitloop.program(terms, names, jitloop.CALM_STATE)
        if prog is None:
            return None
        nu_t = np.ascontiguousarray(nu.transpose(1, 2, 0))
        y = np.ascontiguousarray(d.y[idx].transpose(1, 2, 0))
        _accumulate(in_t, nu_t, y, coef, sw, mask, *prog, speed, fd_step, hess, grad)
    return hess, grad


def _helper(fn):
    _HELPERS.append(fn.__name__)
    return fn


def _compile_helpers() -> None:
    """Replace the helpers by numba functions inlined into the pass (as primitives.jitloop does for
    its own): a call per step would pass every array through the reference counter. Done once,
    after :func:`primitives.jitloop.use` has loaded numba (and with it jitloop's inlined helpers
    this pass calls) and before the pass is first compiled."""
    g = globals()
    with jitloop._LOCK:
        from numba import njit

        for n in _HELPERS:
            if not hasattr(g[n], "py_func"):
                g[n] = njit(inline="always", error_model="numpy")(g[n])


@_helper
def _signals(sig, x, in_t, k, speed):
    """The calm-water signals of the states x (3, B) at step k (primitives.simulate.relative_signals,
    in the signal layout of primitives.jitloop)."""
    batch, one = x.shape[1], in_t.shape[2] == 1
    for i in range(in_t.shape[1]):
        for b in range(batch):
            sig[_N_STATE + i, b] = in_t[k, i, 0 if one else b]
    for b in range(batch):
        u, v = x[0, b], x[1, b]
        sig[0, b], sig[1, b], sig[2, b], sig[3, b], sig[4, b], sig[5, b], sig[6, b] = u, v, x[2, b], u, v, u, v
    if speed:
        for b in range(batch):
            h = math.hypot(x[0, b], x[1, b])
            sig[7, b] = MIN_SPEED if h < MIN_SPEED else h


@jitloop.compiled
def _accumulate(
    in_t, nu_t, y, coef, sw, mask, dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_sta, f_pow, speed, fd_step, hess, grad
):
    """Add each run's H and g over one experiment to ``hess`` (B, p, p), ``grad`` (B, p); the runs
    are the inner loop of every stage (the term program's branches once per step)."""
    n, batch, p = in_t.shape[0], nu_t.shape[2], coef.shape[0]
    sig = np.zeros((_N_STATE + in_t.shape[1], batch))
    phi = np.empty((p, batch), np.float32)
    tmp = np.empty(batch)
    inc = np.empty((4, batch))
    s_old = np.zeros((3, p, batch), np.float32)
    s_new = np.empty((3, p, batch), np.float32)
    jac = np.empty((3, 3, batch), np.float32)
    sk = np.empty((p, batch))
    e = np.empty(batch)
    x = np.empty((3, batch))
    h = np.empty(batch)
    hl = np.zeros((p, p, batch))
    gl = np.zeros((p, batch))
    for k in range(n):
        # col -1: the regressors Phi(k) at nu(k); col 0-2: the increments at nu(k) + h e_col, each
        # term c_t * f_1 * f_2 ... summed left to right per DOF as jitloop._increments does. One
        # call site of each inlined helper: less machine code to compile on first use.
        for col in range(-1, 3):
            x[:] = nu_t[k]
            if col >= 0:
                for b in range(batch):
                    h[b] = fd_step * (1.0 + abs(x[col, b]))
                    x[col, b] = x[col, b] + h[b]
            _signals(sig, x, in_t, k, speed)
            for i in range(3):
                if col >= 0 and dof_n[i] == 0:
                    inc[i, :] = 0.0
                for t in range(dof_first[i], dof_first[i] + dof_n[i]):
                    for b in range(batch):
                        tmp[b] = 1.0 if col < 0 else coef[t, b]
                    for f in range(t_first[t], t_first[t] + t_n[t]):
                        jitloop._times_factor(tmp, sig, f_sig[f], f_sta[f], f_mod[f], f_pow[f], batch)
                    if col < 0:
                        for b in range(batch):
                            phi[t, b] = tmp[b]
                    elif t == dof_first[i]:
                        inc[i, :] = tmp
                    else:
                        for b in range(batch):
                            inc[i, b] = inc[i, b] + tmp[b]
                if col >= 0:
                    for b in range(batch):
                        jac[col, i, b] = (inc[i, b] - (nu_t[k + 1, i, b] - nu_t[k, i, b])) / h[b]
        for i in range(3):
            for q in range(p):
                mq = mask[i, q]
                for b in range(batch):
                    v = phi[q, b] * mq + s_old[i, q, b]
                    v = v + jac[0, i, b] * s_old[0, q, b]
                    v = v + jac[1, i, b] * s_old[1, q, b]
                    v = v + jac[2, i, b] * s_old[2, q, b]
                    s_new[i, q, b] = v
        for i in range(3):
            for q in range(p):
                for b in range(batch):
                    sk[q, b] = np.float64(s_new[i, q, b]) * sw[i, b]
            for b in range(batch):
                e[b] = (y[k + 1, i, b] - nu_t[k + 1, i, b]) * sw[i, b]
            for a in range(p):
                for q in range(a, p):
                    for b in range(batch):
                        hl[a, q, b] += sk[a, b] * sk[q, b]
                for b in range(batch):
                    gl[a, b] += sk[a, b] * e[b]
        s_old[:] = s_new
    for b in range(batch):
        for a in range(p):
            grad[b, a] += gl[a, b]
            for q in range(p):
                hess[b, a, q] += hl[a, q, b] if q >= a else hl[q, a, b]
