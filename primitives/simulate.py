"""Batch simulation of discrete-time ship models (Ljungberg 2022, (3.60), (9.1)).

``nu(k+1) = nu(k) + Phi(k)^T theta + w(k)`` with the regressors built from velocities relative
to the water (u_r, v_r) and to the air (u_q, v_q), and Euler kinematics
``eta(k+1) = eta(k) + Ts R(psi(k)) nu(k)`` (Fossen 2021, ch. 2: x north, y east, psi from north). Vectorised over a batch of Monte
Carlo realisations: the time loop is sequential, every realisation moves at once.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from primitives import jitloop, onestep
from primitives.ship import ShipProfile
from primitives.terms import TermSet
from primitives.velocitystep import (  # noqa: F401 - imported from here too
    MIN_SPEED,
    SPEED,
    WIND_EXCESS,
    VelocityStep,
    add_state_forces,
    body_from_ne,
    model_signals,
    relative_signals,
    signals_read,
)


@dataclass(frozen=True)
class Disturbances:
    """Environment and noise of a simulation. All velocities over ground, n-frame (north, east).

    current_ne: mean ocean current, the velocity it flows with (m/s north, m/s east).
    current_offset_std: std of a constant random offset drawn once per realisation.
    current_sample_std: std of an i.i.d. per-sample random part (the thesis's u_c(k) ~ N(0, s^2)).
    wind_ne: mean air velocity (the direction the wind blows toward), m/s north/east.
    process_std: additive noise on the velocity increments (u, v, r).
    measurement_std: additive noise on the measured u, v, r.
    heading_std, position_std: noise on the measured heading and position.
    current_turning: the current is fixed in the earth frame and the velocity over ground follows
    it as the ship turns (:func:`_turn_current`, Fossen 2021 section 10.3); off, the current acts
    through u_r, v_r only (the thesis's form, Ljungberg (2022) (3.60), (9.1)). A profile says which
    (``[disturbances] current_turning``; a diagnosed model.json with a current: on).
    """

    current_ne: tuple[float, float] = (0.0, 0.0)
    current_offset_std: float = 0.0
    current_sample_std: float = 0.0
    wind_ne: tuple[float, float] = (0.0, 0.0)
    wind_sample_std: float = 0.0
    process_std: tuple[float, float, float] = (0.0, 0.0, 0.0)
    measurement_std: tuple[float, float, float] = (0.0, 0.0, 0.0)
    heading_std: float = 0.0
    position_std: float = 0.0
    current_turning: bool = False

    @classmethod
    def from_profile(cls, profile: ShipProfile) -> Disturbances:
        """The disturbance levels the profile's source used in its Monte Carlo studies."""
        d = profile.disturbances
        return cls(
            current_ne=tuple(d.get("current_mean_ne", (0.0, 0.0))),
            current_sample_std=float(d.get("current_sample_std", 0.0)),
            measurement_std=tuple(d.get("measurement_std", (0.0, 0.0, 0.0))),
            heading_std=float(d.get("heading_std", 0.0)),
            current_turning=bool(d.get("current_turning", False)),
        )

    @property
    def is_calm(self) -> bool:
        return not any(
            np.any(np.asarray(v) != 0)
            for v in (
                self.current_ne,
                self.current_offset_std,
                self.current_sample_std,
                self.wind_ne,
                self.wind_sample_std,
                self.process_std,
            )
        )


@dataclass
class SimResult:
    """Outputs of :func:`simulate`; arrays carry a leading batch axis B.

    nu: (B, N+1, 3) true body velocities over ground; eta: (B, N+1, 3) true pose (x north,
    y east, psi); y: (B, N+1, 3) measured u, v, r (a profile with the roll DOF adds a fourth
    column: roll rate p in nu and y, roll angle phi in eta); psi_meas, pos_meas: measured heading and
    position; current_ne, wind_ne: (B, N, 2) the environment each step saw; inputs: (B, N, m).
    Without measurement noise ``y`` is a read-only view of ``nu``, and a current or wind without
    a random part a read-only broadcast of its mean: copy an array before writing into it.
    """

    t: np.ndarray
    inputs: np.ndarray
    nu: np.ndarray
    eta: np.ndarray
    y: np.ndarray
    psi_meas: np.ndarray
    pos_meas: np.ndarray
    current_ne: np.ndarray
    wind_ne: np.ndarray
    extra: dict = field(default_factory=dict)

    @property
    def batch(self) -> int:
        return self.nu.shape[0]


def _padded(values: np.ndarray | tuple, nd: int) -> np.ndarray:
    """A per-DOF vector given for the 3 planar DOFs (or all), padded with zeros for roll."""
    a = np.asarray(values, float)
    return np.concatenate([a, np.zeros(a.shape[:-1] + (nd - a.shape[-1],))], axis=-1) if a.shape[-1] < nd else a


def _batch_inputs(profile: ShipProfile, inputs: np.ndarray, batch: int) -> np.ndarray:
    inputs = np.asarray(inputs, dtype=float)
    if inputs.ndim == 1:
        inputs = inputs[:, None]
    if inputs.ndim == 2:
        inputs = inputs[None]
    if inputs.shape[-1] != len(profile.inputs):
        raise ValueError(f"inputs have {inputs.shape[-1]} columns; profile {profile.name!r} needs {list(profile.inputs)}")
    if inputs.shape[0] not in (1, batch):
        raise ValueError(f"inputs batch {inputs.shape[0]} does not match batch {batch}")
    return inputs


def simulate(
    profile: ShipProfile,
    inputs: np.ndarray,
    theta: np.ndarray | str | None = None,
    *,
    terms: TermSet | None = None,
    nu0: np.ndarray | tuple = (0.0, 0.0, 0.0),
    eta0: np.ndarray | tuple = (0.0, 0.0, 0.0),
    disturbances: Disturbances | None = None,
    batch: int = 1,
    seed: int | np.random.Generator | None = None,
    positions: bool = True,
    current_turning: bool = False,
) -> SimResult:
    """Simulate ``batch`` realisations driven by ``inputs`` (N, m) or (B, N, m).

    ``theta``: parameter vector (or (B, p) one per realisation) or the name of a set of the
    profile; default the profile's simulation set. ``terms`` overrides the model structure
    (e.g. a predictor or an augmented model). ``positions=False`` is for callers that read the
    velocities only (estimators, validation): the position x, y is not integrated, nor the
    heading unless the velocities depend on it (a current or wind to rotate into body axes, a
    term that reads psi, roll, pods); what is not integrated is NaN in ``eta`` and ``pos_meas``.
    The velocities are bit-identical either way; the position rows are about a fifth of a step.
    ``current_turning``: the velocity over ground also follows the current as the ship turns
    (see :func:`_time_loop`), as does ``disturbances.current_turning``; off, the current acts
    through u_r, v_r only (the thesis's form).
    """
    terms = terms or profile.model
    theta = (
        profile.params(theta) if terms is profile.model or isinstance(theta, str) or theta is None else np.asarray(theta, float)
    )
    if theta.shape[-1] != terms.n_params:
        raise ValueError(f"theta has {theta.shape[-1]} entries, the model needs {terms.n_params}")
    if theta.ndim == 2:
        batch = max(batch, theta.shape[0])
    dist = disturbances or Disturbances()
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    u_in = _batch_inputs(profile, inputs, batch)
    n_steps = u_in.shape[1]
    ts = profile.sample_time
    nd = profile.n_dof  # 3, or 4 with roll: nu (u, v, r, p), eta (x, y, psi, phi)

    # the random draws in this order: current offset, current per sample, wind per sample, process, measurement
    cur = _environment(dist.current_ne, (batch, n_steps), rng, dist.current_offset_std, dist.current_sample_std)
    wind = _environment(dist.wind_ne, (batch, n_steps), rng, 0.0, dist.wind_sample_std)
    proc = _padded(dist.process_std, nd)
    w = rng.normal(0.0, 1.0, (batch, n_steps, nd)) * proc if np.any(proc) else None

    step = VelocityStep(terms, theta, profile.rigid_body, ts)
    nu, eta = _time_loop(
        profile,
        step,
        u_in,
        _padded(nu0, nd),
        _padded(eta0, nd),
        _moving(cur),
        _moving(wind),
        w,
        batch,
        positions,
        current_turning or dist.current_turning,
    )

    meas = _padded(dist.measurement_std, nd)
    y = nu + rng.normal(0.0, 1.0, nu.shape) * meas if np.any(meas) else _read_only(nu)
    psi_meas = eta[..., 2] + (rng.normal(0.0, dist.heading_std, eta[..., 2].shape) if dist.heading_std else 0.0)
    pos_meas = eta[..., :2] + (rng.normal(0.0, dist.position_std, eta[..., :2].shape) if dist.position_std else 0.0)
    return SimResult(
        t=np.arange(n_steps + 1) * ts,
        inputs=np.broadcast_to(u_in, (batch,) + u_in.shape[1:]),
        nu=nu,
        eta=eta,
        y=y,
        psi_meas=psi_meas,
        pos_meas=pos_meas,
        current_ne=cur,
        wind_ne=wind,
    )


def _environment(
    mean: tuple[float, float] | np.ndarray, shape: tuple[int, int], rng: np.random.Generator, offset_std: float, sample_std: float
) -> np.ndarray:
    """A current or air velocity (B, N, 2) over ground: ``mean``, plus an offset drawn once per
    realisation and an i.i.d. part per sample. Without a random part it is a read-only broadcast
    of ``mean`` (no (B, N, 2) array is filled with one constant); with one, a new array."""
    env = np.broadcast_to(np.asarray(mean, float), shape + (2,))
    if not (offset_std or sample_std):
        return env
    env = env.copy()
    if offset_std:
        env += rng.normal(0.0, offset_std, (shape[0], 1, 2))
    if sample_std:
        env += rng.normal(0.0, sample_std, shape + (2,))
    return env


def _moving(env: np.ndarray) -> np.ndarray | None:
    """``env`` for the time loop, None when it is zero throughout: a zero current or wind is not
    rotated into body axes at every step (a sixth of the loop's time in the Monte Carlo). A
    broadcast of one constant is tested by its one value, not by all of its (B, N) copies."""
    if env.size and not any(env.strides[:-1]):  # every realisation and sample is the same vector
        return env if np.any(env[(0,) * (env.ndim - 1)]) else None
    return env if np.any(env) else None


def _read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a``: a second name for the same numbers (the measured velocities
    without measurement noise are the true ones) that cannot be written through by mistake."""
    view = a.view()
    view.flags.writeable = False
    return view


def time_major_forces(profile: ShipProfile, u_in: np.ndarray) -> tuple[list[str], np.ndarray]:
    """The input signals' names and values (N, signals, 1 or B), a step's signals one block."""
    forces = profile.generalized_forces(u_in)  # each (1 or B, N)
    in_t = np.empty((u_in.shape[1], len(forces), max(np.shape(v)[0] if np.ndim(v) else 1 for v in forces.values())))
    for i, v in enumerate(forces.values()):  # signal by signal: a cache-friendly transpose
        in_t[:, i] = np.transpose(v)
    return list(forces), in_t


def _time_loop(
    profile: ShipProfile,
    step: VelocityStep,
    u_in: np.ndarray,
    nu0: np.ndarray,
    eta0: np.ndarray,
    cur: np.ndarray | None,
    wind: np.ndarray | None,
    w: np.ndarray | None,
    batch: int,
    positions: bool,
    current_turning: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """The sequential loop of :func:`simulate`: nu, eta (B, N+1, nd); ``cur``, ``wind`` (B, N, 2)
    or None for still water, calm air.

    With ``current_turning`` an earth-fixed current is also turned into the velocity over ground:
    the hull's dynamics hold in the water-relative velocities (Fossen 2021, section 10.3) and
    nu = nu_r + u_c(psi), so as the heading changes over a step nu changes by
    u_c(psi(k+1)) - u_c(psi(k)) (the current of step k) on top of the hydrodynamic increment.

    The state is kept time-major, (N+1, nd, B), so that every step reads and writes contiguous
    rows of B values (batch-major rows are strided by the whole record); every operation is
    elementwise over the batch, so the numbers are those of any other layout."""
    n_steps, nd, ts = u_in.shape[1], nu0.shape[-1], profile.sample_time
    in_names, in_t = time_major_forces(profile, u_in)
    nu_t = np.empty((n_steps + 1, nd, batch))
    nu_t[0] = np.broadcast_to(nu0, (batch, nd)).T
    cur_t, wind_t = (None if a is None else np.ascontiguousarray(a.transpose(1, 2, 0)) for a in (cur, wind))  # (N, 2, B)
    w_t = None if w is None else np.ascontiguousarray(w.transpose(1, 2, 0))  # (N, nd, B)
    heading = positions or nd == 4 or bool(profile.pods) or cur_t is not None or wind_t is not None or step.reads_heading
    if jitloop.use(batch * n_steps):
        out = _compiled_loop(
            profile, step, in_names, in_t, nu0, eta0, cur_t, wind_t, w_t, batch, positions, heading, current_turning
        )
        if out is not None:
            return out
    if onestep.applies(step, batch, nd, bool(profile.pods), cur_t is not None or wind_t is not None, w_t is not None):
        return onestep.one_ship_loop(step, in_names, in_t, nu0, eta0, ts, positions, heading)
    if heading:
        eta_t = np.full((n_steps + 1, nd, batch), np.nan)
        eta_t[0] = np.broadcast_to(eta0, (batch, nd)).T
    else:  # nothing reads the pose: no array for it in the loop (the heading signal is NaN, read by no term)
        eta_t, unread = None, np.full(batch, np.nan)
    for k in range(n_steps):
        row, nxt = nu_t[k], nu_t[k + 1]
        psi_k = unread if eta_t is None else eta_t[k, 2]
        nu_k = row.T  # (B, nd) view with contiguous columns
        phi_k = eta_t[k, 3] if nd == 4 else None
        exo = dict(zip(in_names, in_t[k]))
        exo["psi"] = psi_k
        cur_b = None if cur_t is None else body_from_ne(cur_t[k].T, psi_k)
        wind_b = None if wind_t is None else body_from_ne(wind_t[k].T, psi_k)
        if nd == 4 or profile.pods:  # roll and pod-force signals depend on the state (the step adds the rest)
            add_state_forces(profile, nu_k, phi_k, exo)
        inc = step.increments(nu_k, exo, cur_b, wind_b)
        for i, d in enumerate(inc):  # one increment per DOF of the term set: nu(k+1) = nu(k) + inc
            np.add(row[i], d, out=nxt[i])
        if len(inc) < nd:  # DOFs without terms keep their velocity
            nxt[len(inc) :] = row[len(inc) :]
        if w_t is not None:
            nxt += w_t[k]
        if current_turning and cur_b is not None:
            _turn_current(nxt, cur_t[k].T, cur_b, psi_k, row[2], phi_k, ts)
        if eta_t is not None:
            _advance_pose(eta_t, k, row, ts, positions)
    nu = np.ascontiguousarray(nu_t.transpose(2, 0, 1))
    if eta_t is not None:
        return nu, np.ascontiguousarray(eta_t.transpose(2, 0, 1))
    eta = np.full((batch, n_steps + 1, nd), np.nan)
    eta[:, 0] = eta0
    return nu, eta


def _compiled_loop(
    profile: ShipProfile,
    step: VelocityStep,
    in_names: list[str],
    in_t: np.ndarray,
    nu0: np.ndarray,
    eta0: np.ndarray,
    cur_t: np.ndarray | None,
    wind_t: np.ndarray | None,
    w_t: np.ndarray | None,
    batch: int,
    positions: bool,
    heading: bool,
    current_turning: bool,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The loop of :func:`_time_loop` compiled (:mod:`primitives.jitloop`), the same arrays in and
    out; None when the term set reads a signal the loop does not provide (the numpy loop then
    raises its error)."""
    nd = nu0.shape[-1]
    state = {"u", "v", "r", "u_r", "v_r", "u_q", "v_q", "U", *WIND_EXCESS, "psi"} | ({"p", "phi"} if nd == 4 else set())
    state |= set(jitloop.POD_TAUS) if profile.pods else set()
    prog = jitloop.program(step.terms, in_names, frozenset(state))
    if prog is None:
        return None
    index = {n: jitloop.N_STATE + i for i, n in enumerate(in_names)}
    pods = jitloop.pod_arrays(profile, index)
    n_steps = in_t.shape[0]
    nu_t = np.empty((n_steps + 1, nd, batch))
    nu_t[0] = np.broadcast_to(nu0, (batch, nd)).T
    eta_t = np.full((n_steps + 1, nd, batch), np.nan) if heading else np.empty((1, nd, batch))
    eta_t[0] = np.broadcast_to(eta0, (batch, nd)).T
    jitloop.time_loop(
        jitloop.writable(in_t, ()),
        nu_t,
        eta_t,
        jitloop.writable(cur_t, (0, 2, batch)),
        jitloop.writable(wind_t, (0, 2, batch)),
        jitloop.writable(w_t, (0, nd, batch)),
        step.coef_array,
        *prog,
        *pods,
        *jitloop.rigid_arrays(step.rigid),
        float(profile.sample_time),
        heading,
        positions,
        bool(current_turning),
        step.wind_excess,
        step.speed,
        False,
        False,
    )
    nu = np.ascontiguousarray(nu_t.transpose(2, 0, 1))
    if heading:
        return nu, np.ascontiguousarray(eta_t.transpose(2, 0, 1))
    eta = np.full((batch, n_steps + 1, nd), np.nan)
    eta[:, 0] = eta0
    return nu, eta


def _turn_current(
    nxt: np.ndarray,
    cur_ne: np.ndarray,
    cur_b: tuple[np.ndarray, np.ndarray],
    psi_k: np.ndarray,
    r: np.ndarray,
    phi_k: np.ndarray | None,
    ts: float,
) -> None:
    """Add to nu(k+1) ``nxt`` (nd, B) the change of an earth-fixed current ``cur_ne`` (B, 2) in body
    axes over the step, u_c(psi(k+1)) - u_c(psi(k)) (``cur_b`` is u_c(psi(k))): nu = nu_r + u_c(psi)
    with the hull's dynamics in nu_r (Fossen 2021, section 10.3). The heading advances as in
    :func:`_advance_pose` (through cos(phi) with roll)."""
    u1, v1 = body_from_ne(cur_ne, psi_k + ts * (r if phi_k is None else np.cos(phi_k) * r))
    nxt[0] += u1 - cur_b[0]
    nxt[1] += v1 - cur_b[1]


def _advance_pose(eta_t: np.ndarray, k: int, row: np.ndarray, ts: float, positions: bool) -> None:
    """eta(k+1) = eta(k) + Ts R(psi(k)) nu(k) in the time-major pose ``eta_t`` (N+1, nd, B), from
    the velocities ``row`` = nu(k) (nd, B): the heading (and roll angle), and with ``positions``
    the position x, y (2.1a-b); with roll the Fossen rows, v and r acting through cos(phi)."""
    u, v, r = row[0], row[1], row[2]
    psi_k, now, nxt = eta_t[k, 2], eta_t[k], eta_t[k + 1]
    c, s = (np.cos(psi_k), np.sin(psi_k)) if positions else (None, None)
    if len(row) == 4:  # the products in this order: the numbers of every earlier version
        phi_k = now[3]
        cphi = np.cos(phi_k)
        if positions:
            nxt[0] = now[0] + ts * (c * u - s * cphi * v)
            nxt[1] = now[1] + ts * (s * u + c * cphi * v)
        nxt[2] = psi_k + ts * cphi * r
        nxt[3] = phi_k + ts * row[3]
        return
    if positions:
        nxt[0] = now[0] + ts * (c * u - s * v)
        nxt[1] = now[1] + ts * (s * u + c * v)
    nxt[2] = psi_k + ts * r
