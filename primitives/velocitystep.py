"""The velocity step of every simulator, ``nu(k+1) = nu(k) + Phi(k)^T theta`` of (3.60)/(9.1)
(:class:`VelocityStep`), and the signals its regressor terms read: the velocities relative to the water
and the air (:func:`relative_signals`), the speed through the water :data:`SPEED`, the wind-excess
signals :data:`WIND_EXCESS` and a podded profile's pod forces (:func:`model_signals`).
:mod:`primitives.simulate` runs the time loop over it and imports these names from here too.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from primitives.pods import pod_generalized_forces
from primitives.rigidbody import RigidBody
from primitives.ship import ShipProfile
from primitives.terms import TermSet, signals_used


def body_from_ne(vec_ne: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotate an n-frame vector (north, east) into the body frame (Fossen 2021, ch. 2: x north, y east, psi from north)."""
    c, s = np.cos(psi), np.sin(psi)
    return c * vec_ne[..., 0] + s * vec_ne[..., 1], -s * vec_ne[..., 0] + c * vec_ne[..., 1]


# Signals of the wind candidate terms: how much the wind loads differ from those of calm air, zero
# in calm air. The loads have the published shape of the wind coefficients as functions of the
# relative wind angle g (Fossen 2021, (10.8)-(10.11); the leading terms of Isherwood's and
# Fujiwara's fits): X ~ V_q^2 cos g = V_q u_q, Y ~ V_q^2 sin g ~ V_q v_q, N ~ V_q^2 sin 2g ~ u_q v_q,
# with V_q the air speed. (Källström's (1977) u_q|u_q|, v_q|v_q| is the same in surge at small
# angles, but in sway it is quadratic in the cross wind where the load is linear in it.)
WIND_EXCESS = ("wx", "wy", "wn")


# The speed through the water U = sqrt(u_r^2 + v_r^2): hull forces of the MMG and prime systems
# scale as 1/2 rho L d U^2 f(v_r/U, r L/U) (Yasukawa & Yoshimura 2015, (10)-(12)), so terms such
# as U*v_r, v_r^3*U^-1, r^3*U^-1 hold them exactly. Floored so that 1/U stays finite at rest.
SPEED = "U"
MIN_SPEED = 1e-9


def relative_signals(
    nu: np.ndarray,
    current_body: tuple[np.ndarray, np.ndarray] | None = None,
    wind_body: tuple[np.ndarray, np.ndarray] | None = None,
    wind_excess: bool = False,
    into: dict[str, np.ndarray] | None = None,
    speed: bool = False,
) -> dict[str, np.ndarray]:
    """State signals of the regressor terms for velocities nu (..., 3): u, v, r, the velocities
    relative to the water (u_r, v_r) and to the air (u_q, v_q), given the current and the air
    velocity in body axes (None: still water, calm air), with ``wind_excess`` the
    :data:`WIND_EXCESS` signals and with ``speed`` the speed through the water :data:`SPEED`.
    Added to ``into`` (e.g. the inputs of the step) when given."""
    u, v, r = nu[..., 0], nu[..., 1], nu[..., 2]
    sig = {} if into is None else into
    sig["u"], sig["v"], sig["r"] = u, v, r
    if current_body is None:
        sig["u_r"], sig["v_r"] = u, v
    else:
        sig["u_r"], sig["v_r"] = u - current_body[0], v - current_body[1]
    if speed:
        sig[SPEED] = np.maximum(np.hypot(sig["u_r"], sig["v_r"]), MIN_SPEED)
    if wind_body is None:
        sig["u_q"], sig["v_q"] = u, v
        if wind_excess:
            sig["wx"] = sig["wy"] = sig["wn"] = np.zeros(np.shape(u))
    else:
        uq, vq = u - wind_body[0], v - wind_body[1]
        sig["u_q"], sig["v_q"] = uq, vq
        if wind_excess:
            vq_abs, v_abs = np.hypot(uq, vq), np.hypot(u, v)
            sig["wx"], sig["wy"], sig["wn"] = vq_abs * uq - v_abs * u, vq_abs * vq - v_abs * v, uq * vq - u * v
    return sig


def model_signals(
    profile: ShipProfile,
    nu: np.ndarray,
    psi: np.ndarray,
    input_sig: dict[str, np.ndarray],
    current_ne: np.ndarray | None = None,
    wind_ne: np.ndarray | None = None,
    phi: np.ndarray | None = None,
    speed: bool = True,
) -> dict[str, np.ndarray]:
    """Signal dictionary the regressor terms read, for velocities nu (..., 3), or (..., 4) with
    the roll rate p (then ``phi`` is the roll angle). Pod forces (the podded-ship MSc thesis, (2.12)) depend on the
    velocities, so a podded profile's tau_x, tau_y, tau_k, tau_n are computed here. ``speed=False``
    leaves out the speed through the water :data:`SPEED` (for terms that do not read it)."""
    sig = relative_signals(
        nu,
        None if current_ne is None else body_from_ne(current_ne, psi),
        None if wind_ne is None else body_from_ne(wind_ne, psi),
        into=dict(input_sig, psi=psi),
        speed=speed,
    )
    return add_state_forces(profile, nu, phi, sig)


def add_state_forces(
    profile: ShipProfile, nu: np.ndarray, phi: np.ndarray | None, sig: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """Add to ``sig`` the signals that depend on the state besides the relative velocities: roll
    rate and angle (nu (..., 4)) and a podded profile's tau_x, tau_y, tau_k, tau_n (the podded-ship MSc thesis, (2.12))."""
    if nu.shape[-1] == 4:
        sig.update(p=nu[..., 3], phi=np.zeros_like(nu[..., 0]) if phi is None else phi)
    if profile.pods:
        sig.update(
            pod_generalized_forces(profile.pod_model, profile.pods, sig | {"u": nu[..., 0], "v": nu[..., 1], "r": nu[..., 2]})
        )
    return sig


@lru_cache(maxsize=64)
def _signals_read(terms: tuple[tuple[str, ...], ...]) -> frozenset[str]:
    return frozenset(signals_used(terms))


def signals_read(terms: TermSet) -> frozenset[str]:
    """The signals the terms read (:func:`primitives.terms.signals_used`), kept per term list:
    compiling the terms costs about a millisecond, and every simulation asks."""
    return _signals_read(terms.terms)


class VelocityStep:
    """One step ``nu(k+1) = nu(k) + Phi(k)^T theta [+ forced(k)]`` of (3.60)/(9.1): the time step
    of every simulator in the project (:func:`simulate`, and the diagnosis's augmented model,
    ``diagnose.model.AugmentedModel``, which adds its candidate terms as ``terms`` and its
    input-only increments as ``forced``). For a physical (rigid-body) profile the terms are
    forces and the increments are ``Ts M^-1 (F - C_RB nu)`` (the podded-ship MSc thesis, (2.13)).

    ``theta`` (p,) for one model or (B, p) for one per batch member. Built once per simulation:
    the increment function is generated from the term strings and the coefficients split once,
    because this call is the inner loop of every simulation.
    """

    def __init__(self, terms: TermSet, theta: np.ndarray, rigid: RigidBody | None = None, ts: float | None = None):
        theta = np.asarray(theta, dtype=float)
        self.inc = terms.increment_function()
        self.terms = terms
        # the coefficients as the compiled loop reads them: (p, 1) for one model, (p, B) for one per member
        self.coef_array = np.ascontiguousarray(theta.reshape(-1, 1) if theta.ndim == 1 else theta.T)
        # contiguous columns: every step multiplies them (a strided column is a slower loop)
        self.coef = theta.tolist() if theta.ndim == 1 else list(np.ascontiguousarray(theta.T))
        used = signals_read(terms)
        self.wind_excess = bool(used & set(WIND_EXCESS))
        self.speed = SPEED in used
        self.reads_heading = "psi" in used
        self.rigid, self.ts = rigid, ts
        # one ship in calm water and air stepped on Python floats (:meth:`next_one`): the same
        # increment function and coefficients, about a sixth of the time of a batch of one
        self.scalar = rigid is None and not self.wind_excess and not self.speed and theta.ndim == 1 and terms.scalar_exact
        self.inc_floats = self.inc if self.scalar else None

    def increments(
        self,
        nu: np.ndarray,
        exo: dict[str, np.ndarray],
        current_body: tuple[np.ndarray, np.ndarray] | None = None,
        wind_body: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> list[np.ndarray]:
        """The increments nu(k+1) - nu(k) per DOF of the term set (arrays or scalars that broadcast
        to (B,)); the arguments as for :meth:`__call__`."""
        sig = relative_signals(nu, current_body, wind_body, self.wind_excess, into=exo, speed=self.speed)
        inc = self.inc(sig, self.coef)
        if self.rigid is not None:
            inc = self.rigid.increments(inc, nu, self.ts)
        return inc

    def next_one(self, nu: np.ndarray, exo: dict) -> np.ndarray:
        """nu(k+1) (n_dof,) of one ship in calm water and calm air from nu(k) (n_dof,) and the
        exogenous signals of step k as Python floats: the bits of ``self(nu[None], exo)[0]``
        (the increment function's float variant: every operation is one IEEE operation on a
        float as on an array, see :attr:`TermSet.scalar_exact`), without numpy's per-call cost
        on one-element arrays. Falls back to the batch step when the step cannot run on floats (:attr:`scalar`)."""
        if not self.scalar or len(nu) != 3:
            return self(np.asarray(nu, float).reshape(1, -1), exo)[0]
        u, v, r = float(nu[0]), float(nu[1]), float(nu[2])
        # relative_signals in still water and calm air: relative velocities are those over ground
        exo["u"] = exo["u_r"] = exo["u_q"] = u
        exo["v"] = exo["v_r"] = exo["v_q"] = v
        exo["r"] = r
        du, dv, dr = self.inc_floats(exo, self.coef)
        return np.array((u + du, v + dv, r + dr))

    def __call__(
        self,
        nu: np.ndarray,
        exo: dict[str, np.ndarray],
        current_body: tuple[np.ndarray, np.ndarray] | None = None,
        wind_body: tuple[np.ndarray, np.ndarray] | None = None,
        forced: np.ndarray | None = None,
    ) -> np.ndarray:
        """nu(k+1) (B, n_dof) from nu(k) (B, n_dof), the exogenous signals of step k (inputs or
        generalized forces, heading, ...), the current and air velocity in body axes (see
        :func:`relative_signals`) and increments ``forced`` (B, n_dof) summed outside the loop.
        ``exo`` is extended in place with the state signals (it is built per step by the caller)."""
        inc = self.increments(nu, exo, current_body, wind_body)
        nxt = nu + forced if forced is not None else nu.copy()
        for i, d in enumerate(inc):  # one increment per DOF of the term set
            nxt[:, i] += d
        return nxt
