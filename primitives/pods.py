"""Podded propulsion (the podded-ship MSc thesis, section 2.2, eq. 2.9-2.12, Table 2.1; adapted from Gierusz 2015).

Each pod is a rotatable thruster with a rudder-like strut. Its propeller ("motive") and strut
("resistive") forces are computed in the pod-through-water frame and rotated into the body frame:

    F_x,m = rho n^2 D^4 K_m,x(delta_r, J),   K_m,x = C_m,x,1 cos(delta_r) + C_m,x,2 J        (2.9a, 2.10a)
    F_y,m = rho n^2 D^4 K_m,y(delta_r, J),   K_m,y = sin(delta_r) (C_m,y,1 + C_m,y,2 J)      (2.9b, 2.10b)
    F_x,r = 1/2 rho A_pod u_tot^2 (C_r,x,1 cos(2 delta_r) + C_r,x,2)                         (2.9c, 2.10c)
    F_y,r = 1/2 rho A_pod u_tot^2 C_r,y sin(2 delta_r)                                       (2.9d, 2.10d)
    [F_x,pod, F_y,pod] = R(sigma) [F_x,m + F_x,r, F_y,m + F_y,r]                              (2.11)

with J = u_tot / (n D) written out (``n^2 J = n u_tot / D``) so that n = 0 is not singular.

Choices the thesis leaves open (recorded here and in the profile):
- u_tot and sigma: the thesis never says how they follow from the ship state. Here the pod's
  velocity through the water is the rigid-body velocity at the pod position,
  ``u_p = u - y_p r``, ``v_p = v + x_p r - z_p p``, ``u_tot = hypot(u_p, v_p)``,
  ``sigma = atan2(v_p, u_p)`` and ``delta_r = delta - sigma`` (digest section 2.5).
- Yaw moment: (2.12) has only ``x_pod F_y,pod``; the ``-y_pod F_x,pod`` part (non-zero when the
  two pods give different thrust) is left out as in the thesis unless the profile sets
  ``pod_model.yaw_moment = "full"``.
- n is in rev/s and must be >= 0 (reverse propeller speed is outside the model).
- Pod-pod interaction, azimuth rate limits and propeller spin-up are not modelled (thesis).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Pod:
    """Position of one pod in the body frame [m] (Table 2.1: x_pod, y_pod, z_pod; z down)."""

    name: str
    x: float
    y: float
    z: float


@dataclass(frozen=True)
class PodModel:
    """Coefficients shared by identical pods (Table 2.1; the thesis makes both pods alike)."""

    rho: float
    diameter: float
    strut_area: float
    c_mx1: float
    c_mx2: float
    c_my1: float
    c_my2: float
    c_rx1: float
    c_rx2: float
    c_ry: float
    yaw_moment: str = "thesis"  # "thesis": x F_y only (2.12); "full": x F_y - y F_x

    def local_forces(self, n: np.ndarray, delta_r: np.ndarray, u_tot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(F_x, F_y) of one pod in its through-water frame, (2.9)-(2.10)."""
        rho, d = self.rho, self.diameter
        d4 = rho * d**4
        fx_m = d4 * (self.c_mx1 * np.cos(delta_r) * n**2 + self.c_mx2 * n * d * u_tot)
        fy_m = d4 * np.sin(delta_r) * (self.c_my1 * n**2 + self.c_my2 * n * d * u_tot)
        q = 0.5 * rho * self.strut_area * u_tot**2
        fx_r = q * (self.c_rx1 * np.cos(2 * delta_r) + self.c_rx2)
        fy_r = q * self.c_ry * np.sin(2 * delta_r)
        return fx_m + fx_r, fy_m + fy_r


def pod_body_forces(
    model: PodModel, pod: Pod, n: np.ndarray, delta: np.ndarray, u: np.ndarray, v: np.ndarray, r: np.ndarray, p: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(F_x,pod, F_y,pod) of one pod in the body frame, (2.9)-(2.11), for pod angle ``delta`` [rad]
    and propeller speed ``n`` [rev/s] at ship velocities (u, v, r, p)."""
    u_p = u - pod.y * r
    v_p = v + pod.x * r - pod.z * p
    u_tot = np.hypot(u_p, v_p)
    sigma = np.arctan2(v_p, u_p)
    fx, fy = model.local_forces(n, delta - sigma, u_tot)
    c, s = np.cos(sigma), np.sin(sigma)
    return fx * c - fy * s, fx * s + fy * c


def pod_generalized_forces(model: PodModel, pods: tuple[Pod, ...], sig: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """tau_act of (2.12) as signals tau_x, tau_y, tau_k (roll), tau_n (yaw).

    ``sig`` holds the ship velocities u, v, r, p and the inputs n1, delta1, n2, delta2, ...
    """
    u, v, r = sig["u"], sig["v"], sig["r"]
    p = sig.get("p", np.zeros_like(u))
    tx = ty = tk = tn = 0.0
    for i, pod in enumerate(pods, start=1):
        fx, fy = pod_body_forces(model, pod, sig[f"n{i}"], sig[f"delta{i}"], u, v, r, p)
        tx = tx + fx
        ty = ty + fy
        tk = tk - pod.z * fy
        tn = tn + pod.x * fy - (pod.y * fx if model.yaw_moment == "full" else 0.0)
    return {"tau_x": tx, "tau_y": ty, "tau_k": tk, "tau_n": tn}
