"""The simulation kernel's time loop compiled with numba: the loop of
:func:`primitives.simulate._time_loop` (and of the diagnosis's open-loop simulator) over every step
and batch member in machine code, about 18 us a step of Python and numpy call overhead gone.

The model is the kernel's: nu(k+1) = nu(k) + Phi(k)^T theta + w(k) (seed 001 (3.60), (9.1)) with the
regressor terms read from their strings (:mod:`primitives.terms`) as a small program of factor
records, the signals of :func:`primitives.simulate.relative_signals`, pod forces (Gierusz 2015 /
seed 000 (2.9)-(2.12), :mod:`primitives.pods`), the rigid-body increments Ts M^-1 (F - C_RB nu)
(seed 000 (2.13), :mod:`primitives.rigidbody`), an earth-fixed current turned with the heading
(Fossen 2021, section 10.3) and the Euler kinematics eta(k+1) = eta(k) + Ts R(psi(k)) nu(k).
Every operation is the numpy path's, in the same order, on the same IEEE doubles (no fast-math, so
no fused multiply-add): the same bits, except where numpy's own vectorised routines may round
differently from the C library the compiled code calls, namely ``hypot`` (the speed U, the wind
terms, pods), ``arctan2`` (pods), powers other than 1, 2 and -1 (``v_r^3``, ``phi^3``: numpy's
vectorised power against the C library's pow, which differ on some CPUs) and the 4x4 product by
M^-1 of rigid-body profiles (BLAS's order of summation). Those differ in the last bit of a step and stay within the tolerance
tests/test_jitloop.py checks.

The pure-numpy loop is kept: it is used when numba cannot be imported or when the environment
sets ``SHIPTRIAL_KERNEL=numpy``, and for small calls in a process that has not loaded the
compiled code (:func:`use`). Compiled code is cached on disk (``cache=True``) so that a warm
process loads it instead of compiling it again.
"""

from __future__ import annotations

import importlib.util
import math
import os
import threading
import warnings
from functools import lru_cache

import numpy as np

from primitives.terms import TermSet, parse_factor

# The compiler is optional: without it (or with SHIPTRIAL_KERNEL=numpy) the numpy loops run. It is
# imported, and the cached machine code loaded, on the first call that is worth it (:func:`use`):
# that costs about a second of CPU per process, more than a command that only steps single ships
# (plan-trial, the library build) would save.
AVAILABLE = os.environ.get("SHIPTRIAL_KERNEL", "").strip().lower() != "numpy" and importlib.util.find_spec("numba") is not None
# Work (batch members x steps) of one call from which the compiled loop is loaded: a 20-member
# batch of 1000 steps costs about 20 ms in the numpy loop, 1 ms compiled.
MIN_WORK = 20_000
_LOADED = False
_LOCK = threading.RLock()  # two threads of a Dask worker must not load (and jit-decorate) twice

# Indices of the state signals in the per-step signal vector; the exogenous signals follow.
_STATE = ("u", "v", "r", "u_r", "v_r", "u_q", "v_q", "U", "wx", "wy", "wn", "psi", "p", "phi", "tau_x", "tau_y", "tau_k", "tau_n")
_IDX = {n: i for i, n in enumerate(_STATE)}
N_STATE = len(_STATE)
POD_TAUS = ("tau_x", "tau_y", "tau_k", "tau_n")
_NO_STATION = math.nan


def kernel_name() -> str:
    """Which time loop a large simulation runs: 'numba' or 'numpy'."""
    return "numba" if AVAILABLE else "numpy"


def loaded() -> bool:
    """Whether the compiled code is loaded in this process and usable (a call of :func:`use`
    loaded it): callers whose own work never pays for the load run compiled only then."""
    return AVAILABLE and _LOADED


def use(work: int) -> bool:
    """Whether a call of ``work`` batch members x steps runs compiled: when numba is available and
    either the compiled code is loaded already or the call is large enough to pay for loading it
    (:data:`MIN_WORK`). Both loops give the same numbers to the tolerance tests/test_jitloop.py
    states, so which one a small call takes may depend on what the process ran before (last-bit
    differences only). A numba that is installed but cannot be loaded (built for another numpy,
    no writable cache) is said once in a warning and the numpy loop runs."""
    global AVAILABLE
    if not AVAILABLE or not (_LOADED or work >= MIN_WORK):
        return False
    with _LOCK:
        if not _LOADED:
            try:
                _load()
            except Exception as e:  # an unusable compiler is no reason to stop: the numpy loop gives the same numbers
                AVAILABLE = False
                warnings.warn(
                    f"compiled simulation kernel unavailable ({type(e).__name__}: {e}); using the numpy loop "
                    "(set SHIPTRIAL_KERNEL=numpy to skip the attempt)",
                    RuntimeWarning,
                    stacklevel=2,
                )
                return False
    return True


@lru_cache(maxsize=256)
def _factors(terms: tuple[tuple[str, ...], ...]) -> tuple:
    """The parsed factors of every term, per DOF: [[(name, modulus, station, power), ...] per term]."""
    return tuple(
        tuple(tuple((f.name, f.modulus, f.station, f.power) for f in (parse_factor(s) for s in t.split("*"))) for t in dof)
        for dof in terms
    )


# the state signals the calm-water time loop provides to a term program (:func:`program`)
CALM_STATE = frozenset({"u", "v", "r", "u_r", "v_r", "u_q", "v_q", "U", "wx", "wy", "wn"})


def program(terms: TermSet, in_names: list[str], state_names: frozenset[str]) -> tuple[np.ndarray, ...] | None:
    """:func:`_program` of the term strings, made once per term list and signal names (a
    diagnosis simulates the same few hundred times; the loop only reads the arrays)."""
    return _program(terms.terms, tuple(in_names), state_names)


@lru_cache(maxsize=256)
def _program(
    terms: tuple[tuple[str, ...], ...], in_names: tuple[str, ...], state_names: frozenset[str]
) -> tuple[np.ndarray, ...] | None:
    """The term set as arrays the compiled loop reads: per DOF its first term and term count, per
    term its first factor and factor count, per factor the signal index, modulus, station (NaN:
    none) and power. Signals are looked up as the numpy loop's dictionary resolves them: the state
    signals ``state_names`` (set by the loop) before the exogenous ``in_names``. None when a term
    reads a signal neither provides (the numpy loop then raises its usual error)."""
    index = {n: N_STATE + i for i, n in enumerate(in_names)}
    index.update({n: _IDX[n] for n in state_names})
    dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_sta, f_pow = [], [], [], [], [], [], [], []
    for dof in _factors(terms):
        dof_first.append(len(t_first))
        dof_n.append(len(dof))
        for term in dof:
            t_first.append(len(f_sig))
            t_n.append(len(term))
            for name, modulus, station, power in term:
                names = (name,) if station is None else (name, "r")
                if any(n not in index for n in names):
                    return None
                f_sig.append(index[name])
                f_mod.append(int(modulus))
                f_sta.append(_NO_STATION if station is None else float(station))
                f_pow.append(power)
    ints = [np.asarray(a, np.int64) for a in (dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_pow)]
    return (*ints[:6], np.asarray(f_sta, float), ints[6])


def pod_arrays(profile, index: dict[str, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A podded profile's pods for the compiled loop: positions (n_pods, 3), the signal indices of
    each pod's propeller speed and angle (n_pods, 2), and the shared coefficients (see
    :func:`_pod_forces`); empty arrays without pods."""
    if profile is None or not profile.pods:
        return np.zeros((0, 3)), np.zeros((0, 2), np.int64), np.zeros(12)
    m = profile.pod_model
    pos = np.array([(p.x, p.y, p.z) for p in profile.pods], float)
    sig = np.array([(index[f"n{i}"], index[f"delta{i}"]) for i in range(1, len(profile.pods) + 1)], np.int64)
    # the Python-float products of PodModel.local_forces, formed once as they are there
    coef = np.array(
        [
            m.rho * m.diameter**4,
            m.diameter,
            m.c_mx1,
            m.c_mx2,
            m.c_my1,
            m.c_my2,
            0.5 * m.rho * m.strut_area,
            m.c_rx1,
            m.c_rx2,
            m.c_ry,
            1.0 if m.yaw_moment == "full" else 0.0,
            0.0,
        ]
    )
    return pos, sig, coef


def rigid_arrays(rigid) -> tuple[np.ndarray, np.ndarray]:
    """M^-1 (4, 4) and (m, x_g, z_g) of a rigid-body profile; empty without one."""
    if rigid is None:
        return np.zeros((0, 0)), np.zeros(3)
    return np.ascontiguousarray(rigid.inverse_mass), np.array([rigid.mass, rigid.x_g, rigid.z_g])


def writable(a: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` as a C-contiguous writable float array (the one array type the compiled loop is built
    for, so a warm process loads one cached specialisation), or an empty one of ``shape``."""
    if a is None:
        return np.zeros(shape)
    return np.require(a, float, ["C", "W"])


def open_loop(
    step,
    names: list[str],
    exo: dict[str, np.ndarray],
    nu0: np.ndarray,
    cur_body: tuple | None,
    wind_body: tuple | None,
    forced: np.ndarray | None,
) -> np.ndarray | None:
    """nu (B, N+1, 3) of ``step`` (a :class:`primitives.simulate.VelocityStep` without rigid body)
    stepped N times from nu0 (B, 3), the loop of a caller that supplies every signal itself: the
    exogenous signals ``exo[name]`` (N, B) (the heading among them when a term reads it), the
    current and air velocity already in body axes (each a pair of (N, B) arrays, or None) and
    increments ``forced`` (N, B, 3) added before the model's, as ``step(nu, exo_k, cur_k, wind_k,
    forced_k)`` would step after step; an exogenous signal may be (N, 1), the same for every
    member (when all are, it is stored once per step for the whole batch). None when the compiled
    loop does not apply."""
    n_work = nu0.shape[0] * (forced.shape[0] if forced is not None else next(iter(exo.values())).shape[0])
    if not use(n_work) or step.rigid is not None or nu0.shape[-1] != 3:
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


_INLINED: list[tuple[dict, str]] = []  # (the helper's module globals, its name)
_COMPILED: list = []  # every compiled function, given its dispatcher by _load


class compiled:
    """``fn`` compiled by numba (cached on disk: a warm process loads the machine code instead of
    compiling it), with the helpers marked :func:`inlined` compiled into it. Its dispatcher is made
    when :func:`use` first loads numba, so a compiler that cannot work is found there, before a
    caller has chosen the compiled path. Called only when :func:`use` says so."""

    def __init__(self, fn):
        self.fn, self.jit = fn, None
        self.__doc__, self.__name__ = fn.__doc__, fn.__name__
        _COMPILED.append(self)

    def __call__(self, *args):
        if self.jit is None:
            with _LOCK:
                _load()
                if self.jit is None:  # a function defined after numba was loaded
                    from numba import njit

                    self._dispatch(njit)
        return self.jit(*args)

    def _dispatch(self, njit) -> None:
        # error_model="numpy": a division by zero gives inf or NaN as numpy's does, without a check that stops vectorising
        try:
            self.jit = njit(cache=True, nogil=True, error_model="numpy")(self.fn)
        except RuntimeError:  # no writable cache directory (read-only install, no home): compile in memory
            self.jit = njit(nogil=True, error_model="numpy")(self.fn)
            return
        _stamp_shared_helpers(self.jit)


# The files whose inlined helpers are compiled into other files' functions (expdesign.oekernel
# inlines _increments and _times_factor, expdesign.ivsolve regkernel._factor).
SHARED_HELPER_FILES = (__file__, os.path.join(os.path.dirname(__file__), "regkernel.py"))


def _stamp_shared_helpers(jit) -> None:
    """Make ``jit``'s disk cache stale when a file of :data:`SHARED_HELPER_FILES` changes, not only
    its own file. numba keeps a cached function while its own source file's modification time and
    size are those recorded in the cache index (numba.core.caching.IndexDataCacheFile): a changed
    helper inlined from another file would otherwise leave the old machine code in use. The
    helpers' files' (mtime, size) are added to the stamp the index is checked against (a private
    numba attribute: where it is missing, only the function's own file is checked, as before)."""
    cache_file = getattr(getattr(jit, "_cache", None), "_cache_file", None)
    if cache_file is None or not hasattr(cache_file, "_source_stamp"):
        return
    try:
        shared = tuple((st.st_mtime, st.st_size) for st in map(os.stat, SHARED_HELPER_FILES))
    except OSError:
        return
    cache_file._source_stamp = (cache_file._source_stamp, shared)


def _load() -> None:
    """Import numba, replace the :func:`inlined` helpers by their compiled form and make every
    :class:`compiled` function's dispatcher, once (the caller holds ``_LOCK``)."""
    global _LOADED
    if _LOADED:
        return
    from numba import njit

    for g, name in _INLINED:
        if not hasattr(g[name], "py_func"):
            # inlined into the loop at compile time: a call per step would pass every array argument
            # through the reference counter, more than the arithmetic's cost for a small batch
            g[name] = njit(inline="always", error_model="numpy")(g[name])
    for c in _COMPILED:
        if c.jit is None:
            c._dispatch(njit)
    _LOADED = True


def inlined(fn):
    """Mark the module-level helper ``fn`` to be compiled into the :class:`compiled` functions that
    call it. numba's disk cache sees a change to the caller's own file only: a helper called from
    another file must be in a file of :data:`SHARED_HELPER_FILES`. Compiled at once when numba is
    loaded already."""
    if _LOADED:
        from numba import njit

        return njit(inline="always", error_model="numpy")(fn)
    _INLINED.append((fn.__globals__, fn.__name__))
    return fn


@inlined
def _times_factor(acc, sig, idx, station, modulus, power, batch):
    """acc[b] *= |sig[idx, b] + station * r|^power over the batch: one factor of a term (the
    numpy expression of primitives.terms.Factor.code: x**2 a square, x**-1 a reciprocal)."""
    has_station = not math.isnan(station)
    if not has_station and power == 1:  # the common factors, as loops without branches (they vectorise)
        if modulus:
            for b in range(batch):
                acc[b] = acc[b] * abs(sig[idx, b])
        else:
            for b in range(batch):
                acc[b] = acc[b] * sig[idx, b]
        return
    for b in range(batch):
        x = sig[idx, b]
        if has_station:
            x = x + station * sig[2, b]
        if modulus:
            x = abs(x)
        if power == 2:
            x = x * x
        elif power == -1:
            x = 1.0 / x
        elif power != 1:
            x = math.pow(x, float(power))
        acc[b] = acc[b] * x


@inlined
def _increments(inc, tmp, sig, coef, batch, dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_sta, f_pow):
    """inc[i, b] = Phi_i^T theta per DOF i: each term c_j * f_1 * f_2 ... and their sum, left to
    right, as the generated increment function (primitives.terms.TermSet.increment_function);
    the term program's branches once per step, the arithmetic in loops over the batch."""
    per_member = coef.shape[1] > 1
    for i in range(dof_first.shape[0]):
        if dof_n[i] == 0:
            for b in range(batch):
                inc[i, b] = 0.0
            continue
        for t in range(dof_first[i], dof_first[i] + dof_n[i]):
            for b in range(batch):
                tmp[b] = coef[t, b] if per_member else coef[t, 0]
            for f in range(t_first[t], t_first[t] + t_n[t]):
                _times_factor(tmp, sig, f_sig[f], f_sta[f], f_mod[f], f_pow[f], batch)
            if t == dof_first[i]:
                for b in range(batch):
                    inc[i, b] = tmp[b]
            else:
                for b in range(batch):
                    inc[i, b] = inc[i, b] + tmp[b]


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
    """The signals of step k per member into ``sig`` (primitives.simulate.relative_signals and
    _add_state_forces): inputs, u, v, r, psi (p, phi), pod forces, the velocities relative to the
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
            else:  # primitives.simulate.body_from_ne
                c, s = math.cos(psi), math.sin(psi)
                cn, ce = cur_t[k, 0, b], cur_t[k, 1, b]
                cu, cv = c * cn + s * ce, -s * cn + c * ce
        cub[b], cvb[b] = cu, cv
        ur, vr = (u - cu, v - cv) if has_cur else (u, v)
        sig[3, b], sig[4, b] = ur, vr
        if speed:
            h = math.hypot(ur, vr)
            sig[7, b] = 1e-9 if h < 1e-9 else h  # primitives.simulate.MIN_SPEED; NaN stays NaN as in np.maximum
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
    sig = np.zeros((N_STATE + in_t.shape[1], batch))
    inc = np.zeros((4, batch))
    tmp = np.empty(batch)
    cub, cvb = np.zeros(batch), np.zeros(batch)
    n_inc = 4 if minv.shape[0] > 0 else dof_first.shape[0]
    for k in range(n_steps):
        _state_signals(
            sig, cub, cvb, k, nu_t, eta_t, in_t, cur_t, wind_t, pod_pos, pod_sig, pod_coef, heading, wind_excess, speed, env_body
        )
        _increments(inc, tmp, sig, coef, batch, dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_sta, f_pow)
        _advance(k, nu_t, eta_t, inc, n_inc, w_t, cur_t, cub, cvb, minv, rb, ts, heading, positions, turning, forced_first)
