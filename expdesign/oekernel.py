"""The output-error estimator's compiled path (numba, when :mod:`primitives.jitloop` has it loaded):
the candidate simulations, their mean squared errors and the Gauss-Newton moments, on outputs kept
time-major (N+1, 3, runs) from one pass to the next. The moments are one pass over the samples (the
runs are the inner loop of every stage), replacing the numpy path's four array stages (state
Jacobian, regressors, sensitivity recursion, sums) of :func:`expdesign.oerefine._gauss_newton_moments_numpy`.

Per run and step k of the noise-free simulated trajectory nu(k): the regressors Phi(k) (Ljungberg
(2022) (9.2)), the state Jacobian d inc / d nu by forward differences with the step 1e-7 (1 + |nu|) from
the trajectory's own increment nu(k+1) - nu(k), the output sensitivities
S(k+1) = (I + d inc/d nu) S(k) + Phi(k) in single precision, and the sums
H += S(k+1)^T W S(k+1), g += S(k+1)^T W (y(k+1) - nu(k+1)) in double precision. The operations on
each number are the numpy path's (the same factors in the same order, the same float32 roundings of
the Jacobian and of S), so S is the numpy path's to the bit (but where a term reads the speed U or a
power outside :data:`primitives.powers.PRODUCT_POWERS`: the C library's hypot and pow against numpy's,
a last-bit difference, see :mod:`primitives.jitloop`); the order of the sums over the samples differs (numpy's einsum pairs and vectorises them), which moves H and g by rounding (measured
up to 3e-13 relative for H, 1.4e-11 of the largest entry for g, near the optimum where g cancels;
tests/test_oekernel.py checks 1e-9 against the numpy path).

Applies to planar models without pods, rigid body or heading terms, simulated in calm water (the
output-error model); otherwise :func:`calm_runs` returns None and the numpy path runs. The
simulations and mean squares are the numpy path's bits (the operations of the compiled time loop
of :func:`primitives.simulate.simulate` in calm water, in :func:`_calm_loop`; sums over the samples
in their order, added as the loop makes each step).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from primitives import jitloop
from primitives.jitprogram import _IDX
from primitives.simulate import MIN_SPEED, SPEED, signals_read, time_major_forces

_N_STATE = jitloop.N_STATE
_HELPERS: list[str] = []  # compiled inline into the pass on first use (see _compile_helpers)


@dataclass
class CalmRuns:
    """A batch's experiments laid out once for the compiled output-error path (:func:`calm_runs`):
    per experiment the input signals (N, S, 1 or B), the measured velocities time-major
    (N+1, 3, B), the start states (B, 3) and the term program; the simulated outputs it passes
    from :func:`simulate` (which scores them as it makes them) to :func:`moments_t` stay time-major
    (N+1, 3, b), the layout of the time loop and of the moments' pass, so no output is
    transposed, copied or given a pose array."""

    terms: object
    in_t: list[np.ndarray]
    y_t: list[np.ndarray]
    nu0: list[np.ndarray]
    prog: list[tuple]
    speed: bool
    reads: list[np.ndarray]


def calm_runs(profile, terms, data: Sequence) -> CalmRuns | None:
    """The batch ``data`` laid out for the compiled path, or None where the numpy path runs (no
    compiler loaded or worth loading, pods, roll, rigid body, a signal the programs lack). The
    simulation (:func:`simulate`) gives the bits of :func:`primitives.simulate.simulate`'s
    compiled loop in calm water without a pose."""
    work = sum(d.y.shape[0] * d.inputs.shape[1] for d in data)
    if profile.pods or profile.n_dof != 3 or terms.n_dof != 3 or profile.rigid_body is not None or not jitloop.use(work):
        return None
    _compile_helpers()
    in_t, progs = [], []
    for d in data:
        names, forces = time_major_forces(profile, d.inputs)
        prog = jitloop.program(terms, names, jitloop.CALM_STATE)
        if prog is None:
            return None
        in_t.append(forces)
        progs.append(prog)
    return CalmRuns(
        terms,
        in_t,
        [np.ascontiguousarray(d.y.transpose(1, 2, 0), float) for d in data],
        [np.asarray(d.nu0, float) for d in data],
        progs,
        SPEED in signals_read(terms),
        [_reads_state(prog, terms.n_params) for prog in progs],
    )


def simulate(cr: CalmRuns, theta: np.ndarray, idx: np.ndarray, limit: float) -> tuple[list[np.ndarray], np.ndarray]:
    """Noise-free outputs nu (N+1, 3, len(idx)) per experiment of the runs ``idx`` with their
    ``theta`` rows, and their :func:`expdesign.oerefine._mean_squares` (b, 3) (inf for a run
    with an output not below ``limit`` in magnitude, NaN too). The simulation is :func:`_calm_loop`,
    the operations of the compiled loop of :func:`primitives.simulate._compiled_loop` for
    ``simulate(..., positions=False)`` in calm water (the same bits), the runs' inputs read
    through their indices; the squared errors are summed as each step is made, sample after sample
    per run and DOF (numpy's reduction's order, so the same bits), no second pass over the outputs."""
    b = len(idx)
    coef = np.ascontiguousarray(theta[idx].T)
    runs = np.asarray(idx, np.int64)
    n = sum(y.shape[0] - 1 for y in cr.y_t)
    out, sums, bad = [], [], np.zeros(b, np.bool_)
    for in_t, y, nu0, prog in zip(cr.in_t, cr.y_t, cr.nu0, cr.prog):
        nu_t, s = run_scored(in_t, y, nu0[idx], runs, coef, prog, cr.speed, 1, limit, bad)
        out.append(nu_t)
        sums.append(s)
    ms = np.zeros((b, 3))
    good = np.flatnonzero(~bad)
    for s in sums:
        ms[good] += s[good]
    ms[good] /= n
    ms[bad] = np.inf
    return out, ms


def run_scored(
    in_t: np.ndarray,
    y: np.ndarray,
    nu0: np.ndarray,
    runs: np.ndarray,
    coef: np.ndarray,
    prog: tuple,
    speed: bool,
    first: int,
    limit: float,
    bad: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """One experiment's :func:`_calm_loop` from the start states ``nu0`` (b, 3), batch member b
    driven by the inputs of run ``runs[b]`` of ``in_t`` and measured by ``y`` (N+1, 3, B)
    time-major: the outputs nu (N+1, 3, b) and the sums (b, 3) over the samples k = first..N of
    (y[k, i, runs[b]] - nu[k, i, b])^2, added sample after sample; ``bad`` (b,) set where some
    |nu| is not below ``limit`` (NaN too)."""
    b = len(runs)
    nu_t = np.empty((in_t.shape[0] + 1, 3, b))
    nu_t[0] = nu0.T
    sq = np.zeros((3, b))
    if b:
        _calm_loop(in_t, nu_t, runs, coef, *prog, speed, y, first, limit, sq, bad)
    return nu_t, sq.T


@jitloop.compiled
def _calm_loop(
    in_t, nu_t, runs, coef, dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_sta, f_pow, speed, y, first, limit, sq, bad
):
    """nu_t (N+1, 3, B), row 0 set, stepped nu(k+1) = nu(k) + Phi(k)^T theta in calm water, batch
    member b driven by the inputs of run ``runs[b]`` of ``in_t`` (N, S, 1 or R): the signals of
    :func:`_signals` and primitives.jitloop's increments and sums in their order, i.e.
    primitives.jitloop.time_loop without current, wind, pose or forcing and none of its per-member
    branches for them (2.3 times faster on the Monte Carlo's candidate simulations, same bits);
    each row scored as it is made (:func:`run_scored`)."""
    n, batch = in_t.shape[0], nu_t.shape[2]
    sig = np.zeros((_N_STATE + in_t.shape[1], batch))  # the wind-excess signals stay 0: calm air
    inc = np.zeros((3, batch))
    tmp = np.empty(batch)
    _score_row(nu_t, y, runs, 0, first, limit, sq, bad, batch)
    for k in range(n):
        _signals(sig, nu_t[k], in_t, runs, k, speed)
        jitloop._increments(inc, tmp, sig, coef, batch, dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_sta, f_pow)
        for i in range(3):
            for b in range(batch):
                nu_t[k + 1, i, b] = nu_t[k, i, b] + inc[i, b]
        _score_row(nu_t, y, runs, k + 1, first, limit, sq, bad, batch)


def moments_t(cr: CalmRuns, sims: list[np.ndarray], theta: np.ndarray, idx: np.ndarray, w: np.ndarray, fd_step: float):
    """(hess (b, p, p), grad (b, p)) of the runs ``idx`` from their time-major outputs ``sims``
    (N+1, 3, b), as :func:`expdesign.oerefine._gauss_newton_moments_numpy` computes them but for
    the order of the sums (module doc)."""
    p, b = theta.shape[1], len(idx)
    hess, grad = np.zeros((b, p, p)), np.zeros((b, p))
    coef = np.ascontiguousarray(theta[idx].T)
    sw = np.ascontiguousarray(np.sqrt(w[idx]).T)
    runs, mask = np.asarray(idx, np.int64), _mask(cr.terms, p)  # the same for every experiment
    for in_t, y, nu_t, prog, reads in zip(cr.in_t, cr.y_t, sims, cr.prog, cr.reads):
        _accumulate(in_t, nu_t, y, runs, coef, sw, mask, reads, ~reads.all(axis=0), *prog, cr.speed, fd_step, hess, grad)
    return hess, grad


# the signals of the calm-water layout (set by _state_signals) that move with u, v and r: in calm
# water u_r = u_q = u and v_r = v_q = v, U = hypot(u, v); r also moves a factor with a station,
# x + station * r. Looked up by name so that a change of primitives.jitprogram's layout cannot
# silently reuse a term that moves.
_MOVED_BY = tuple(tuple(_IDX[n] for n in names) for names in (("u", "u_r", "u_q", "U"), ("v", "v_r", "v_q", "U"), ("r",)))


def _reads_state(prog: tuple, p: int) -> np.ndarray:
    """(3, p) bool: whether term t of the program ``prog`` reads a signal that moves with state
    u, v or r (:data:`_MOVED_BY`); a term that does not has the same value at nu(k) + h e_col
    as at nu(k)."""
    t_first, t_n, f_sig, f_sta = prog[2], prog[3], prog[4], prog[6]
    reads = np.zeros((3, p), np.bool_)
    for t in range(p):
        for f in range(t_first[t], t_first[t] + t_n[t]):
            for col, moved in enumerate(_MOVED_BY):
                reads[col, t] |= int(f_sig[f]) in moved or (col == 2 and not np.isnan(f_sta[f]))
    return reads


def _mask(terms, p: int) -> np.ndarray:
    mask = np.zeros((3, p), np.float32)
    for i in range(3):
        mask[i, terms.dof_slice(i)] = 1.0
    return mask


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
def _score_row(nu_t, y, runs, k, first, limit, sq, bad, batch):
    """Row k of the outputs checked against ``limit`` and, from sample ``first`` on, its squared
    errors added to ``sq`` (3, B) (:func:`run_scored`)."""
    for i in range(3):
        for b in range(batch):
            x = nu_t[k, i, b]
            if not abs(x) < limit:
                bad[b] = True
            if k >= first:
                e = y[k, i, runs[b]] - x
                sq[i, b] = e * e if k == first else sq[i, b] + e * e


@_helper
def _signals(sig, x, in_t, runs, k, speed):
    """The calm-water signals of the states x (3, B) at step k (primitives.velocitystep.relative_signals,
    in the signal layout of primitives.jitloop), the inputs of batch member b those of run runs[b]."""
    batch, one = x.shape[1], in_t.shape[2] == 1
    for i in range(in_t.shape[1]):
        for b in range(batch):
            sig[_N_STATE + i, b] = in_t[k, i, 0 if one else runs[b]]
    _state_signals(sig, x, speed, batch)


@_helper
def _state_signals(sig, x, speed, batch):
    """The state rows of :func:`_signals` (u, v, r, the relative velocities in calm water and,
    where read, the speed U) of the states x (3, B); the input rows are left as they are."""
    for b in range(batch):
        u, v = x[0, b], x[1, b]
        sig[0, b], sig[1, b], sig[2, b], sig[3, b], sig[4, b], sig[5, b], sig[6, b] = u, v, x[2, b], u, v, u, v
    if speed:
        for b in range(batch):
            h = math.hypot(x[0, b], x[1, b])
            sig[7, b] = MIN_SPEED if h < MIN_SPEED else h


@jitloop.compiled
def _accumulate(
    in_t,
    nu_t,
    y,
    runs,
    coef,
    sw,
    mask,
    reads,
    reused,
    dof_first,
    dof_n,
    t_first,
    t_n,
    f_sig,
    f_mod,
    f_sta,
    f_pow,
    speed,
    fd_step,
    hess,
    grad,
):
    """Add each run's H and g over one experiment to ``hess`` (b, p, p), ``grad`` (b, p), batch member b
    reading the inputs and measurements of run ``runs[b]`` of ``in_t``, ``y``; the runs
    are the inner loop of every stage (the term program's branches once per step). ``reads``
    (3, p) says which terms read a signal of state u, v, r (:func:`_reads_state`), ``reused``
    (p,) which terms some perturbation leaves alone."""
    n, batch, p = in_t.shape[0], nu_t.shape[2], coef.shape[0]
    one = in_t.shape[2] == 1
    tv = np.empty((p, batch))
    sig = np.zeros((_N_STATE + in_t.shape[1], batch))
    phi = np.empty((p, batch), np.float32)
    tmp = np.empty(batch)
    inc = np.empty((4, batch))
    s_old = np.zeros((3, p, batch), np.float32)
    s_new = np.empty((3, p, batch), np.float32)
    jac = np.empty((3, 3, batch), np.float32)
    sk = np.empty((3, p, batch))
    e = np.empty((3, batch))
    x = np.empty((3, batch))
    h = np.empty(batch)
    hl = np.zeros((p, p, batch))
    gl = np.zeros((p, batch))
    for k in range(n):
        for i in range(in_t.shape[1]):  # the inputs at step k, read once for the four evaluations
            for b in range(batch):
                sig[_N_STATE + i, b] = in_t[k, i, 0 if one else runs[b]]
        # col -2: the terms' values c_t * f_1 * f_2 ... at nu(k) (those some perturbation leaves
        # alone); col -1: the regressors Phi(k) at nu(k); col 0-2: the increments at nu(k) + h e_col,
        # the terms summed left to right per DOF as jitloop._increments does, a term that reads no
        # signal of state col taken from col -2 (the same operations on the same numbers, so the same
        # bits). One call site of each inlined helper: less machine code to compile on first use.
        for col in range(-2, 3):
            if col != -1:  # col -1 reads col -2's signals
                x[:] = nu_t[k]
                if col >= 0:
                    for b in range(batch):
                        h[b] = fd_step * (1.0 + abs(x[col, b]))
                        x[col, b] = x[col, b] + h[b]
                _state_signals(sig, x, speed, batch)
            for i in range(3):
                if col >= 0 and dof_n[i] == 0:
                    inc[i, :] = 0.0
                for t in range(dof_first[i], dof_first[i] + dof_n[i]):
                    if col == -2 and not reused[t]:
                        continue
                    if col >= 0 and not reads[col, t]:
                        for b in range(batch):
                            tmp[b] = tv[t, b]
                    else:
                        for b in range(batch):
                            tmp[b] = 1.0 if col == -1 else coef[t, b]
                        for f in range(t_first[t], t_first[t] + t_n[t]):
                            jitloop._times_factor(tmp, sig, f_sig[f], f_sta[f], f_mod[f], f_pow[f], batch)
                    if col == -2:
                        for b in range(batch):
                            tv[t, b] = tmp[b]
                    elif col == -1:
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
        # S(k+1) and its weighted double-precision copy in one pass (no second read of S)
        for i in range(3):
            for q in range(p):
                mq = mask[i, q]
                for b in range(batch):
                    v = phi[q, b] * mq + s_old[i, q, b]
                    v = v + jac[0, i, b] * s_old[0, q, b]
                    v = v + jac[1, i, b] * s_old[1, q, b]
                    v = v + jac[2, i, b] * s_old[2, q, b]
                    s_new[i, q, b] = v
                    sk[i, q, b] = np.float64(v) * sw[i, b]
            for b in range(batch):
                e[i, b] = (y[k + 1, i, runs[b]] - nu_t[k + 1, i, b]) * sw[i, b]
        # the three DOFs' products added one after the other to each sum (the order of adding them
        # DOF by DOF, so the same roundings), each sum read and written once a step, not three times
        for a in range(p):
            for q in range(a, p):
                for b in range(batch):
                    v = hl[a, q, b] + sk[0, a, b] * sk[0, q, b]
                    v = v + sk[1, a, b] * sk[1, q, b]
                    hl[a, q, b] = v + sk[2, a, b] * sk[2, q, b]
            for b in range(batch):
                v = gl[a, b] + sk[0, a, b] * e[0, b]
                v = v + sk[1, a, b] * e[1, b]
                gl[a, b] = v + sk[2, a, b] * e[2, b]
        s_old, s_new = s_new, s_old  # S(k+1) is the next step's S(k): no copy
    for b in range(batch):
        for a in range(p):
            grad[b, a] += gl[a, b]
            for q in range(p):
                hess[b, a, q] += hl[a, q, b] if q >= a else hl[q, a, b]
