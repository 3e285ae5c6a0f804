"""Forces of a ship's two propulsion-steering units, for the MMG model of
:mod:`primitives.particulars.mmg` (Yasukawa & Yoshimura 2015, eqs. 13-27, applied per unit).

Twin screws, twin rudders (``layout = "twin"``): each side is a screw-rudder unit at
y = -+ y_unit L. Each screw sees the longitudinal speed of its own position, u - y r (the outer screw
of a turn runs lighter), through the hull's wake w_P; each rudder is the single-unit MMG rudder
(eqs. 17-27, area A_R / 2) in its own screw's slipstream; the thrust X_P,i and the rudder drag
X_R,i give the yaw moment -y_i X_i (Khanfir et al. 2011, "Mathematical model for maneuverability
and estimation of hydrodynamic coefficients of twin-propeller twin-rudder ship", J. Mar. Sci.
Technol.; its measured per-rudder interaction coefficients are not used). Assumed, not measured:
the two rudders do not disturb each other, both see the same flow straightening gamma_R and
hull-rudder interaction a_H, x'_H, t_R (Kijima et al. 1990's single-screw regressions), the
screws counter-rotate (no net side force).

Steerable pods (``layout = "pods"``): each pod turns its screw and its housing together by the
azimuth angle alpha (+ thrust to starboard). The screw's thrust T = rho n^2 D^4 K_T(J) acts along
the pod's axis, with J from the inflow along that axis, (1 - w_P) (u - y r) cos alpha + (v + x r)
sin alpha (the pod's velocity through the water at its position, as the podded-ship model of
Gierusz 2015 takes it); the thrust deduction t_P reduces its surge part. The housing (strut and
gondola) is a low-aspect foil in the screw's slipstream: the MMG rudder force (eqs. 17-27) with
delta = -alpha, eps = 1 (the housing sits in its own screw's wake and race), its lateral area and
lift gradient (Fujii & Tuda at aspect 1), the hull's flow straightening gamma_R, l'_R and
interaction a_H, x'_H as for a rudder. Pod-pod interaction is left out (as Gierusz 2015).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from primitives.particulars.regressions import RHO

# Two units (twin screws or pods) sit a quarter beam either side of the centre line (assumed:
# twin-screw ferries, naval ships and podded cruise ships have them at about 0.2-0.3 B).
UNIT_OFFSET_B = 0.25

# A pod's housing (strut and gondola) as a foil: lateral area 1.2 D^2 and span D (assumed: an
# Azipod-type pulling pod's gondola is about 2 D long and 0.4 D thick, its strut about D high).
HOUSING_AREA_D2 = 1.2

if TYPE_CHECKING:
    from primitives.particulars.mmg import MMGShip


def _shafts(n: float | tuple[float, float]) -> tuple[float, float]:
    """(port, starboard) shaft speeds."""
    return (float(n), float(n)) if np.isscalar(n) else (float(n[0]), float(n[1]))


def screw_thrust(ship: MMGShip, n: float, u_a: float) -> float:
    """Open-water thrust [N] of one screw at shaft speed n [rev/s] and inflow u_a [m/s] (eq. 14-15),
    written without J so that n = 0 is not singular."""
    D = ship.prop_diameter
    k0, k1, k2 = ship.kt
    return RHO * D**4 * (k0 * n * abs(n) + k1 * n * u_a / D + k2 * u_a * abs(u_a) / D**2)


def unit_forces(
    ship: MMGShip, nu: np.ndarray, delta: float, n: float | tuple[float, float], U: float, beta: float, rp: float
) -> tuple[float, float, float]:
    """X, Y, N [N, N, N m] of both units (propellers and rudders, or pods)."""
    u, v, r = nu
    L = ship.length
    xs = ys = ns = 0.0
    for side, n_i in zip((-1.0, 1.0), _shafts(n)):
        y = side * ship.y_unit * L
        u_local = u - y * r
        if ship.layout == "twin":
            xp, u_p = ship.propeller_force(u_local, n_i, beta, rp)
            xr, yr, nr = ship.rudder_forces(delta, n_i, u_p, U, beta, rp)
            x_i, y_i, n_moment = xp + xr, yr, nr
        else:
            x_i, y_i, n_moment = _pod(ship, delta, n_i, u_local, v + ship.x_p * L * r, U, beta, rp)
        xs, ys, ns = xs + x_i, ys + y_i, ns + n_moment - y * x_i
    return xs, ys, ns


def _pod(ship: MMGShip, delta: float, n: float, u_local: float, v_local: float, U: float, beta: float, rp: float):
    """X, Y, N [N, N, N m] (N about midship, before the -y X arm) of one pod steered to ``delta``
    (alpha = -delta): thrust along the axis plus the housing as a foil (module docstring)."""
    it = ship.inter
    alpha = -delta
    ca, sa = math.cos(alpha), math.sin(alpha)
    u_axis = (1.0 - it["wP0"]) * u_local * ca + v_local * sa
    thrust = screw_thrust(ship, n, u_axis)
    fx, fy = (1.0 - it["tP"]) * thrust * ca, thrust * sa
    scale = it.get("housing", 1.0)
    xh, yh, nh = (scale * f for f in ship.rudder_forces(delta, n, max(u_axis, 0.0), U, beta, rp, eps=1.0))
    return fx + xh, fy + yh, ship.x_p * ship.length * fy + nh
