"""The Mariner class cargo ship as measured by planar-motion-mechanism tests: the non-linear model
of Chislett & Strøm-Tejsen (1965), "Planar motion mechanism tests and full-scale steering and
manoeuvring predictions for a Mariner class vessel", Hy-5, Hydro- og Aerodynamisk Laboratorium,
Lyngby (coefficients as tabulated in Fossen 2011, "Handbook of marine craft hydrodynamics and
motion control", section 7.2.2). A truth for benchmarks/bench_profile_new.py, sharing no code
with primitives.particulars: L = 160.93 m, U0 = 15 kn, x_G = -0.023 L, non-dimensional on
1/2 rho L^2 U^2 (forces) and 1/2 rho L^3 U^2 (moments), masses on 1/2 rho L^3.

The model is in perturbations about the approach speed (u = U0 + du) with the propeller held as on
the approach; positive delta turns to starboard here (the table's rudder sign reversed).
"""

from __future__ import annotations

import math

import numpy as np

L, U0 = 160.93, 15 * 1852 / 3600
B, T, CB = 23.17, 7.47, 0.6  # main particulars of the Mariner (volume 798e-5 x L^3 / 2: Cb 0.597)
E = 1e-5
M, IZ, XG = 798 * E, 39.2 * E, -0.023
X = dict(udot=-42, u=-184, uu=-110, uuu=-215, vv=-899, rr=18, dd=-95, udd=-190, rv=798, vd=93, uvd=93)
Y = dict(vdot=-748, rdot=-9.354, v=-1160, r=-499, vvv=-8078, vvr=15356, vu=-1160, ru=-499, d=278, ddd=-90, ud=556, uud=278,
         vdd=-4, vvd=1190, c0=-4, c0u=-8, c0uu=-4)  # fmt: skip
N = dict(vdot=4.646, rdot=-43.8, v=-264, r=-166, vvv=1636, vvr=-5483, vu=-264, ru=-166, d=-139, ddd=45, ud=-278, uud=-139,
         vdd=13, vvd=-489, c0=3, c0u=6, c0uu=3)  # fmt: skip


def _forces(du: float, v: float, r: float, d: float) -> tuple[float, float, float]:
    x, y, n = ({k: val * E for k, val in tab.items()} for tab in (X, Y, N))
    fx = (x["u"] * du + x["uu"] * du**2 + x["uuu"] * du**3 + x["vv"] * v**2 + x["rr"] * r**2 + x["rv"] * r * v + x["dd"] * d**2
          + x["udd"] * du * d**2 + x["vd"] * v * d + x["uvd"] * du * v * d)  # fmt: skip
    out = []
    for c in (y, n):
        out.append(c["v"] * v + c["r"] * r + c["vvv"] * v**3 + c["vvr"] * v**2 * r + c["vu"] * v * du + c["ru"] * r * du + c["d"] * d
                   + c["ddd"] * d**3 + c["ud"] * du * d + c["uud"] * du**2 * d + c["vdd"] * v * d**2 + c["vvd"] * v**2 * d
                   + c["c0"] + c["c0u"] * du + c["c0uu"] * du**2)  # fmt: skip
    return fx, out[0], out[1]


def derivatives(state: np.ndarray, delta: float) -> np.ndarray:
    """d/dt of (du, v, r) [m/s, m/s, rad/s] with the actual rudder ``delta`` [rad, + starboard]."""
    du, v, r = state
    U = math.hypot(U0 + du, v)
    fx, fy, fn = _forces(du / U, v / U, r * L / U, -delta)
    m11 = M - X["udot"] * E
    m22, m23 = M - Y["vdot"] * E, M * XG - Y["rdot"] * E
    m32, m33 = M * XG - N["vdot"] * E, IZ - N["rdot"] * E
    det = m22 * m33 - m23 * m32
    return np.array([fx * U**2 / L / m11, (m33 * fy - m23 * fn) * U**2 / L / det, (-m32 * fy + m22 * fn) * U**2 / L**2 / det])


def simulate(helm, steps: int, dt: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """(track (N+1, 3) = x, y, psi; velocities (N+1, 3) = u, v, r): ``helm(k, psi) -> rudder
    command`` [rad], the rudder following at ``rate`` [rad/s]; classical Runge-Kutta at dt."""
    s, pose, delta = np.zeros(3), np.zeros(3), 0.0
    track, vel = [pose.copy()], [np.array([U0, 0.0, 0.0])]
    for k in range(steps):
        delta += float(np.clip(helm(k, pose[2]) - delta, -rate * dt, rate * dt))
        k1 = derivatives(s, delta)
        k2 = derivatives(s + 0.5 * dt * k1, delta)
        k3 = derivatives(s + 0.5 * dt * k2, delta)
        k4 = derivatives(s + dt * k3, delta)
        new = s + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        u, v, r = U0 + 0.5 * (s[0] + new[0]), 0.5 * (s[1] + new[1]), 0.5 * (s[2] + new[2])
        psi = pose[2] + 0.5 * dt * r
        pose = pose + dt * np.array([u * math.cos(psi) - v * math.sin(psi), u * math.sin(psi) + v * math.cos(psi), r])
        s = new
        track.append(pose.copy()), vel.append(np.array([U0 + s[0], s[1], s[2]]))
    return np.array(track), np.array(vel)
