"""The generalized forces that hold a ship's velocities steady in calm water (the feed-forward of
the manoeuvre generators, the autopilot and the Monte Carlo's hold), and which ships have them.

Evaluated with the simulation kernel's regressor signals (:func:`primitives.simulate.model_signals`).
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
    require_steady_forces(profile)
    terms = profile.model
    theta = profile.params(theta)
    # one batched evaluation at tau = 0 and at the three unit forces
    taus = np.vstack([np.zeros(3), np.eye(3)])
    nu = np.tile([u, v, r], (4, 1)).astype(float)
    sig = model_signals(profile, nu, np.zeros(4), {"tau_x": taus[:, 0], "tau_y": taus[:, 1], "tau_n": taus[:, 2]})
    f = np.array(terms.increments(sig, theta))  # (3 DOFs, 4 settings)
    jac = f[:, 1:] - f[:, :1]
    try:
        tau = np.linalg.solve(jac, -f[:, 0])
    except np.linalg.LinAlgError:
        tau, *_ = np.linalg.lstsq(jac, -f[:, 0], rcond=None)
    return float(tau[0]), float(tau[1]), float(tau[2])
