"""The MMG standard manoeuvring model of Yasukawa & Yoshimura (2015), "Introduction of MMG
standard method for ship maneuvering predictions", J. Mar. Sci. Technol. 20:37-52, built from
regression coefficients (:mod:`primitives.particulars.regressions`), and the standard
manoeuvres (IMO MSC.137(76)) run on it with a rate-limited steering gear.

Midship origin, x_G = 0 (a first model knows no LCG), deep calm water. Equations (4):
(m + m_x) u' - (m + m_y) v r = X_H + X_R + X_P; (m + m_y) v' + (m + m_x) u r = Y_H + Y_R;
(I_zG + J_z) r' = N_H + N_R.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from primitives.particulars.regressions import RHO
from primitives.particulars.units import unit_forces


@dataclass(frozen=True)
class MMGShip:
    """Dimensional particulars and non-dimensional MMG coefficients of one ship."""

    length: float
    draught: float
    volume: float
    hull: dict[str, float]  # R0, Xvv, Xvr, Xrr, Xvvvv, Yv, Yr, Nv, Nr and the Kijima non-linear ones
    mass: dict[str, float]  # mx, my, Jz (non-dimensional)
    inter: dict[str, float]  # tR, aH, xH, gammaR, lR, eps, kappa, wP0, tP
    prop_diameter: float
    kt: tuple[float, float, float]  # K_T = k0 + k1 J + k2 J^2 (eq. 15)
    rudder_area: float
    rudder_span: float
    f_alpha: float
    x_p: float = -0.48  # propeller position x'_P (Yasukawa & Yoshimura 2015, Table 1 for KVLCC2)
    x_r: float = -0.5  # rudder position x'_R
    # "single": one screw and one rudder on the centre line; "twin": two screw-rudder units at
    # y = -+ y_unit L; "pods": two steerable pods there, rudder_area then being the housing's lateral
    # area per pod (both in primitives.particulars.units.unit_forces)
    layout: str = "single"
    y_unit: float = 0.0  # y'/L of the starboard unit (the port one mirrors it)

    @property
    def units(self) -> int:
        """Propellers (and rudders or pods) of the ship."""
        return 1 if self.layout == "single" else 2

    def derivatives(self, nu: np.ndarray, delta: float, n: float | tuple[float, float]) -> np.ndarray:
        """(u', v', r') [m/s^2, m/s^2, rad/s^2] of eq. (4). ``delta``: the rudder angle, or for
        pods the steering angle both pods take (+ turns to starboard, as a rudder); ``n``: one shaft
        speed for every propeller, or (port, starboard) [rev/s]."""
        u, v, r = nu
        L, d = self.length, self.draught
        m = RHO * self.volume
        q = 0.5 * RHO * L * d
        mx, my = self.mass["mx"] * q * L, self.mass["my"] * q * L
        jz = self.mass["Jz"] * q * L**3
        izg = m * (0.25 * L) ** 2
        U = math.hypot(u, v)
        if U < 1e-6:
            vp = rp = 0.0
        else:
            vp, rp = v / U, r * L / U
        beta = -vp  # drift angle (small-angle form of atan(-v/u) the regressions use)
        xh, yh, nh = self.hull_forces(vp, rp, U)
        if self.layout == "single":
            n = _one_shaft(n)
            xp, u_p = self.propeller_force(u, n, beta, rp)
            xr, yr, nr = self.rudder_forces(delta, n, u_p, U, beta, rp)
        else:
            xr, yr, nr = unit_forces(self, nu, delta, n, U, beta, rp)
            xp = 0.0
        return np.array(
            [
                (xh + xr + xp + (m + my) * v * r) / (m + mx),
                (yh + yr - (m + mx) * u * r) / (m + my),
                (nh + nr) / (izg + jz),
            ]
        )

    def hull_forces(self, vp: float, rp: float, U: float) -> tuple[float, float, float]:
        """X_H, Y_H, N_H [N, N, N m] of eqs. (10)-(12), with the Kijima et al. (1990) non-linear terms
        in beta = -v'."""
        h, L = self.hull, self.length
        q = 0.5 * RHO * L * self.draught * U**2
        b = -vp
        xh = q * (-h["R0"] + h["Xvv"] * vp**2 + h["Xvr"] * vp * rp + h["Xrr"] * rp**2 + h["Xvvvv"] * vp**4)

        def lateral(dof: str) -> float:
            return (
                h[f"{dof}v"] * vp
                + h[f"{dof}r"] * rp
                + h[f"{dof}bb"] * b * abs(b)
                + h[f"{dof}rr"] * rp * abs(rp)
                + (h[f"{dof}bbr"] * b + h[f"{dof}brr"] * rp) * b * rp
            )

        return xh, q * lateral("Y"), q * L * lateral("N")

    def propeller_force(self, u: float, n: float, beta: float, rp: float) -> tuple[float, float]:
        """X_P [N] of eqs. (13)-(15) and the inflow speed u_P [m/s]. The turn wake is not eq. (16)
        (Yasukawa & Yoshimura's C_1, C_2 need captive tests) but Inoue et al. (1981):
        w_P = w_P0 exp(-4 beta_P^2)."""
        beta_p = beta - self.x_p * rp
        u_p = (1.0 - self.inter["wP0"] * math.exp(-4.0 * beta_p**2)) * u
        D = self.prop_diameter
        k0, k1, k2 = self.kt
        thrust = RHO * D**4 * (k0 * n * abs(n) + k1 * n * u_p / D + k2 * u_p * abs(u_p) / D**2)
        return (1.0 - self.inter["tP"]) * thrust, u_p

    def rudder_forces(
        self, delta: float, n: float, u_p: float, U: float, beta: float, rp: float, eps: float | None = None
    ) -> tuple[float, float, float]:
        """X_R, Y_R, N_R [N, N, N m] of eqs. (17)-(27) of one rudder (of area ``rudder_area``)
        behind a propeller of inflow ``u_p``; ``eps`` overrides the ship's (a pod's housing)."""
        it, D = self.inter, self.prop_diameter
        eps = it["eps"] if eps is None else eps
        eta = min(D / self.rudder_span, 1.0)
        if abs(n) > 1e-6 and u_p > 0:
            j = u_p / (n * D)
            kt = self.kt[0] + self.kt[1] * j + self.kt[2] * j * j
            load = max(1.0 + 8.0 * max(kt, 0.0) / (math.pi * j * j), 0.0)
            u_r = eps * u_p * math.sqrt(eta * (1.0 + it["kappa"] * (math.sqrt(load) - 1.0)) ** 2 + (1.0 - eta))
        else:
            u_r = eps * u_p
        v_r = U * it["gammaR"] * (beta - it["lR"] * rp)
        alpha = delta - math.atan2(v_r, max(u_r, 1e-6))
        fn = 0.5 * RHO * self.rudder_area * (u_r**2 + v_r**2) * self.f_alpha * math.sin(alpha)
        xr = -(1.0 - it["tR"]) * fn * math.sin(delta)
        yr = -(1.0 + it["aH"]) * fn * math.cos(delta)
        nr = -(self.x_r + it["aH"] * it["xH"]) * self.length * fn * math.cos(delta)
        return xr, yr, nr

    def input_row(self, delta: float, n: float | tuple[float, float]) -> tuple[float, ...]:
        """The profile's inputs for a steering angle and shaft speed(s): (delta, n) of a rudder ship
        (a twin-screw ship's rudders and shafts move together), (n1, alpha1, n2, alpha2) of a podded
        one (pod 1 to port; alpha + thrust to starboard, so a starboard turn is alpha = -delta)."""
        if self.layout != "pods":
            return (delta, _one_shaft(n))
        n_port, n_stbd = (n, n) if np.isscalar(n) else n
        return (float(n_port), -delta, float(n_stbd), -delta)

    def step(self, nu: np.ndarray, delta: float, n: float | tuple[float, float], dt: float) -> np.ndarray:
        """Classical Runge-Kutta over dt with the inputs held."""
        k1 = self.derivatives(nu, delta, n)
        k2 = self.derivatives(nu + 0.5 * dt * k1, delta, n)
        k3 = self.derivatives(nu + 0.5 * dt * k2, delta, n)
        k4 = self.derivatives(nu + dt * k3, delta, n)
        return nu + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


def _one_shaft(n: float | tuple[float, float]) -> float:
    """The shaft speed of the ship's inputs: one for every shaft (a twin-screw ship's shafts turn alike)."""
    return n if isinstance(n, float | int) else 0.5 * (n[0] + n[1])


@dataclass
class Run:
    """One simulated manoeuvre at the sample time: nu (N+1, 3), psi (N+1,), xy (N+1, 2) and the
    inputs applied over each sample, (N, 2) = (delta [rad], n [rev/s])."""

    name: str
    nu: np.ndarray
    psi: np.ndarray
    xy: np.ndarray
    inputs: np.ndarray


Helm = Callable[[int, float], tuple[float, float]]  # (k, psi) -> (rudder command [rad], n [rev/s])


def run(ship: MMGShip, name: str, helm: Helm, u0: float, steps: int, dt: float, rate: float, max_rudder: float) -> Run:
    """Simulate ``steps`` samples from a steady straight approach at u0: the helm orders a rudder
    angle and a shaft speed each sample, the rudder follows at ``rate`` [rad/s]."""
    nu = np.array([u0, 0.0, 0.0])
    psi, pos, delta = 0.0, np.zeros(2), 0.0
    nus, psis, xys, ins = [nu], [psi], [pos], []
    for k in range(steps):
        cmd, n = helm(k, psi)
        cmd = float(np.clip(cmd, -max_rudder, max_rudder))
        delta += float(np.clip(cmd - delta, -rate * dt, rate * dt))
        new = ship.step(nu, delta, n, dt)
        mid = 0.5 * (nu + new)
        psi_mid = psi + 0.5 * dt * mid[2]
        pos = pos + dt * np.array(
            [mid[0] * math.cos(psi_mid) - mid[1] * math.sin(psi_mid), mid[0] * math.sin(psi_mid) + mid[1] * math.cos(psi_mid)]
        )
        psi += dt * mid[2]
        nu = new
        if not np.all(np.isfinite(nu)):
            raise FloatingPointError(f"the MMG model diverged in the {name}")
        nus.append(nu), psis.append(psi), xys.append(pos), ins.append(ship.input_row(delta, n))
    return Run(name, np.array(nus), np.array(psis), np.array(xys), np.array(ins))


def zigzag_helm(angle: float, side: float, n: float) -> Helm:
    """Z angle/angle: rudder to ``side`` (+1 starboard), reversed each time the heading passes the
    check angle to that side (ITTC 7.5-04-02-01)."""
    state = {"s": side}

    def helm(k: int, psi: float) -> tuple[float, float]:
        if state["s"] * psi >= angle:
            state["s"] = -state["s"]
        return state["s"] * angle, n

    return helm


def fixed_helm(rudder: float, n: float, n_after: float | None = None, at: int | None = None) -> Helm:
    """A constant rudder (turning circle); optionally the shaft speed changes to ``n_after`` at
    sample ``at`` (speed change, stopping)."""

    def helm(k: int, psi: float) -> tuple[float, float]:
        return rudder, (n if at is None or k < at else n_after)

    return helm
