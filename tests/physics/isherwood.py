"""Wind loads on a merchant ship from Isherwood (1972), the battery truth's wind (issue 26).

R. M. Isherwood (1972), Wind resistance of merchant ships, Trans. RINA 115, 327-338: a multiple
regression over wind-tunnel tests of merchant ships, tabulated every 10 deg of the relative wind
angle g (0 = from ahead, 180 = from astern):

    C_X = -(A0 + A1 2 A_L/L^2 + A2 2 A_F/B^2 + A3 L/B + A4 S/L + A5 C/L + A6 M)
    C_Y =   B0 + B1 2 A_L/L^2 + B2 2 A_F/B^2 + B3 L/B + B4 S/L + B5 C/L + B6 A_SS/A_L
    C_N =   C0 + C1 2 A_L/L^2 + C2 2 A_F/B^2 + C3 L/B + C4 S/L + C5 C/L

X = C_X q A_F, Y = C_Y q A_L, N = C_N q A_L L, q = rho_a V_rw^2 / 2 (L overall, B beam, A_F, A_L
frontal and lateral projected areas, A_SS the superstructure's lateral area, S the perimeter of
the lateral projection without the waterline, C the distance of its centroid from the bow, M the
number of mast groups). Signs as in Blendermann (1994) / Fossen (2021, section 10.1): the
coefficients of a wind from port (g > 0); a wind from starboard mirrors C_Y and C_N. Linear
interpolation between the 10-deg rows, as the table is used in practice.

This is test physics: it shares no code with ``diagnose`` (whose wind candidate uses
Blendermann's (1994) closed form, a different published fit).
"""

from __future__ import annotations

import numpy as np

# Isherwood (1972), Table (A0..A6 per 10 deg, 0..180 deg)
_A = np.array(
    [
        [2.152, -5.00, 0.243, -0.164, 0, 0, 0],
        [1.714, -3.33, 0.145, -0.121, 0, 0, 0],
        [1.818, -3.97, 0.211, -0.143, 0, 0, 0.033],
        [1.965, -4.81, 0.243, -0.154, 0, 0, 0.041],
        [2.333, -5.99, 0.247, -0.190, 0, 0, 0.042],
        [1.726, -6.54, 0.189, -0.173, 0.348, 0, 0.048],
        [0.913, -4.68, 0, -0.104, 0.482, 0, 0.052],
        [0.457, -2.88, 0, -0.068, 0.346, 0, 0.043],
        [0.341, -0.91, 0, -0.031, 0, 0, 0.032],
        [0.355, 0, 0, 0, -0.247, 0, 0.018],
        [0.601, 0, 0, 0, -0.372, 0, -0.020],
        [0.651, 1.29, 0, 0, -0.582, 0, -0.031],
        [0.564, 2.54, 0, 0, -0.748, 0, -0.024],
        [-0.142, 3.58, 0, 0.047, -0.700, 0, -0.028],
        [-0.677, 3.64, 0, 0.069, -0.529, 0, -0.032],
        [-0.723, 3.14, 0, 0.064, -0.475, 0, -0.032],
        [-2.148, 2.56, 0, 0.081, 0, 1.27, -0.027],
        [-2.707, 3.97, -0.175, 0.126, 0, 1.81, 0],
        [-2.529, 3.76, -0.174, 0.128, 0, 1.55, 0],
    ]
)
# B0..B6
_B = np.array(
    [
        [0, 0, 0, 0, 0, 0, 0],
        [0.096, 0.22, 0, 0, 0, 0, 0],
        [0.176, 0.71, 0, 0, 0, 0, 0],
        [0.225, 1.38, 0, 0.023, 0, -0.29, 0],
        [0.329, 1.82, 0, 0.043, 0, -0.59, 0],
        [1.164, 1.26, 0.121, 0, -0.242, -0.95, 0],
        [1.163, 0.96, 0.101, 0, -0.177, -0.88, 0],
        [0.916, 0.53, 0.069, 0, 0, -0.65, 0],
        [0.844, 0.55, 0.082, 0, 0, -0.54, 0],
        [0.889, 0, 0.138, 0, 0, -0.66, 0],
        [0.799, 0, 0.155, 0, 0, -0.55, 0],
        [0.797, 0, 0.151, 0, 0, -0.55, 0],
        [0.996, 0, 0.184, 0, -0.212, -0.66, 0.34],
        [1.014, 0, 0.191, 0, -0.280, -0.69, 0.44],
        [0.784, 0, 0.166, 0, -0.209, -0.53, 0.38],
        [0.536, 0, 0.176, -0.029, -0.163, 0, 0.27],
        [0.251, 0, 0.106, -0.022, 0, 0, 0],
        [0.125, 0, 0.046, -0.012, 0, 0, 0],
        [0, 0, 0, 0, 0, 0, 0],
    ]
)
# C0..C5
_C = np.array(
    [
        [0, 0, 0, 0, 0, 0],
        [0.0596, 0.061, 0, 0, 0, -0.074],
        [0.1106, 0.204, 0, 0, 0, -0.170],
        [0.2258, 0.245, 0, 0, 0, -0.380],
        [0.2017, 0.457, 0, 0.0067, 0, -0.472],
        [0.1759, 0.573, 0, 0.0118, 0, -0.523],
        [0.1925, 0.480, 0, 0.0115, 0, -0.546],
        [0.2133, 0.315, 0, 0.0081, 0, -0.526],
        [0.1827, 0.254, 0, 0.0053, 0, -0.443],
        [0.2627, 0, 0, 0, 0, -0.508],
        [0.2102, 0, -0.0195, 0, 0.0335, -0.492],
        [0.1567, 0, -0.0258, 0, 0.0497, -0.457],
        [0.0801, 0, -0.0311, 0, 0.0740, -0.396],
        [-0.0189, 0, -0.0488, 0.0101, 0.1128, -0.420],
        [0.0256, 0, -0.0422, 0.0100, 0.0889, -0.463],
        [0.0552, 0, -0.0381, 0.0109, 0.0689, -0.476],
        [0.0881, 0, -0.0306, 0.0091, 0.0366, -0.415],
        [0.0851, 0, -0.0122, 0.0025, 0, -0.220],
        [0, 0, 0, 0, 0, 0],
    ]
)
_ANGLES = np.radians(np.arange(0.0, 181.0, 10.0))


def coefficient_curves(Loa: float, B: float, A_L: float, A_F: float, A_SS: float, S: float, C: float, M: float) -> np.ndarray:
    """(3, 19) C_X, C_Y, C_N at 0, 10, ..., 180 deg for a ship's above-water particulars."""
    feats = np.array([1.0, 2 * A_L / Loa**2, 2 * A_F / B**2, Loa / B, S / Loa, C / Loa])
    cx = -(_A @ np.append(feats, M))
    cy = _B @ np.append(feats, A_SS / A_L if A_L > 0 else 0.0)  # no windage: loads are zero anyway
    cn = _C @ feats
    return np.stack([cx, cy, cn])


def loads(curves: np.ndarray, q: np.ndarray, gamma: np.ndarray, A_F: float, A_L: float, Loa: float):
    """X, Y, N (N, N m) for dynamic pressure ``q`` and relative wind angle ``gamma`` (rad, any
    range; positive from port), from :func:`coefficient_curves`."""
    g = np.angle(np.exp(1j * np.asarray(gamma, float)))  # -pi..pi
    a, side = np.abs(g), np.sign(g)
    cx = np.interp(a, _ANGLES, curves[0])
    cy = side * np.interp(a, _ANGLES, curves[1])
    cn = side * np.interp(a, _ANGLES, curves[2])
    return q * A_F * cx, q * A_L * cy, q * A_L * Loa * cn
