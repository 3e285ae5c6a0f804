"""Sway-roll-yaw truth of the seed-000 multipurpose naval vessel for the detection study.

Rows 2-4 of (2.13)-(2.14) with the Appendix A values (Tables A.1, A.2) and the two pods of
(2.9)-(2.12) with Table 2.1; surge ``u`` is prescribed (an input, as in the thesis's yaw study,
L859-860). Choices the text leaves open, written down:

- Coriolis as ``-C_RB(nu) nu`` (the digest's section 1.5): sway ``-m u r``, roll ``+m z_g u r``,
  yaw ``-m x_g u r``;
- restoring ``-rho g Delta GM phi`` plus ``K_phiphiphi phi^3`` with ``-0.325 rho g Delta``;
- pod inflow ``u_p = u - y_p r``, ``v_p = v + x_p r - z_p p``, drift ``sigma = atan2(v_p, u_p)``,
  pod yaw moment ``x_pod F_y`` only, as (2.12) (the ``-y_pod F_x`` terms are left out);
- ``n`` in rev/s (the thesis's "3600 s^-1" read as rpm).

NOTE: this is the detection study's own truth model. The 4-DOF podded profile in the shared
kernel (``primitives/``) is the one source of truth for this vessel; once it lands, this module
should be replaced by a call to it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

RHO, G = 1025.0, 9.82
M, DISP, I_X, I_Z, X_G, Z_G, GM = 359e3, 350.0, 3.4e6, 33.7e6, -3.38, -1.75, 0.776
POD_D, POD_A = 0.42, 2.5
POD_X, POD_Y, POD_Z = -23.5, (-1.0, 1.0), 1.2
CMX1, CMX2, CMY1, CMY2, CRX1, CRX2, CRY = 0.484, -0.47, 0.484, 0.7, 1.2, -1.2, 1.2

#: Table A.2 coefficients used in the sway (Y), roll (K) and yaw (N) rows.
Y = {"vd": -0.393e6, "pd": -0.296e6, "rd": -1.4e6, "uv": -11800, "vv": -3700, "vr": -0.794e6, "rv": -0.182e6,
     "fuv": 10800, "fur": 0.251e6, "fuu": -74, "ur": 0.131e6}
K = {"vd": 0.296e6, "pd": -0.774e6, "uv": 9260, "vv": 29300, "vr": 0.621e6, "rv": 0.142e6, "fuv": -8400,
     "fur": -0.196e6, "fuu": -1180, "ur": -0.102e6, "pp": -0.416e6, "p": -0.5e6, "up": -15500}
N = {"vd": 0.538e6, "rd": -28.7e6, "uv": -92000, "rv": -15.6e6, "fuv": -0.214e6, "ur": -4.71e6, "rr": -202e6,
     "fur": -4.98e6, "fuu": -8000}

#: Table 4.1 white measurement noise (standard deviations) of the signals the prior model uses.
TABLE_4_1 = {"r": 0.0025, "v_dot": 0.015, "u": 0.15, "v": 0.15, "phi": 0.025, "tau_r": 5e4}


def pod_forces(alpha: np.ndarray, n: np.ndarray, u: np.ndarray, v: np.ndarray, r: np.ndarray, p: np.ndarray,
               y_pod: float) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame (F_x, F_y) of one pod at angle ``alpha`` [rad] and ``n`` [rev/s], (2.9)-(2.11).

    The expanded form ``rho D^4 (C n^2 + C' n D u_tot)`` avoids J = u/(nD) at n = 0.
    """
    up = u - y_pod * r
    vp = v + POD_X * r - POD_Z * p
    ut = np.hypot(up, vp)
    sig = np.arctan2(vp, up)
    dr = alpha - sig
    d4 = RHO * POD_D**4
    fxm = d4 * (CMX1 * np.cos(dr) * n**2 + CMX2 * n * POD_D * ut)
    fym = d4 * np.sin(dr) * (CMY1 * n**2 + CMY2 * n * POD_D * ut)
    q = 0.5 * RHO * POD_A * ut**2
    fx, fy = fxm + q * (CRX1 * np.cos(2 * dr) + CRX2), fym + q * CRY * np.sin(2 * dr)
    c, s = np.cos(sig), np.sin(sig)
    return fx * c - fy * s, fx * s + fy * c


def pod_yaw_moment(ch: dict[str, np.ndarray], u, v, r, p) -> tuple[np.ndarray, np.ndarray]:
    """(sum F_y, yaw moment x_pod sum F_y) of both pods from channels n1, alpha1, n2, alpha2, (2.12)."""
    fy = sum(pod_forces(ch[f"alpha{i}"], ch[f"n{i}"], u, v, r, p, POD_Y[i - 1])[1] for i in (1, 2))
    return fy, POD_X * fy


@dataclass(frozen=True)
class Vessel:
    """Scales of the properties a change can hit: rigid-body yaw inertia I_z (seed 000's "10 % more
    I_z", L1591, moves I_r = I_z - N_rdot by 5.4 %), yaw damping, pod force."""

    inertia: float = 1.0
    damping: float = 1.0
    pod_gain: float = 1.0
    lumped_inertia: float = 1.0  # scale of I_r = I_z - N_rdot as a whole (the other reading of "10 %")

    def mass_matrix(self) -> np.ndarray:
        """Rows/columns v, p, r of (2.14)."""
        i_r = (I_Z * self.inertia - N["rd"]) * self.lumped_inertia  # inertia: the ship's own I_z (cargo)
        return np.array([[M - Y["vd"], -(M * Z_G + Y["pd"]), M * X_G - Y["rd"]],
                         [-(M * Z_G + K["vd"]), I_X - K["pd"], 0.0],
                         [M * X_G - N["vd"], 0.0, i_r]])


def _forces(ves: Vessel, u, v, p, phi, r, fy):
    """Right-hand sides of the sway, roll and yaw rows (everything but M nu_dot)."""
    au, av, ar = np.abs(u), np.abs(v), np.abs(r)
    yy = (Y["uv"] * au * v + Y["ur"] * u * r + Y["vv"] * v * av + Y["vr"] * v * ar + Y["rv"] * r * av
          + Y["fuv"] * phi * np.abs(u * v) + Y["fur"] * phi * np.abs(u * r) + Y["fuu"] * phi * u**2 - M * u * r + fy)
    kk = (K["uv"] * au * v + K["ur"] * u * r + K["vv"] * v * av + K["vr"] * v * ar + K["rv"] * r * av
          + K["fuv"] * phi * np.abs(u * v) + K["fur"] * phi * np.abs(u * r) + K["fuu"] * phi * u**2
          + K["pp"] * p * np.abs(p) + K["p"] * p + K["up"] * au * p
          - RHO * G * DISP * GM * phi - 0.325 * RHO * G * DISP * phi**3 + M * Z_G * u * r - POD_Z * fy)
    d = ves.damping
    nn = (d * (N["uv"] * au * v + N["ur"] * au * r + N["rr"] * r * ar + N["rv"] * r * av
               + N["fuv"] * phi * np.abs(u * v) + N["fur"] * phi * u * ar + N["fuu"] * phi * u * au)
          - M * X_G * u * r + POD_X * fy)
    return np.stack([yy, kk, nn])


def simulate(ves: Vessel, ch: dict[str, np.ndarray], dt: float, x0: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """States v, p, phi, r, the accelerations v_dot and the pod yaw moment tau_r (Heun's method).

    ``ch`` holds ``u`` and the pod channels ``n1, alpha1, n2, alpha2``, each of shape (n,);
    ``x0`` the initial (v, p, phi, r), at rest by default.
    """
    minv = np.linalg.inv(ves.mass_matrix())
    u = ch["u"]
    ns = len(u)
    x = np.zeros((ns, 4))  # v, p, phi, r
    if x0 is not None:
        x[0] = x0
    acc = np.zeros((ns, 3))
    tau = np.zeros(ns)

    def f(k: int, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        v, p, phi, r = s
        pods = {c: ch[c][k] for c in ("n1", "alpha1", "n2", "alpha2")}
        fy, mz = pod_yaw_moment(pods, u[k], v, r, p)
        nud = minv @ _forces(ves, u[k], v, p, phi, r, ves.pod_gain * fy)
        return np.array([nud[0], nud[1], p, nud[2]]), nud, ves.pod_gain * mz

    for k in range(ns - 1):
        k1, acc[k], tau[k] = f(k, x[k])
        k2, _, _ = f(k + 1, x[k] + dt * k1)
        x[k + 1] = x[k] + 0.5 * dt * (k1 + k2)
    _, acc[-1], tau[-1] = f(ns - 1, x[-1])
    return {"v": x[:, 0], "p": x[:, 1], "phi": x[:, 2], "r": x[:, 3], "v_dot": acc[:, 0], "tau_r": tau}


def harbour_inputs(n_samples: int, dt: float, seed: int, n_rps: float = 60.0) -> dict[str, np.ndarray]:
    """Harbour-like manoeuvring at a prescribed surge speed [choice; seed 000 does not give its
    signals]: random pod-angle steps (both pods together, |alpha| <= 26 deg, one every 15 s)
    through a 2 s low-pass, n = 60 rev/s, u ~ 6-8 m/s. Forward speed keeps u > 0 so the lumped
    A u r term of (2.17) stays valid (the thesis's pods-at-90-degree harbour exit goes astern)."""
    rng = np.random.default_rng(seed)
    hold = int(round(15.0 / dt))
    steps = np.repeat(rng.uniform(-0.45, 0.45, n_samples // hold + 1), hold)[:n_samples]
    a = np.exp(-dt / 2.0)
    alpha = lfilter([1 - a], [1, -a], steps)
    u = 7.0 + 1.0 * np.sin(2 * np.pi * np.arange(n_samples) * dt / 400.0)
    n = np.full(n_samples, n_rps)
    return {"u": u, "n1": n, "alpha1": alpha, "n2": n.copy(), "alpha2": alpha.copy()}


def measure(truth: dict[str, np.ndarray], ch: dict[str, np.ndarray], noise: dict[str, float],
            rng: np.random.Generator, runs: int | None = None) -> dict[str, np.ndarray]:
    """Measured signals with white noise of the given standard deviations (Table 4.1 names);
    ``runs`` adds a second axis of independent realisations."""
    sig = {"u": ch["u"], **{k: truth[k] for k in ("v", "r", "phi", "v_dot", "tau_r")}}
    shape = (len(ch["u"]),) if runs is None else (len(ch["u"]), runs)
    out = {}
    for k, x in sig.items():
        x = x if runs is None else x[:, None]
        out[k] = x + noise.get(k, 0.0) * rng.standard_normal(shape)
    return out
