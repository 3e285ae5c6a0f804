"""Test-side physics: the MMG standard model of KVLCC2 (Yasukawa & Yoshimura 2015).

Yasukawa, H., Yoshimura, Y. (2015) Introduction of MMG standard method for ship maneuvering
predictions. J. Mar. Sci. Technol. 20:37-52 (doi:10.1007/s00773-014-0293-y). This module is
independent of the product (it imports nothing from ``primitives`` or ``diagnose``): the
product's ``kvlcc2`` profile is a nonlinear discrete-time model fitted on MARIN data (quadratic
resistance and thrust, cross-flow drag, rudder force growing with inflow and slipstream; its
deliberately linear diagnosis baseline is ``kvlcc2-linear``), this is the published nonlinear
continuous-time MMG model, and the gap between them is what a diagnosis on real data has to
see through.

Equations (numbers are the paper's):

- motion about midship (4): (m+m_x) u' - (m+m_y) v r - x_G m r^2 = X_H + X_R + X_P,
  (m+m_y) v' + (m+m_x) u r + x_G m r' = Y_H + Y_R,
  (I_zG + x_G^2 m + J_z) r' + x_G m (v' + u r) = N_H + N_R;
- hull (10)-(12): X'_H = -R'_0 + X'_vv v'^2 + X'_vr v' r' + X'_rr r'^2 + X'_vvvv v'^4,
  Y'_H, N'_H cubic in v' = v/U, r' = r L/U;
- propeller (13)-(16): X_P = (1 - t_P) rho n^2 D_P^4 K_T(J_P), K_T = k0 + k1 J + k2 J^2,
  J_P = u (1 - w_P) / (n D_P), (1 - w_P)/(1 - w_P0) = 1 + (1 - exp(-C1 |beta_P|)) (C2 - 1),
  beta_P = beta - x'_P r' (C1 = 2.0, C2 = 1.6 for beta_P > 0, 1.1 otherwise);
- rudder (17)-(27): F_N = 1/2 rho A_R U_R^2 f_alpha sin(alpha_R), alpha_R = delta - atan(v_R/u_R),
  X_R = -(1 - t_R) F_N sin delta, Y_R = -(1 + a_H) F_N cos delta,
  N_R = -(x_R + a_H x_H) F_N cos delta, v_R = U gamma_R beta_R (flow straightening,
  beta_R = beta - l'_R r', gamma_R by the sign of beta_R), u_R = eps u (1 - w_P)
  sqrt(eta {1 + kappa (sqrt(1 + 8 K_T / (pi J_P^2)) - 1)}^2 + (1 - eta)).

Sign conventions. Inside this module the MMG convention holds: positive rudder angle turns
the ship to starboard (r > 0). The shiptrial recordings follow the MARIN KVLCC2 data (and the
``kvlcc2`` profile fitted on them), where a positive rudder angle turns the ship to port:
:func:`to_recorded_delta` converts. Beta = atan2(-v, u) as in the paper.

Scale: the coefficients are the paper's (captive tests of the 1:45.7 model, L = 7 m). The
full-scale ship is the Froude-scaled model (lengths x lambda, speeds and times x sqrt(lambda),
rps / sqrt(lambda)), with the same non-dimensional coefficients (no skin-friction
correction): a model-scale run is exactly the Froude-scaled full-scale run.

Current: constant in the earth frame; the hull, propeller and rudder see the water-relative
velocity, and for a uniform irrotational current the equations hold unchanged in relative
velocities (Fossen 2021, section 10.3), so the state integrated is (x, y, psi, u_r, v_r, r)
and the velocity over ground is u_r + u_c(psi). Wind: Isherwood's (1972) tabulated coefficients
for merchant ships (``tests.physics.isherwood``; not the cos g, sin g, sin 2g shapes the
diagnosis's wind terms have), q = 1/2 rho_a V_rw^2, g = -atan2(v_rw, u_rw), with the
over-ground velocity relative to the air. Every run has it: without wind the air is still and the ship's
own motion drags the superstructure through it (a calm-water trial has this air resistance;
the MMG resistance R'_0, from captive tank tests, does not hold it).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from tests.physics import isherwood

RHO = 1025.0  # sea water, kg/m^3
RHO_AIR = 1.225
MODEL_SCALE = 45.7  # SIMMAN / Yasukawa & Yoshimura 2015: L = 7.00 m model of the 320 m ship


@dataclass(frozen=True)
class Coefficients:
    """Non-dimensional KVLCC2 coefficients, Yasukawa & Yoshimura (2015) Tables 2-4."""

    m_x: float = 0.022
    m_y: float = 0.223
    J_z: float = 0.011
    R_0: float = 0.022
    X_vv: float = -0.040
    X_vr: float = 0.002
    X_rr: float = 0.011
    X_vvvv: float = 0.771
    Y_v: float = -0.315
    Y_r: float = 0.083
    Y_vvv: float = -1.607
    Y_vvr: float = 0.379
    Y_vrr: float = -0.391
    Y_rrr: float = 0.008
    N_v: float = -0.137
    N_r: float = -0.049
    N_vvv: float = -0.030
    N_vvr: float = -0.294
    N_vrr: float = 0.055
    N_rrr: float = -0.013
    # propeller (Table 3)
    t_P: float = 0.220
    w_P0: float = 0.40
    x_P: float = -0.48
    C1: float = 2.0
    C2_plus: float = 1.6
    C2_minus: float = 1.1
    k0: float = 0.2931
    k1: float = -0.2753
    k2: float = -0.1385
    # rudder (Table 4)
    t_R: float = 0.387
    a_H: float = 0.312
    x_H: float = -0.464
    x_R: float = -0.500
    gamma_minus: float = 0.395
    gamma_plus: float = 0.640
    l_R: float = -0.710
    epsilon: float = 1.09
    kappa: float = 0.50
    f_alpha: float = 2.747


@dataclass(frozen=True)
class MMGShip:
    """Dimensional KVLCC2 at one scale. ``scale`` = lambda (1 full scale, 45.7 the 7 m model)."""

    scale: float
    L: float
    B: float
    d: float
    volume: float
    x_G: float
    D_p: float
    H_R: float
    A_R: float
    U0: float  # approach speed, m/s
    rudder_rate: float  # rad/s (2.32 deg/s at full scale)
    rudder_max: float  # rad
    A_F: float  # frontal and lateral windage areas, m^2
    A_L: float
    # Isherwood's (1972) other above-water particulars: length overall, superstructure lateral
    # area, perimeter of the lateral projection (without the waterline), its centroid's
    # distance from the bow, mast groups
    L_oa: float = 0.0
    A_SS: float = 0.0
    S_perimeter: float = 0.0
    C_centroid: float = 0.0
    masts: int = 1
    c: Coefficients = field(default_factory=Coefficients)
    thrust_factor: float = 1.0  # 0.8 = 20 % thrust loss (K_T scaled: thrust and slipstream)
    extra_N_rr: float = 0.0  # extra yaw damping N' += extra_N_rr r'|r'| (a concealed effect)

    @property
    def mass(self) -> float:
        return RHO * self.volume

    @property
    def time_scale(self) -> float:
        """Seconds of this ship per second of the full-scale ship (1/sqrt(lambda))."""
        return 1.0 / np.sqrt(self.scale)

    def mass_matrix(self) -> np.ndarray:
        """(4) left-hand side about midship, dimensional."""
        q = 0.5 * RHO * self.L**2 * self.d
        m, xg = self.mass, self.x_G
        mx, my, jz = self.c.m_x * q, self.c.m_y * q, self.c.J_z * q * self.L**2
        izg = m * (0.25 * self.L) ** 2  # radius of gyration 0.25 L (Yasukawa & Yoshimura 2015, Table 1)
        return np.array([[m + mx, 0.0, 0.0], [0.0, m + my, xg * m], [0.0, xg * m, izg + xg**2 * m + jz]])


def kvlcc2(scale: float = 1.0) -> MMGShip:
    """KVLCC2 at scale 1:``scale`` (1 = full scale 320 m; 45.7 = the 7 m model of the paper).

    Full-scale particulars (Yasukawa & Yoshimura 2015, Table 1): L = 320 m, B = 58 m,
    d = 20.8 m, displacement 312 600 m^3, x_G = 11.2 m, D_P = 9.86 m, H_R = 15.80 m,
    A_R = 112.5 m^2, 15.5 kn. Rudder rate 2.32 deg/s (SIMMAN 2008). Windage (not in the paper;
    an estimate for the loaded tanker: 9.2 m freeboard, 30 m depth, plus the superstructure):
    A_F = 1 130 m^2, A_L = 3 950 m^2, L_oa 325 m, superstructure 900 m^2 (a 40 m x 22 m
    accommodation block), perimeter 400 m, centroid 180 m from the bow (the block aft), one mast group.
    """
    s = float(scale)
    return MMGShip(
        scale=s,
        L=320.0 / s,
        B=58.0 / s,
        d=20.8 / s,
        volume=312600.0 / s**3,
        x_G=11.2 / s,
        D_p=9.86 / s,
        H_R=15.80 / s,
        A_R=112.5 / s**2,
        U0=7.97 / np.sqrt(s),
        rudder_rate=np.radians(2.32) * np.sqrt(s),
        rudder_max=np.radians(35.0),
        A_F=1130.0 / s**2,
        A_L=3950.0 / s**2,
        L_oa=325.0 / s,
        A_SS=900.0 / s**2,
        S_perimeter=400.0 / s,
        C_centroid=180.0 / s,
    )


def with_effects(ship: MMGShip, *, thrust_factor: float | None = None, extra_N_rr: float | None = None, **coef: float) -> MMGShip:
    """The ship with changed physics (thrust loss, extra yaw damping, changed hull coefficients)."""
    out = ship
    if coef:
        out = replace(out, c=replace(out.c, **coef))
    if thrust_factor is not None:
        out = replace(out, thrust_factor=thrust_factor)
    if extra_N_rr is not None:
        out = replace(out, extra_N_rr=extra_N_rr)
    return out


def to_recorded_delta(delta_mmg):
    """MMG rudder angle (positive turns to starboard) -> the shiptrial/MARIN convention (positive turns to port)."""
    return -np.asarray(delta_mmg)


def propeller(ship: MMGShip, u, v, r, n):
    """(13)-(16): thrust coefficient, advance ratio, 1 - w_P and X_P."""
    c = ship.c
    U = np.sqrt(u**2 + v**2)
    Us = np.maximum(U, 1e-9)
    beta = np.arctan2(-v, u)
    r_ = r * ship.L / Us
    beta_p = beta - c.x_P * r_
    C2 = np.where(beta_p > 0, c.C2_plus, c.C2_minus)
    one_w = (1.0 - c.w_P0) * (1.0 + (1.0 - np.exp(-c.C1 * np.abs(beta_p))) * (C2 - 1.0))
    ns = np.where(np.abs(n) > 1e-9, n, 1e-9)
    J = u * one_w / (ns * ship.D_p)
    KT = ship.thrust_factor * (c.k0 + c.k1 * J + c.k2 * J**2)
    XP = (1.0 - c.t_P) * RHO * n**2 * ship.D_p**4 * KT
    return KT, J, one_w, XP


def hull_forces(ship: MMGShip, u, v, r):
    """(10)-(12) X_H, Y_H, N_H (plus the optional extra yaw damping)."""
    c = ship.c
    U = np.sqrt(u**2 + v**2)
    Us = np.maximum(U, 1e-9)
    vp, rp = v / Us, r * ship.L / Us
    q = 0.5 * RHO * ship.L * ship.d * U**2
    X = q * (-c.R_0 + c.X_vv * vp**2 + c.X_vr * vp * rp + c.X_rr * rp**2 + c.X_vvvv * vp**4)
    Y = q * (c.Y_v * vp + c.Y_r * rp + c.Y_vvv * vp**3 + c.Y_vvr * vp**2 * rp + c.Y_vrr * vp * rp**2 + c.Y_rrr * rp**3)
    N = (
        q
        * ship.L
        * (
            c.N_v * vp
            + c.N_r * rp
            + c.N_vvv * vp**3
            + c.N_vvr * vp**2 * rp
            + c.N_vrr * vp * rp**2
            + c.N_rrr * rp**3
            + ship.extra_N_rr * rp * np.abs(rp)
        )
    )
    return X, Y, N


def rudder_forces(ship: MMGShip, u, v, r, delta, KT, J, one_w):
    """(17)-(27) X_R, Y_R, N_R with flow straightening and the propeller slipstream."""
    c = ship.c
    U = np.sqrt(u**2 + v**2)
    Us = np.maximum(U, 1e-9)
    beta = np.arctan2(-v, u)
    beta_r = beta - c.l_R * r * ship.L / Us
    gamma = np.where(beta_r < 0, c.gamma_minus, c.gamma_plus)
    vR = U * gamma * beta_r
    eta = ship.D_p / ship.H_R
    Js = np.where(np.abs(J) > 1e-6, J, 1e-6)
    slip = np.sqrt(np.maximum(1.0 + 8.0 * KT / (np.pi * Js**2), 0.0))
    uR = c.epsilon * u * one_w * np.sqrt(eta * (1.0 + c.kappa * (slip - 1.0)) ** 2 + (1.0 - eta))
    alpha = delta - np.arctan2(vR, uR)
    FN = 0.5 * RHO * ship.A_R * (uR**2 + vR**2) * c.f_alpha * np.sin(alpha)
    return (
        -(1.0 - c.t_R) * FN * np.sin(delta),
        -(1.0 + c.a_H) * FN * np.cos(delta),
        -(c.x_R + c.a_H * c.x_H) * ship.L * FN * np.cos(delta),
    )


def wind_forces(ship: MMGShip, u, v, psi, wind_ne):
    """Isherwood (1972) loads of the wind (air velocity toward, north/east m/s) on a ship moving
    at (u, v) over ground with heading psi (``tests.physics.isherwood``)."""
    if wind_ne is None:
        z = np.zeros_like(u)
        return z, z, z
    cp, sp = np.cos(psi), np.sin(psi)
    uw = cp * wind_ne[0] + sp * wind_ne[1]
    vw = -sp * wind_ne[0] + cp * wind_ne[1]
    urw, vrw = u - uw, v - vw
    q = 0.5 * RHO_AIR * (urw**2 + vrw**2)
    g = -np.arctan2(vrw, urw)
    return isherwood.loads(_wind_curves(ship), q, g, ship.A_F, ship.A_L, ship.L_oa)


def _wind_curves(ship: MMGShip) -> np.ndarray:
    return isherwood.coefficient_curves(
        ship.L_oa, ship.B, ship.A_L, ship.A_F, ship.A_SS, ship.S_perimeter, ship.C_centroid, ship.masts
    )


@dataclass(frozen=True)
class Environment:
    current_ne: tuple[float, float] = (0.0, 0.0)  # water velocity toward, north/east m/s
    wind_ne: tuple[float, float] | None = None  # air velocity toward, north/east m/s (None: still air, not recorded)
    # gusts: the wind speed times (1 + g(t)), g a first-order Gauss-Markov process of this std
    # (turbulence intensity, 0.1-0.2 over the sea) and time constant (full-scale s), seeded
    gust: float = 0.0
    gust_time_s: float = 20.0
    # direction gusts: the wind turned by a Gauss-Markov angle of this std (rad), same time constant
    # (over the sea the lateral turbulence is about 0.8 of the longitudinal: 0.12 rad at 15 %)
    gust_dir: float = 0.0
    gust_seed: int = 0

    @property
    def air_ne(self) -> tuple[float, float]:
        """The air velocity the superstructure moves through (still air when there is no wind)."""
        return (0.0, 0.0) if self.wind_ne is None else self.wind_ne


def derivative(ship: MMGShip, Minv: np.ndarray, s: np.ndarray, delta, n, env: Environment) -> np.ndarray:
    """d/dt of s = (..., [x, y, psi, u_r, v_r, r]) (velocities relative to the water)."""
    x, y, psi, ur, vr, r = (s[..., i] for i in range(6))
    KT, J, one_w, XP = propeller(ship, ur, vr, r, n)
    XH, YH, NH = hull_forces(ship, ur, vr, r)
    XR, YR, NR = rudder_forces(ship, ur, vr, r, delta, KT, J, one_w)
    cp, sp = np.cos(psi), np.sin(psi)
    cn, ce = env.current_ne
    u = ur + cp * cn + sp * ce  # over ground
    v = vr - sp * cn + cp * ce
    # no wind is still air, not no air: the superstructure is dragged through it at the ship's own
    # speed (relative wind = -ship velocity in (10.8)-(10.11)); the MMG hull coefficients (captive
    # tank tests) hold no air resistance, which a full-scale prediction adds (ITTC 1978, C_AA)
    XW, YW, NW = wind_forces(ship, u, v, psi, np.asarray(env.air_ne, float))
    m, xg = ship.mass, ship.x_G
    q = 0.5 * RHO * ship.L**2 * ship.d
    mx, my = ship.c.m_x * q, ship.c.m_y * q
    rhs = np.stack(
        [XH + XR + XP + XW + (m + my) * vr * r + xg * m * r**2, YH + YR + YW - (m + mx) * ur * r, NH + NR + NW - xg * m * ur * r],
        axis=-1,
    )
    acc = rhs @ Minv.T
    return np.stack([u * cp - v * sp, u * sp + v * cp, r, acc[..., 0], acc[..., 1], acc[..., 2]], axis=-1)


def self_propulsion_rps(ship: MMGShip, speed: float | None = None) -> float:
    """Propeller rps that holds ``speed`` (default the approach speed) straight ahead: X = 0."""
    from scipy.optimize import brentq

    U = ship.U0 if speed is None else speed

    def surplus(n: float) -> float:
        s = np.array([0, 0, 0, U, 0.0, 0.0])
        return float(derivative(ship, np.eye(3), s, 0.0, n, Environment())[3])

    n_hi = 50.0 * np.sqrt(ship.scale)
    return float(brentq(surplus, 1e-3, n_hi, xtol=1e-10))
