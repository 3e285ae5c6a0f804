"""Rigid-body and added-mass part of a 4-DOF (surge, sway, yaw, roll) ship model (the podded-ship MSc thesis, eq. 2.1-2.4, 2.13-2.14).

    M nu_dot = f(nu, eta) - g(eta) + tau_act - C_RB(nu) nu                                (2.13)

The profile's regressor terms give the hydrodynamic forces f - g and the actuator forces (with
physical coefficients, N and N m); this module adds the rigid-body Coriolis forces and turns the
force vector into the velocity increment ``Ts M^-1 F`` of the kernel's Euler step.

State order in this project is (u, v, r, p) -- yaw stays the third entry as in the 3-DOF ships,
roll is appended -- where the thesis writes (u, v, p, r); the matrices below are the thesis's
(2.3), (2.4), (2.14) permuted accordingly.

Choice: (2.13) prints ``+ C(nu) nu``; physics and the yaw row (2.15) (``- m x_g u r``) need
``- C_RB(nu) nu`` on the right-hand side, which is what is used here. M is not symmetric with the
Appendix A values (Y_pdot = -K_vdot), so Cholesky does not apply: M^-1 is formed once per profile
with ``np.linalg.inv`` (LAPACK's LU solve of M X = I) and the kernel multiplies each step's forces
by it (:attr:`RigidBody.inverse_mass`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

ADDED_MASS_KEYS = ("X_udot", "Y_vdot", "Y_pdot", "Y_rdot", "K_vdot", "K_pdot", "N_vdot", "N_rdot")


@dataclass(frozen=True)
class RigidBody:
    """Mass m [kg], inertias I_x, I_z [kg m^2], centre of gravity (x_g, z_g) [m, z down] and the
    added-mass derivatives of (2.7) (SI, as in Table A.2)."""

    mass: float
    i_x: float
    i_z: float
    x_g: float
    z_g: float
    added: dict[str, float]

    @cached_property
    def mass_matrix(self) -> np.ndarray:
        """M = M_RB - M_A of (2.14), rows/columns in state order (u, v, r, p)."""
        m, xg, zg, a = self.mass, self.x_g, self.z_g, self.added
        return np.array(
            [
                [m - a["X_udot"], 0.0, 0.0, 0.0],
                [0.0, m - a["Y_vdot"], m * xg - a["Y_rdot"], -(m * zg + a["Y_pdot"])],
                [0.0, m * xg - a["N_vdot"], self.i_z - a["N_rdot"], 0.0],
                [0.0, -(m * zg + a["K_vdot"]), 0.0, self.i_x - a["K_pdot"]],
            ]
        )

    @cached_property
    def inverse_mass(self) -> np.ndarray:
        """M^-1 of (2.13), formed once: ``np.linalg.inv`` (an LU factorisation; M is not symmetric)."""
        return np.linalg.inv(self.mass_matrix)

    def coriolis(self, u: np.ndarray, v: np.ndarray, r: np.ndarray, p: np.ndarray) -> list[np.ndarray]:
        """-C_RB(nu) nu of (2.4) per DOF (surge, sway, yaw, roll)."""
        m, xg, zg = self.mass, self.x_g, self.z_g
        return [m * (v * r - zg * p * r + xg * r * r), -m * u * r, -m * xg * u * r, m * zg * u * r]

    def increments(self, forces: list[np.ndarray], nu: np.ndarray, ts: float) -> list[np.ndarray]:
        """Euler velocity increments ``Ts M^-1 (F - C_RB nu)`` for forces F per DOF and velocities nu (..., 4)."""
        c = self.coriolis(nu[..., 0], nu[..., 1], nu[..., 2], nu[..., 3])
        f = np.stack([np.broadcast_to(fi + ci, nu.shape[:-1]) for fi, ci in zip(forces, c)], axis=-1)
        inc = ts * f @ self.inverse_mass.T
        return [inc[..., i] for i in range(4)]
