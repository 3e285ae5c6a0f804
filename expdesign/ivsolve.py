"""The one instrumental-variable solve of the block-diagonal predictor (9.2), shared by
:func:`expdesign.estimators.estimate` and the Monte Carlo (:mod:`expdesign.montecarlo`): the
instrument mean removal (7.19)/(7.20) and the per-DOF systems, each judged before it is solved so
that a singular or ill-conditioned one is a failed estimate (NaN), never a number made of rounding.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from primitives import jitloop, regkernel
from primitives.ship import ShipProfile
from primitives.simulate import MIN_SPEED, SPEED, signals_read
from primitives.terms import TermSet

# A DOF's system fails (NaN) when the mean removal leaves one of its instruments constant to this
# relative precision (only rounding left: such columns in the Monte Carlo are below 4e-15 of their
# norm, its smallest real variation 1e-3), or when its condition number, rows scaled by the
# mean-removed instrument norms and columns by the regressor norms (units do not decide), exceeds
# MAX_CONDITION: eps * cond, the solution's relative error bound, above 2e-4 (the Monte Carlo's
# other systems, model-ship and full-scale, every protocol and mean subtraction, stay below 3e7).
CONSTANT_INSTRUMENT = 1e-10
MAX_CONDITION = 1e12


def remove_instrument_mean(z: np.ndarray, mean_subtraction: str, starts: Sequence[int] = (0,)) -> np.ndarray:
    """Instruments Z (..., N, p) with their mean removed: 'none'; per sub-experiment (7.19),
    'batchwise', the sub-experiments starting at the sample indices ``starts``; over the whole
    experiment (7.20), 'complete'."""
    if mean_subtraction == "complete":
        return z - z.mean(axis=-2, keepdims=True)
    if mean_subtraction == "batchwise":
        blocks = np.split(z, list(starts[1:]), axis=-2)
        return np.concatenate([c - c.mean(axis=-2, keepdims=True) for c in blocks], axis=-2)
    return z


def _solve_checked(a: np.ndarray, rhs: np.ndarray, row_norm: np.ndarray, col_norm: np.ndarray, fail: np.ndarray) -> np.ndarray:
    """x of a x = rhs for each system (a (..., n, n), rhs (..., n)); NaN where ``fail`` (...,) or
    where the system is not finite, singular, or its condition number scaled by ``row_norm`` and
    ``col_norm`` (..., n) exceeds MAX_CONDITION. Each system is solved on its own: the SVDs and
    solves of a stack are LAPACK's calls per matrix, the numbers of one system do not depend on
    the batch (a stack with a system LAPACK rejects is redone one system at a time)."""
    n = a.shape[-1]
    a2, r2 = a.reshape(-1, n, n), rhs.reshape(-1, n)
    x = np.full(r2.shape, np.nan)
    with np.errstate(all="ignore"):
        scaled = a2 / (row_norm.reshape(-1, n, 1) * col_norm.reshape(-1, 1, n))
        todo = np.flatnonzero(~np.reshape(fail, -1) & np.isfinite(scaled).all(axis=(1, 2)) & np.isfinite(a2).all(axis=(1, 2)))
        if not todo.size:
            return x.reshape(rhs.shape)
        try:
            s = np.linalg.svd(scaled[todo], compute_uv=False)
            good = todo[s[:, -1] * MAX_CONDITION >= s[:, 0]]
            x[good] = np.linalg.solve(a2[good], r2[good][..., None])[..., 0]
        except np.linalg.LinAlgError:  # an exact zero pivot (or an SVD that did not converge): one by one
            for k in todo:
                try:
                    s = np.linalg.svd(scaled[k], compute_uv=False)
                    if s[-1] * MAX_CONDITION >= s[0]:
                        x[k] = np.linalg.solve(a2[k], r2[k])
                except np.linalg.LinAlgError:
                    pass
    return x.reshape(rhs.shape)


def _column_norms(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("...ki,...ki->...i", x, x))


def iv_solve(
    terms: TermSet, phi: np.ndarray, z: np.ndarray, tgt: np.ndarray, mean_subtraction: str = "none", starts: Sequence[int] = (0,)
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The block-diagonal IV estimate (2.18) of (9.2): per DOF i,
    theta_i = (sum Z~_i Phi_i^T)^-1 sum Z~_i (y_i(k+1) - y_i(k)), with Z~ the instruments with
    their mean removed (:func:`remove_instrument_mean`; Z = Phi gives least squares).

    phi, z (..., N, p), tgt (..., N, 3), any leading batch axes. A DOF whose system is singular
    or ill-conditioned (see CONSTANT_INSTRUMENT, MAX_CONDITION) gets NaN: a failed estimate to
    report, never a pseudo-inverse's number.
    Returns theta (..., p), Z~ and the DOFs' matrices sum Z~_i Phi_i^T [(..., p_i, p_i)].
    """
    zt = remove_instrument_mean(z, mean_subtraction, starts)
    zt_norm, phi_norm = _column_norms(zt), _column_norms(phi)
    with np.errstate(invalid="ignore"):
        constant = ~(zt_norm > CONSTANT_INSTRUMENT * _column_norms(z)) if mean_subtraction != "none" else zt_norm == 0
    theta = np.empty(phi.shape[:-2] + phi.shape[-1:])
    mats = []
    for i in range(3):
        s = terms.dof_slice(i)
        a = np.einsum("...ki,...kj->...ij", zt[..., s], phi[..., s])  # c_einsum, no BLAS: no thread-count rounding
        rhs = np.einsum("...ki,...k->...i", zt[..., s], tgt[..., i])
        theta[..., s] = _solve_checked(a, rhs, zt_norm[..., s], phi_norm[..., s], constant[..., s].any(axis=-1))
        mats.append(a)
    return theta, zt, mats


def iv_estimates(
    terms: TermSet, phi: np.ndarray, z: np.ndarray, tgt: np.ndarray, mean_subtraction: str = "none", starts: Sequence[int] = (0,)
) -> np.ndarray:
    """theta (B, p) of :func:`iv_solve` for phi, z (B, N, p), tgt (B, N, 3): the moments of each run
    in one compiled pass over its samples when numba is loaded (:mod:`primitives.jitloop`) and the
    mean is removed over the experiment or not at all, :func:`iv_solve` otherwise. The same
    systems, checks and solves, and sums over the samples in their order, one by one (as numpy's
    einsum and mean over that axis did in every Monte Carlo run measured: the same bits for all
    4,000 runs of 2,000 x 2; tests/test_ivsolve.py allows 1e-12, since numpy does not promise
    its order)."""
    if mean_subtraction == "batchwise" or phi.ndim != 3 or not jitloop.loaded():
        return iv_solve(terms, phi, z, tgt, mean_subtraction, starts)[0]
    moments = _moments_pass(
        np.ascontiguousarray(phi),
        np.ascontiguousarray(z),
        np.ascontiguousarray(tgt),
        _dof_of(terms),
        mean_subtraction == "complete",
    )
    return solve_moments(terms, *moments, mean_subtraction)


def _dof_of(terms: TermSet) -> np.ndarray:
    """The DOF of each parameter of a block-diagonal term set (p,)."""
    return np.concatenate([np.full(terms.dof_slice(i).stop - terms.dof_slice(i).start, i) for i in range(3)])


def solve_moments(terms: TermSet, a: np.ndarray, rhs: np.ndarray, norms: np.ndarray, mean_subtraction: str) -> np.ndarray:
    """theta (B, p) from the compiled passes' moments: the systems A (B, p, p), right-hand sides
    (B, p) and squared column norms of Z~, Phi, Z (3, B, p), judged and solved as :func:`iv_solve`
    judges and solves them."""
    zt_norm, phi_norm, z_norm = np.sqrt(norms)
    with np.errstate(invalid="ignore"):
        constant = ~(zt_norm > CONSTANT_INSTRUMENT * z_norm) if mean_subtraction != "none" else zt_norm == 0
    theta = np.empty(rhs.shape)
    for i in range(3):
        s = terms.dof_slice(i)
        theta[:, s] = _solve_checked(a[:, s, s], rhs[:, s], zt_norm[:, s], phi_norm[:, s], constant[:, s].any(axis=-1))
    return theta


@jitloop.inlined
def _blocks(dof):
    """Each parameter's DOF block [lo, hi) of the sorted parameter DOFs ``dof`` (p,)."""
    p = dof.shape[0]
    lo, hi = np.empty(p, np.int64), np.empty(p, np.int64)
    for q in range(p):
        lo[q], hi[q] = q, q + 1
        while lo[q] > 0 and dof[lo[q] - 1] == dof[q]:
            lo[q] -= 1
        while hi[q] < p and dof[hi[q]] == dof[q]:
            hi[q] += 1
    return lo, hi


@jitloop.inlined
def _run_moments(z, phi_b, tgt_b, dof, complete, a_b, rhs_b, norms, j, zbar, zt):
    """One run's sums over its samples (z, phi_b (N, p), tgt_b (N, 3)) into a_b (p, p), rhs_b (p,)
    and norms[:, j]: A[q, r] = sum_k Z~(k, q) Phi(k, r) within a DOF's block, rhs[q] =
    sum_k Z~(k, q) tgt(k, dof q), the squared column norms of Z~, Phi and Z; Z~ = Z less its
    mean over the samples when ``complete``."""
    n, p = phi_b.shape
    lo, hi = _blocks(dof)
    zbar[:] = 0.0
    if complete:
        for k in range(n):
            for q in range(p):
                zbar[q] += z[k, q]
        for q in range(p):
            zbar[q] = zbar[q] / n
    for k in range(n):
        for q in range(p):
            zq = z[k, q]
            zt[q] = zq - zbar[q]
            ph = phi_b[k, q]
            norms[0, j, q] += zt[q] * zt[q]
            norms[1, j, q] += ph * ph
            norms[2, j, q] += zq * zq
            rhs_b[q] += zt[q] * tgt_b[k, dof[q]]
        for q in range(p):
            for r in range(lo[q], hi[q]):
                a_b[q, r] += zt[q] * phi_b[k, r]


@jitloop.compiled
def _moments_pass(phi, z, tgt, dof, complete):
    """Per run b the sums of :func:`_run_moments`: (A (B, p, p), rhs (B, p), norms (3, B, p))."""
    batch, n, p = phi.shape
    a = np.zeros((batch, p, p))
    rhs = np.zeros((batch, p))
    norms = np.zeros((3, batch, p))
    zbar = np.zeros(p)
    zt = np.empty(p)
    for b in range(batch):
        _run_moments(z[b], phi[b], tgt[b], dof, complete, a[b], rhs[b], norms, b, zbar, zt)
    return a, rhs, norms


def instrument_moments(
    profile: ShipProfile,
    sim_terms: TermSet,
    terms: TermSet,
    forces: np.ndarray | tuple[list[str], np.ndarray],
    nu0: np.ndarray,
    coef: np.ndarray,
    runs: np.ndarray,
    y: np.ndarray,
    mean_subtraction: str,
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None:
    """The IV moments of the runs ``runs`` from their measured velocities, with their instruments
    simulated, in one compiled pass over tiles of runs that stores no array of a whole batch:
    ((A, rhs, norms) as :func:`_moments_pass` gives them, sane (len(runs),): every
    instrument finite and below ``Z_LIMIT`` in magnitude).

    Phi(k) are the regressors of ``terms`` (the predictor (9.2), Ljungberg (2022)) at the measured
    velocities y(k) (``y`` (B, N+1, 3); the estimator knows no current: u_r = u), the target
    y(k+1) - y(k); Z(k) the same regressors at the noise-free calm-water simulation
    nu(k+1) = nu(k) + Phi_sim(k)^T theta of ``sim_terms`` with ``coef`` (p_sim, 1 or len(runs)),
    from ``nu0[runs]``, driven by ``forces``: the inputs (B or 1, N, m) or their :func:`run_forces`
    (made once for several calls on the same runs). The operations are those of
    :func:`primitives.regressors.predictor_regressors`, :func:`primitives.simulate.simulate`
    (compiled loop) and :func:`_moments_pass` in their order, so the moments are the unfused path's
    bits (but a term reading the speed U: the C library's hypot against numpy's, a last-bit
    difference). None where the pass does not apply (no numba loaded, pods, roll, rigid body,
    heading terms, powers outside primitives.powers.PRODUCT_POWERS, the mean removed per block): the caller takes the
    unfused path. Wind terms read calm air, as the unfused path's regressors without a wind.

    Where ``sim_terms`` are ``terms`` (the iterations) each factor is evaluated once a step for
    both Z and the increments (the same values, so the same products)."""
    if mean_subtraction == "batchwise" or profile.pods or profile.n_dof != 3 or profile.rigid_body is not None:
        return None
    if sim_terms.n_dof != 3 or terms.n_dof != 3:  # the pass steps and sums three DOFs: a roll list is the unfused path's
        return None
    if not jitloop.loaded() or regkernel._program(sim_terms.terms) is None or regkernel._program(terms.terms) is None:
        return None
    names, in_t = forces if isinstance(forces, tuple) else run_forces(profile, forces)
    sim, reg = (jitloop.program(t, names, jitloop.CALM_STATE) for t in (sim_terms, terms))
    if sim is None or reg is None:
        return None
    n_runs, p = len(runs), terms.n_params
    a, rhs, norms, sane = np.zeros((n_runs, p, p)), np.zeros((n_runs, p)), np.zeros((3, n_runs, p)), np.zeros(n_runs, np.bool_)
    speed = SPEED in signals_read(sim_terms) or SPEED in signals_read(terms)
    same = sim_terms.terms == terms.terms  # one program (array_equal would never hold: no station is NaN)
    _instrument_pass(
        in_t,
        np.ascontiguousarray(nu0, float),
        np.ascontiguousarray(coef, float),
        np.asarray(runs, np.int64),
        *sim[:6],
        sim[7],
        sim[6],
        *reg[2:6],
        reg[7],
        reg[6],
        speed,
        same,
        np.ascontiguousarray(y, float),
        _dof_of(terms),
        mean_subtraction == "complete",
        Z_LIMIT,
        a,
        rhs,
        norms,
        sane,
    )
    return (a, rhs, norms), sane


def run_forces(profile: ShipProfile, inputs: np.ndarray) -> tuple[list[str], np.ndarray]:
    """The input signals' names and values (N, signals, B or 1) of ``inputs`` (B or 1, N, m),
    time-major (:func:`instrument_moments` steps a tile of runs together)."""
    forces = profile.generalized_forces(inputs)  # each (1 or B, N)
    shape = np.broadcast_shapes(*(np.shape(v) for v in forces.values()))
    return list(forces), np.stack([np.broadcast_to(v, shape).T for v in forces.values()], axis=1)


# signals the calm-water pass provides (primitives.jitloop's layout): the velocities relative to
# water and air are the velocities, U their modulus; wind terms read zeros
Z_LIMIT = 1e6  # instruments above this come from an exploding simulation
TILE = 32  # runs stepped together by the fused IV pass (their instruments kept for the moments: N x p x TILE)


@jitloop.compiled
def _instrument_pass(
    in_t,
    nu0,
    coef,
    runs,
    dof_first,
    dof_n,
    t_first,
    t_n,
    f_sig,
    f_mod,
    f_pow,
    f_sta,
    r_first,
    r_n,
    g_sig,
    g_mod,
    g_pow,
    g_sta,
    speed,
    same,
    y,
    dof,
    complete,
    z_limit,
    a,
    rhs,
    norms,
    sane,
):
    """:func:`instrument_moments`' pass over tiles of TILE runs (``runs[j]``: batch member of run j),
    the runs the inner loop of every stage: the time loop of primitives.jitloop.time_loop in calm
    water (each term c_t * f_1 * f_2 ... summed left to right per DOF, nu(k+1) = nu(k) + inc) with
    Z(k) at nu(k) kept for the tile and summed for its mean as it is made; then each run's sums of
    :func:`_run_moments` step by step, Phi(k) and the target made from y at that step
    (:func:`_data_row`): the same operations in the same order per run (so the same bits). Phi is
    made anew on every pass over a run: faster than keeping it for the batch and gathering a
    tile's rows from it (measured 21 against 25 ms for 250 runs of 1,000 steps)."""
    n, p, nf = y.shape[1] - 1, dof.shape[0], g_sig.shape[0]
    one_in, one_coef = in_t.shape[2] == 1, coef.shape[1] == 1
    lo, hi = _blocks(dof)
    m = TILE
    st = np.empty((jitloop.N_STATE + in_t.shape[1], m))
    x = np.empty((3, m))
    fv, fs = np.empty((nf, m)), np.empty((f_sig.shape[0], m))
    ph, tg = np.empty((p, m)), np.empty((3, m))  # a step's data regressors and targets
    z = np.empty((n, p, m))
    acc, inc = np.empty(m), np.empty((3, m))
    worst, zbar, zt = np.empty(m), np.empty((p, m)), np.empty((p, m))
    at, rt, nt = np.empty((p, p, m)), np.empty((p, m)), np.empty((3, p, m))
    bs = np.empty(m, np.int64)
    for j0 in range(0, runs.shape[0], m):
        tl = min(m, runs.shape[0] - j0)
        for t in range(tl):
            bs[t] = runs[j0 + t]
            for i in range(3):
                x[i, t] = nu0[bs[t], i]
            worst[t] = 0.0
        zbar[:] = 0.0
        for k in range(n):
            _tile_signals(st, x, in_t, bs, one_in, k, speed, tl)
            _tile_factors(fv, st, g_sig, g_mod, g_pow, g_sta, tl)
            for q in range(p):
                _term_product(acc, fv, r_first[q], r_n[q], tl)
                for t in range(tl):
                    v = acc[t]
                    z[k, q, t] = v
                    if not abs(v) <= worst[t]:  # NaN too
                        worst[t] = abs(v) if v == v else math.inf
                if complete:  # the sum over the samples in their order, as _run_moments adds them
                    for t in range(tl):
                        zbar[q, t] += acc[t]
            src = fv  # the predictor's factors are the simulated model's: read them, no copy
            if not same:  # the simulated model's own factors at the same signals
                _tile_factors(fs, st, f_sig, f_mod, f_pow, f_sta, tl)
                src = fs
            for i in range(3):
                for t in range(tl):
                    inc[i, t] = 0.0
                for q in range(dof_first[i], dof_first[i] + dof_n[i]):
                    for t in range(tl):
                        acc[t] = coef[q, 0 if one_coef else j0 + t]
                    for f in range(t_first[q], t_first[q] + t_n[q]):
                        for t in range(tl):
                            acc[t] = acc[t] * src[f, t]
                    for t in range(tl):
                        inc[i, t] = acc[t] if q == dof_first[i] else inc[i, t] + acc[t]
            for i in range(3):
                for t in range(tl):
                    x[i, t] = x[i, t] + inc[i, t]
        for t in range(tl):
            sane[j0 + t] = worst[t] < z_limit
        if complete:
            for q in range(p):
                for t in range(tl):
                    zbar[q, t] = zbar[q, t] / n
        at[:] = 0.0
        rt[:] = 0.0
        nt[:] = 0.0
        for k in range(n):
            # the time loop's signal, state and factor scratch (st, x, fv) is free for the data's regressors
            _data_row(ph, tg, y, in_t, bs, one_in, k, speed, st, x, fv, g_sig, g_mod, g_pow, g_sta, r_first, r_n, acc, tl)
            for q in range(p):
                dq = dof[q]
                for t in range(tl):
                    zq = z[k, q, t]
                    e = zq - zbar[q, t]
                    zt[q, t] = e
                    phq = ph[q, t]
                    nt[0, q, t] += e * e
                    nt[1, q, t] += phq * phq
                    nt[2, q, t] += zq * zq
                    rt[q, t] += e * tg[dq, t]
            for q in range(p):
                for r in range(lo[q], hi[q]):
                    for t in range(tl):
                        at[q, r, t] += zt[q, t] * ph[r, t]
        for t in range(tl):
            j = j0 + t
            for q in range(p):
                rhs[j, q] = rt[q, t]
                for i in range(3):
                    norms[i, j, q] = nt[i, q, t]
                for r in range(p):
                    a[j, q, r] = at[q, r, t]


@jitloop.inlined
def _tile_signals(st, x, in_t, bs, one_in, k, speed, tl):
    """The calm-water signals (S, TILE) of the tile's states x (3, TILE) and inputs at step k."""
    for i in range(in_t.shape[1]):
        for t in range(tl):
            st[jitloop.N_STATE + i, t] = in_t[k, i, 0 if one_in else bs[t]]
    for t in range(tl):
        u, v = x[0, t], x[1, t]
        st[0, t], st[1, t], st[2, t], st[3, t], st[4, t], st[5, t], st[6, t] = u, v, x[2, t], u, v, u, v
    if speed:
        for t in range(tl):
            h = math.hypot(x[0, t], x[1, t])
            st[7, t] = MIN_SPEED if h < MIN_SPEED else h  # NaN stays NaN, as in np.maximum


@jitloop.inlined
def _tile_factors(fv, st, f_sig, f_mod, f_pow, f_sta, tl):
    """fv[f, t] = regkernel._factor of each factor f of a program for the tile's members t."""
    for f in range(f_sig.shape[0]):
        i = f_sig[f]
        if math.isnan(f_sta[f]) and f_pow[f] == 1:  # the common factors, as loops without branches (they vectorise)
            if f_mod[f]:
                for t in range(tl):
                    fv[f, t] = abs(st[i, t])
            else:
                for t in range(tl):
                    fv[f, t] = st[i, t]
            continue
        for t in range(tl):
            fv[f, t] = regkernel._factor(st[i, t], st[2, t], f_sta[f], f_mod[f], f_pow[f])


@jitloop.inlined
def _data_row(ph, tg, y, in_t, bs, one_in, k, speed, st, x, fv, g_sig, g_mod, g_pow, g_sta, r_first, r_n, acc, tl):
    """The tile's data regressors Phi(k) (p, TILE) at the measured velocities y(k) (the signals,
    factors and products of the instruments at the simulated ones: the operations of
    :func:`primitives.regressors.predictor_regressors`) and targets y(k+1) - y(k) (3, TILE)."""
    for i in range(3):
        for t in range(tl):
            x[i, t] = y[bs[t], k, i]
            tg[i, t] = y[bs[t], k + 1, i] - x[i, t]
    _tile_signals(st, x, in_t, bs, one_in, k, speed, tl)
    _tile_factors(fv, st, g_sig, g_mod, g_pow, g_sta, tl)
    for q in range(ph.shape[0]):
        _term_product(acc, fv, r_first[q], r_n[q], tl)
        for t in range(tl):
            ph[q, t] = acc[t]


@jitloop.inlined
def _term_product(acc, fv, first, count, tl):
    """acc[t] = 1.0 * f_1 * f_2 ... of one term's factor values fv[first:first + count, t], left
    to right (regkernel._build's product)."""
    for t in range(tl):
        acc[t] = 1.0
    for f in range(first, first + count):
        for t in range(tl):
            acc[t] = acc[t] * fv[f, t]
