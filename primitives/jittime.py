"""The simulation kernel's time loop compiled with numba (:mod:`primitives.jitloop` loads it): the
loop of :func:`primitives.simulate._time_loop` (and of the diagnosis's open-loop simulator) over
every step and batch member in machine code.

The model is the kernel's: nu(k+1) = nu(k) + Phi(k)^T theta + w(k) (seed 001 (3.60), (9.1)) with the
regressor terms read as a term program (:mod:`primitives.jitprogram`, evaluated by
:mod:`primitives.jitfactors`), the signals of :func:`primitives.velocitystep.relative_signals`, pod
forces (Gierusz 2015 / seed 000 (2.9)-(2.12), :mod:`primitives.pods`), the rigid-body increments
Ts M^-1 (F - C_RB nu) (seed 000 (2.13), :mod:`primitives.rigidbody`), an earth-fixed current turned
with the heading (Fossen 2021, section 10.3) and the Euler kinematics
eta(k+1) = eta(k) + Ts R(psi(k)) nu(k). Import it through :mod:`primitives.jitloop` (its
``time_loop`` and ``open_loop``).
"""

from __future__ import annotations

import math

import numpy as np

from primitives import jitfactors, jitloop
from primitives.jitloop import compiled, inlined
from primitives.jitprogram import CALM_STATE, N_STATE, pod_arrays, program, rigid_arrays


def open_loop(
    step,
    names: list[str],
    exo: dict[str, np.ndarray],
    nu0: np.ndarray,
    cur_body: tuple | None,
    wind_body: tuple | None,
    forced: np.ndarray | None,
) -> np.ndarray | None:
    """nu (B, N+1, 3) of ``step`` (a :class:`primitives.velocitystep.VelocityStep` without rigid body)
    stepped N times from nu0 (B, 3), the loop of a caller that supplies every signal itself: the
    exogenous signals ``exo[name]`` (N, B) (the heading among them when a term reads it), the
    current and air velocity already in body axes (each a pair of (N, B) arrays, or None) and
    increments ``forced`` (N, B, 3) added before the model's, as ``step(nu, exo_k, cur_k, wind_k,
    forced_k)`` would step after step; an exogenous signal may be (N, 1), the same for every
    member (when all are, it is stored once per step for the whole batch). None when the compiled
    loop does not apply."""
    n_work = nu0.shape[0] * (forced.shape[0] if forced is not None else next(iter(exo.values())).shape[0])
    if not jitloop.use(n_work) or step.rigid is not None or nu0.shape[-1] != 3:
        return None
    prog = program(step.terms, names, CALM_STATE)
    if prog is None:
        return None
    batch, n_steps = nu0.shape[0], (forced.shape[0] if forced is not None else next(iter(exo.values())).shape[0])
    in_t = np.empty((n_steps, len(names), batch if any(exo[n].shape[1] > 1 for n in names) else 1))
    for i, n in enumerate(names):
        in_t[:, i] = exo[n]
    nu_t = np.empty((n_steps + 1, 3, batch))
    nu_t[0] = nu0.T
    env = [np.zeros((0, 2, batch)) if e is None else np.ascontiguousarray(np.stack(e, axis=1)) for e in (cur_body, wind_body)]
    w_t = np.zeros((0, 3, batch)) if forced is None else np.ascontiguousarray(forced.transpose(0, 2, 1))
    time_loop(
        in_t,
        nu_t,
        np.zeros((1, 3, batch)),
        env[0],
        env[1],
        w_t,
        step.coef_array,
        *prog,
        *pod_arrays(None, {}),
        *rigid_arrays(None),
        0.0,
        False,
        False,
        False,
        step.wind_excess,
        step.speed,
        True,
        True,
    )
    return nu_t.transpose(2, 0, 1)


@inlined
def _pod_forces(sig, b, u, v, r, p, pod_pos, pod_sig, pc):
    """tau_x, tau_y, tau_k, tau_n of the pods (seed 000 (2.9)-(2.12), primitives.pods) into ``sig``."""
    d4, d, c_mx1, c_mx2, c_my1, c_my2, qc, c_rx1, c_rx2, c_ry, full = (
        pc[0],
        pc[1],
        pc[2],
        pc[3],
        pc[4],
        pc[5],
        pc[6],
        pc[7],
        pc[8],
        pc[9],
        pc[10],
    )
    tx = ty = tk = tn = 0.0
    for i in range(pod_pos.shape[0]):
        px, py, pz = pod_pos[i, 0], pod_pos[i, 1], pod_pos[i, 2]
        n, delta = sig[pod_sig[i, 0], b], sig[pod_sig[i, 1], b]
        u_p = u - py * r
        v_p = v + px * r - pz * p
        u_tot = math.hypot(u_p, v_p)
        sigma = math.atan2(v_p, u_p)
        dr = delta - sigma
        fx_m = d4 * (c_mx1 * math.cos(dr) * (n * n) + c_mx2 * n * d * u_tot)
        fy_m = d4 * math.sin(dr) * (c_my1 * (n * n) + c_my2 * n * d * u_tot)
        q = qc * (u_tot * u_tot)
        fx = fx_m + q * (c_rx1 * math.cos(2 * dr) + c_rx2)
        fy = fy_m + q * c_ry * math.sin(2 * dr)
        c, s = math.cos(sigma), math.sin(sigma)
        bx, by = fx * c - fy * s, fx * s + fy * c
        tx = tx + bx
        ty = ty + by
        tk = tk - pz * by
        tn = tn + px * by - (py * bx if full else 0.0)
    sig[14, b], sig[15, b], sig[16, b], sig[17, b] = tx, ty, tk, tn


@inlined
def _state_signals(
    sig, cub, cvb, k, nu_t, eta_t, in_t, cur_t, wind_t, pod_pos, pod_sig, pod_coef, heading, wind_excess, speed, env_body
):
    """The signals of step k per member into ``sig`` (primitives.velocitystep.relative_signals and
    primitives.velocitystep.add_state_forces): inputs, u, v, r, psi (p, phi), pod forces, the velocities relative to the
    water and the air, U, the wind signals; the current in body axes into ``cub``, ``cvb``."""
    nd, batch, n_in, in_b = nu_t.shape[1], nu_t.shape[2], in_t.shape[1], in_t.shape[2]
    has_cur, has_wind = cur_t.shape[0] > 0, wind_t.shape[0] > 0
    for b in range(batch):
        u, v, r = nu_t[k, 0, b], nu_t[k, 1, b], nu_t[k, 2, b]
        p = nu_t[k, 3, b] if nd == 4 else 0.0
        psi = eta_t[k, 2, b] if heading else math.nan
        ib = b if in_b > 1 else 0
        for i in range(n_in):
            sig[N_STATE + i, b] = in_t[k, i, ib]
        sig[0, b], sig[1, b], sig[2, b], sig[11, b], sig[12, b] = u, v, r, psi, p
        sig[13, b] = eta_t[k, 3, b] if nd == 4 else 0.0
        if pod_pos.shape[0] > 0:
            _pod_forces(sig, b, u, v, r, p, pod_pos, pod_sig, pod_coef)
        cu = cv = 0.0
        if has_cur:
            if env_body:
                cu, cv = cur_t[k, 0, b], cur_t[k, 1, b]
            else:  # primitives.velocitystep.body_from_ne
                c, s = math.cos(psi), math.sin(psi)
                cn, ce = cur_t[k, 0, b], cur_t[k, 1, b]
                cu, cv = c * cn + s * ce, -s * cn + c * ce
        cub[b], cvb[b] = cu, cv
        ur, vr = (u - cu, v - cv) if has_cur else (u, v)
        sig[3, b], sig[4, b] = ur, vr
        if speed:
            h = math.hypot(ur, vr)
            sig[7, b] = 1e-9 if h < 1e-9 else h  # primitives.velocitystep.MIN_SPEED; NaN stays NaN as in np.maximum
        if has_wind:
            if env_body:
                wu, wv = wind_t[k, 0, b], wind_t[k, 1, b]
            else:
                c, s = math.cos(psi), math.sin(psi)
                wn_, we_ = wind_t[k, 0, b], wind_t[k, 1, b]
                wu, wv = c * wn_ + s * we_, -s * wn_ + c * we_
            uq, vq = u - wu, v - wv
            sig[5, b], sig[6, b] = uq, vq
            if wind_excess:
                vq_abs, v_abs = math.hypot(uq, vq), math.hypot(u, v)
                sig[8, b], sig[9, b], sig[10, b] = vq_abs * uq - v_abs * u, vq_abs * vq - v_abs * v, uq * vq - u * v
        else:
            sig[5, b], sig[6, b] = u, v
            sig[8, b] = sig[9, b] = sig[10, b] = 0.0


@inlined
def _advance(k, nu_t, eta_t, inc, n_inc, w_t, cur_t, cub, cvb, minv, rb, ts, heading, positions, turning, forced_first):
    """nu(k+1) and eta(k+1) of every member from the increments ``inc`` (primitives.simulate._time_loop,
    RigidBody.increments, _turn_current, _advance_pose: the same operations in the same order).
    One call per step, the loop over the batch inside: an inlined call still passes each array
    argument through the reference counter, which per member costs more than the arithmetic."""
    nd = nu_t.shape[1]
    for b in range(nu_t.shape[2]):
        cu, cv = cub[b], cvb[b]
        u, v, r = nu_t[k, 0, b], nu_t[k, 1, b], nu_t[k, 2, b]
        p = nu_t[k, 3, b] if nd == 4 else 0.0
        psi = eta_t[k, 2, b] if heading else math.nan
        phi = eta_t[k, 3, b] if nd == 4 else 0.0
        if minv.shape[0] > 0:  # Ts M^-1 (F - C_RB nu)
            m, xg, zg = rb[0], rb[1], rb[2]
            f0 = ts * (inc[0, b] + m * (v * r - zg * p * r + xg * r * r))
            f1 = ts * (inc[1, b] + -m * u * r)
            f2 = ts * (inc[2, b] + -m * xg * u * r)
            f3 = ts * (inc[3, b] + m * zg * u * r)
            for i in range(4):
                inc[i, b] = f0 * minv[i, 0] + f1 * minv[i, 1] + f2 * minv[i, 2] + f3 * minv[i, 3]
        has_w = w_t.shape[0] > 0
        for i in range(nd):
            x = nu_t[k, i, b]
            if forced_first and has_w:
                x = x + w_t[k, i, b]
            if i < n_inc:
                x = x + inc[i, b]
            if has_w and not forced_first:
                x = x + w_t[k, i, b]
            nu_t[k + 1, i, b] = x
        if turning and cur_t.shape[0] > 0:  # u_c(psi(k+1)) - u_c(psi(k))
            psi1 = psi + ts * (r if nd == 3 else math.cos(phi) * r)
            c1, s1 = math.cos(psi1), math.sin(psi1)
            cn, ce = cur_t[k, 0, b], cur_t[k, 1, b]
            nu_t[k + 1, 0, b] += (c1 * cn + s1 * ce) - cu
            nu_t[k + 1, 1, b] += (-s1 * cn + c1 * ce) - cv
        if heading:
            x0, y0 = eta_t[k, 0, b], eta_t[k, 1, b]
            if nd == 4:
                cphi = math.cos(phi)
                if positions:
                    c, s = math.cos(psi), math.sin(psi)
                    eta_t[k + 1, 0, b] = x0 + ts * (c * u - s * cphi * v)
                    eta_t[k + 1, 1, b] = y0 + ts * (s * u + c * cphi * v)
                eta_t[k + 1, 2, b] = psi + ts * cphi * r
                eta_t[k + 1, 3, b] = phi + ts * p
            else:
                if positions:
                    c, s = math.cos(psi), math.sin(psi)
                    eta_t[k + 1, 0, b] = x0 + ts * (c * u - s * v)
                    eta_t[k + 1, 1, b] = y0 + ts * (s * u + c * v)
                eta_t[k + 1, 2, b] = psi + ts * r


@compiled
def time_loop(
    in_t,
    nu_t,
    eta_t,
    cur_t,
    wind_t,
    w_t,
    coef,
    dof_first,
    dof_n,
    t_first,
    t_n,
    f_sig,
    f_mod,
    f_sta,
    f_pow,
    pod_pos,
    pod_sig,
    pod_coef,
    minv,
    rb,
    ts,
    heading,
    positions,
    turning,
    wind_excess,
    speed,
    env_body,
    forced_first,
):
    """nu_t, eta_t (N+1, nd, B), row 0 set, filled in place step by step.

    ``in_t`` (N, S, 1 or B) exogenous signals; ``cur_t``, ``wind_t`` (N, 2, B) over ground in the
    n-frame, rotated by the simulated heading (or, with ``env_body``, already in body axes), empty
    for still water / calm air; ``w_t`` (N, nd, B) increments added after the model's (before it
    with ``forced_first``: the diagnosis's input-only increments), empty for none; ``coef`` (p, 1
    or B); the term program (:func:`program`); pods (:func:`pod_arrays`), rigid body
    (:func:`rigid_arrays`); ``wind_excess``, ``speed``: the wind and speed signals are read;
    ``heading``: the pose is integrated (psi read from ``eta_t``), ``positions``: x, y too;
    ``turning``: the earth-fixed current also turns with the heading."""
    n_steps, batch = nu_t.shape[0] - 1, nu_t.shape[2]
    n_sig = N_STATE + in_t.shape[1]
    row, d_sig, d_mod, d_sta, d_pow = jitfactors._factor_table(n_sig, f_sig, f_mod, f_sta, f_pow)
    sig = np.zeros((n_sig + d_sig.shape[0], batch))
    inc = np.zeros((4, batch))
    tmp = np.empty(batch)
    cub, cvb = np.zeros(batch), np.zeros(batch)
    shared_from = N_STATE if in_t.shape[2] == 1 else n_sig  # one input column: every member reads the same inputs
    n_inc = 4 if minv.shape[0] > 0 else dof_first.shape[0]
    cf = np.empty((coef.shape[0], batch))  # every member's coefficients (one column shared: copied to all)
    for t in range(coef.shape[0]):
        for b in range(batch):
            cf[t, b] = coef[t, b] if coef.shape[1] > 1 else coef[t, 0]
    for k in range(n_steps):
        _state_signals(
            sig, cub, cvb, k, nu_t, eta_t, in_t, cur_t, wind_t, pod_pos, pod_sig, pod_coef, heading, wind_excess, speed, env_body
        )
        jitfactors._derived_rows(sig, n_sig, d_sig, d_mod, d_sta, d_pow, batch, shared_from)
        jitfactors._table_increments(inc, tmp, sig, cf, batch, dof_first, dof_n, t_first, t_n, row)
        _advance(k, nu_t, eta_t, inc, n_inc, w_t, cur_t, cub, cvb, minv, rb, ts, heading, positions, turning, forced_first)
