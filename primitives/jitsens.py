"""Forward sensitivities of the open-loop simulation of :mod:`primitives.jitloop` (calm water, no
current, no rigid body), compiled with numba.

For the model nu(k+1) = nu(k) + w(k) + Phi(nu(k), x(k))^T theta (seed 001 (3.60)) the derivative
S(k) = d nu(k) / d p of the simulated state with respect to a parameter p obeys the sensitivity
equations (the variational equations of the recursion, e.g. Ljung 1999, section 10.3)

    S(k+1) = S(k) + A(k) S(k) + G(k),   A(k) = d(Phi^T theta)/d nu at nu(k),

with G(k) the direct derivative of the step's increment: Phi_j(k) in its DOF's row for the
coefficient theta_j (of a state term, read in the loop, or of an input-only term, the increments
``w``), zero for an initial state, whose S(0) is a unit column. Integrated beside the simulated
trajectory, one pass gives every column of the output-error Jacobian that finite differences need
one simulated member each for.

The terms are the kernel's term program (:func:`primitives.jitloop.program`): a term is
c * prod_f |s_f + station_f r|^power_f over the signals of
:func:`primitives.velocitystep.relative_signals`, whose derivatives with respect to (u, v, r) are
taken here by the chain rule: u_r, v_r and u_q, v_q move one to one with u, v; U = hypot(u_r, v_r)
(held at its floor below 1e-9, where its derivative is taken as zero); the wind-excess signals
wx = |V_q| u_q - |V| u, wy = |V_q| v_q - |V| v, wn = u_q v_q - u v; every exogenous signal is fixed.
"""

from __future__ import annotations

import math

import numpy as np

from primitives import jitloop
from primitives.jitloop import N_STATE, compiled

# the signals whose derivative the kernel forms (jitloop's state signals it sets in calm water)
_ROWS = 11  # u, v, r, u_r, v_r, u_q, v_q, U, wx, wy, wn


def available() -> bool:
    """Whether the compiled kernel can run in this process (loading numba when it is not loaded)."""
    return jitloop.use(jitloop.MIN_WORK)


def state_sensitivities(
    nu: np.ndarray,
    inputs: np.ndarray,
    wind: np.ndarray | None,
    coef: np.ndarray,
    prog: tuple[np.ndarray, ...],
    col: np.ndarray,
    pre_val: np.ndarray,
    pre_dof: np.ndarray,
    pre_col: np.ndarray,
    s0: np.ndarray,
) -> np.ndarray:
    """S (N+1, 3, m): d nu(k) / d p for the m parameters p along the trajectory ``nu`` (N+1, 3).

    ``inputs`` (N, n_in) the exogenous signals the program ``prog`` reads (after the state
    signals, :func:`primitives.jitloop.program`); ``wind`` (N, 2) the air velocity in body axes or
    None; ``coef`` (p,) the program's term coefficients, ``col`` (p,) each term's column of S (-1:
    not a parameter); ``pre_val`` (N, q) the input-only terms' values, their DOF ``pre_dof`` and
    column ``pre_col`` (q,); ``s0`` (3, m) S(0)."""
    w = np.zeros((0, 2)) if wind is None else np.ascontiguousarray(wind, float)
    S = np.empty((len(nu), 3, s0.shape[1]))
    S[0] = s0
    _sens_loop(
        np.ascontiguousarray(nu, float),
        np.ascontiguousarray(inputs, float),
        w,
        np.ascontiguousarray(coef, float),
        *prog,
        np.ascontiguousarray(col, np.int64),
        np.ascontiguousarray(pre_val, float),
        np.ascontiguousarray(pre_dof, np.int64),
        np.ascontiguousarray(pre_col, np.int64),
        S,
    )
    return S


@compiled
def _sens_loop(
    nu, inputs, wind, coef, dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_sta, f_pow, col, pre_val, pre_dof, pre_col, S
):
    """S (N+1, 3, m) filled in place from S[0] (:func:`state_sensitivities`)."""
    n_steps, m = nu.shape[0] - 1, S.shape[2]
    n_in = inputs.shape[1]
    sig = np.zeros(N_STATE + n_in)
    dsig = np.zeros((N_STATE + n_in, 3))  # d signal / d (u, v, r); exogenous rows stay zero
    A = np.zeros((3, 3))
    n_fac = 1  # the most factors a term has (the program's terms are not bounded in length)
    for t in range(t_n.shape[0]):
        n_fac = max(n_fac, t_n[t])
    fv = np.zeros(n_fac)
    fg = np.zeros((n_fac, 3))
    grad = np.zeros(3)
    has_wind = wind.shape[0] > 0
    for k in range(n_steps):
        u, v, r = nu[k, 0], nu[k, 1], nu[k, 2]
        for i in range(n_in):
            sig[N_STATE + i] = inputs[k, i]
        for i in range(_ROWS):
            for j in range(3):
                dsig[i, j] = 0.0
        sig[0], sig[1], sig[2], sig[3], sig[4] = u, v, r, u, v
        dsig[0, 0] = dsig[1, 1] = dsig[2, 2] = dsig[3, 0] = dsig[4, 1] = 1.0
        h = math.hypot(u, v)
        sig[7] = 1e-9 if h < 1e-9 else h
        if h >= 1e-9:
            dsig[7, 0], dsig[7, 1] = u / h, v / h
        uq, vq = u, v
        if has_wind:
            uq, vq = u - wind[k, 0], v - wind[k, 1]
        sig[5], sig[6] = uq, vq
        dsig[5, 0] = dsig[6, 1] = 1.0
        q = math.hypot(uq, vq)
        sig[8], sig[9], sig[10] = q * uq - h * u, q * vq - h * v, uq * vq - u * v
        qu = uq / q if q > 0.0 else 0.0
        qv = vq / q if q > 0.0 else 0.0
        hu = u / h if h > 0.0 else 0.0
        hv = v / h if h > 0.0 else 0.0
        dsig[8, 0], dsig[8, 1] = qu * uq + q - hu * u - h, qv * uq - hv * u
        dsig[9, 0], dsig[9, 1] = qu * vq - hu * v, qv * vq + q - hv * v - h
        dsig[10, 0], dsig[10, 1] = vq - v, uq - u
        for i in range(3):
            for j in range(3):
                A[i, j] = 0.0
        for i in range(3):
            for c in range(m):
                S[k + 1, i, c] = S[k, i, c]
        for i in range(dof_first.shape[0]):
            for t in range(dof_first[i], dof_first[i] + dof_n[i]):
                nf = t_n[t]
                for a in range(nf):  # each factor's value and gradient
                    f = t_first[t] + a
                    s = f_sig[f]
                    x = sig[s]
                    gx0, gx1, gx2 = dsig[s, 0], dsig[s, 1], dsig[s, 2]
                    if not math.isnan(f_sta[f]):
                        x = x + f_sta[f] * sig[2]
                        gx2 = gx2 + f_sta[f]
                    if f_mod[f]:
                        sg = 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)
                        x, gx0, gx1, gx2 = abs(x), sg * gx0, sg * gx1, sg * gx2
                    pw = f_pow[f]
                    if pw == 1:
                        val, dv = x, 1.0
                    else:  # -1 * (1 / (x x)) and 2 * x: the bits of -1 / (x x) and 2.0 x
                        val, dv = jitloop.int_power(x, pw), pw * jitloop.int_power(x, pw - 1)
                    fv[a] = val
                    fg[a, 0], fg[a, 1], fg[a, 2] = dv * gx0, dv * gx1, dv * gx2
                phi = 1.0
                grad[0] = grad[1] = grad[2] = 0.0
                for a in range(nf):  # d(prod f)/d nu = sum_a f'_a prod_{b != a} f_b
                    rest = 1.0
                    for b in range(nf):
                        if b != a:
                            rest *= fv[b]
                    for j in range(3):
                        grad[j] += fg[a, j] * rest
                    phi *= fv[a]
                for j in range(3):
                    A[i, j] += coef[t] * grad[j]
                if col[t] >= 0:
                    S[k + 1, i, col[t]] += phi
        for i in range(3):
            for c in range(m):
                S[k + 1, i, c] += A[i, 0] * S[k, 0, c] + A[i, 1] * S[k, 1, c] + A[i, 2] * S[k, 2, c]
        for j in range(pre_dof.shape[0]):
            S[k + 1, pre_dof[j], pre_col[j]] += pre_val[k, j]
