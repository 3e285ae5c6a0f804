"""The generalized forces that hold a ship's velocities steady in calm water (the feed-forward of
the manoeuvre generators, the autopilot and the Monte Carlo's hold), and which ships have them.

Evaluated with the simulation kernel's regressor signals (:func:`primitives.velocitystep.model_signals`).
"""

from __future__ import annotations

import numpy as np

from primitives.ship import ProfileError, ShipProfile
from primitives.simulate import model_signals

# The actuator kinds whose inputs are (or allocate) generalized forces, so that the forces holding
# a state steady (:func:`steady_forces`) can be applied: not a rudder/propeller ship's helm and rpm.
STEADY_FORCE_ACTUATORS = ("generalized", "azimuth")


def has_steady_forces(profile: ShipProfile) -> bool:
    """Whether :func:`steady_forces` applies to the ship (a 3-DOF generalized-force or azimuth ship)."""
    return profile.planar and profile.actuator in STEADY_FORCE_ACTUATORS


def require_steady_forces(profile: ShipProfile) -> None:
    """Refuse a ship :func:`steady_forces` does not apply to, in one line saying why."""
    profile.require_planar("steady_forces")
    if profile.actuator not in STEADY_FORCE_ACTUATORS:
        raise ProfileError(
            f"profile {profile.name!r}: steady generalized forces need generalized-force or azimuth inputs, not rudder/propeller"
        )


def steady_forces(
    profile: ShipProfile, u: float, v: float, r: float, theta: np.ndarray | str | None = None
) -> tuple[float, float, float]:
    """Generalized forces (tau_x, tau_y, tau_n) that hold (u, v, r) steady in calm water.

    Solves Phi(u, v, r, tau)^T theta = 0 for tau, using that the model is affine in each of
    tau_x, tau_y, tau_n (true for (3.60) and (9.1)).
    """
    tau = steady_forces_many(profile, np.array([u], float), np.array([v], float), np.array([r], float), theta)[0]
    return float(tau[0]), float(tau[1]), float(tau[2])


def steady_forces_many(
    profile: ShipProfile, u: np.ndarray, v: np.ndarray, r: np.ndarray, theta: np.ndarray | str | None = None
) -> np.ndarray:
    """:func:`steady_forces` of each state (u[k], v[k], r[k]): (n, 3), in one batched evaluation
    of the increments and one stacked solve (elementwise and per system: each row the numbers
    of a call for that state alone)."""
    require_steady_forces(profile)
    terms = profile.model
    theta = profile.params(theta)
    n = len(u)
    # the increments at tau = 0 and at the three unit forces, setting after setting
    taus = np.repeat(np.vstack([np.zeros(3), np.eye(3)]), n, axis=0)
    nu = np.tile(np.column_stack([u, v, r]).astype(float), (4, 1))
    sig = model_signals(profile, nu, np.zeros(4 * n), {"tau_x": taus[:, 0], "tau_y": taus[:, 1], "tau_n": taus[:, 2]})
    f = np.array(terms.increments(sig, theta)).reshape(3, 4, n)  # (3 DOFs, 4 settings, n)
    jac = (f[:, 1:] - f[:, :1]).transpose(2, 0, 1)  # (n, DOF, force)
    rhs = -f[:, 0].T
    try:
        return np.linalg.solve(jac, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError:  # a singular state: each on its own, least squares where singular
        out = np.empty((n, 3))
        for k in range(n):
            try:
                out[k] = np.linalg.solve(jac[k], rhs[k])
            except np.linalg.LinAlgError:
                out[k] = np.linalg.lstsq(jac[k], rhs[k], rcond=None)[0]
        return out
