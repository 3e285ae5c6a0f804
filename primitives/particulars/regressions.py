"""Published regressions of manoeuvring coefficients on a ship's main particulars.

Every function is pure and returns non-dimensional MMG coefficients (Yasukawa & Yoshimura 2015,
forces on 1/2 rho L d U^2, moments on 1/2 rho L^2 d U^2, masses on 1/2 rho L^2 d, inertia on
1/2 rho L^4 d; v' = v/U, r' = r L/U; x forward, y starboard, r positive to starboard).

- Hull forces, linear and non-linear: Kijima, Katsuno, Nakiri & Furukawa (1990), "On the
  manoeuvring performance of a ship with the parameter of loading condition", J. Soc. Naval
  Arch. Japan 168, eqs. for Y'_beta ... N'_beta_r_r at even keel (tau = 0); their hull model is
  in the drift angle beta = -v' with beta|beta| and r|r| terms, kept in that form here.
- Linear derivatives and added mass, the independent check: Clarke, Gedling & Hine (1983), "The
  application of manoeuvring criteria in hull design using linear theory", Trans. RINA 125,
  eqs. (9)-(16) (non-dimensional on L^2, converted here to L d).
- Surge cross terms: Yoshimura & Masumoto (2012), "Hydrodynamic database and manoeuvring
  prediction method with medium high-speed merchant ships and fishing vessels", MARSIM 2012,
  Table 3 (X'_vv, X'_vr, X'_rr, X'_vvvv).
- Hull-propeller-rudder interaction: Kijima et al. (1990) (1 - t_R, a_H, x'_H, eps and the flow-
  straightening gamma_R = -22.2 (Cb B/L)^2 + 0.02 Cb B/L + 0.68 with l'_R = -0.9); the linear form
  gamma_R = 2.06 Cb B/L + 0.14 found in some compilations is not Kijima's; kappa = 0.5 is assumed
  (KVLCC2's 0.50, Yasukawa & Yoshimura 2015, Table 4); rudder lift gradient of Fujii & Tuda (1961),
  f_alpha = 6.13 L/(L + 2.25).
- The wake ratio eps = (1 - w_R)/(1 - w_P) of fine hulls: Kijima's eps is a quadratic in Cb B/L
  whose maximum, 1.004, is at Cb B/L = 41.6 / (2 x 156.5) = 0.133; finer than that it falls (0.67
  at the Mariner's 0.086). There eps is Lee & Shin (1998), "The prediction of ship's manoeuvring
  performance in initial design stage", PRADS '98: eps = -2.3281 + 8.697 Cb - 3.78 k + 1.19 Cb^2
  + 292 k^2 - 81.51 Cb k with k = 2 d / L, clipped to lie between Kijima's value for the hull and
  Kijima's maximum. The clip keeps eps continuous across the switch (unclipped, eps jumped from
  1.004 to 1.25 for Cb 0.7, T/L 0.06 and to 2.3 for Cb 0.8, T/L 0.03 at a 0.5 % change of beam)
  and out of values no regression database supports (Lee & Shin give 1.36 for KVLCC2, captive
  1.09, and 2.46 for a shallow full hull, w_R = -0.5). The formula is transcribed second-hand (the
  mmgdynamics package, N. Paulig, which cites the paper and names "Suras and Sakir Bal (2019)",
  presumably Sukas, Kinaci & Bal 2019, Ocean Eng. 192, as its source of empirical formulas); the paper itself, its
  database and its stated range of validity were not available to us. The switch at Kijima's
  maximum and the clip are our rule (from the two formulas alone, fitted to no ship).
- Wake and thrust deduction: Taylor's w = 0.5 Cb - 0.05 (Harvald 1983, "Resistance and
  propulsion of ships", eq. 5.6.3), t = 0.6 w (ibid., single screw).
- Resistance: ITTC-1957 friction line C_F = 0.075 / (log10 Re - 2)^2, form factor of Watanabe
  (in Kijima et al. 1990) k = -0.095 + 25.6 Cb / ((L/B)^2 sqrt(B/d)), wetted surface of Denny-
  Mumford S = 1.7 L d + V / d.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

RHO = 1025.0  # sea water [kg/m^3]
MX_FRACTION = 0.05  # m'_x / m' of a merchant hull (see added_mass)
NU_WATER = 1.19e-6  # kinematic viscosity of sea water at 15 deg C [m^2/s] (ITTC 7.5-02-01-03)


@dataclass(frozen=True)
class Hull:
    """Main particulars that the hull regressions read [m, -]."""

    length: float
    beam: float
    draught: float
    cb: float

    @property
    def k(self) -> float:
        """Aspect ratio of the hull as a wing, 2 d / L (Kijima et al. 1990)."""
        return 2.0 * self.draught / self.length

    @property
    def cb_b_l(self) -> float:
        return self.cb * self.beam / self.length

    @property
    def volume(self) -> float:
        return self.cb * self.length * self.beam * self.draught

    @property
    def mass_nd(self) -> float:
        """m' = m / (1/2 rho L^2 d) = 2 Cb B / L."""
        return 2.0 * self.cb_b_l


def kijima_linear(h: Hull) -> dict[str, float]:
    """Linear hull derivatives of Kijima et al. (1990) in MMG v', r' form.

    Y'_beta = pi/2 k + 1.4 Cb B/L, Y'_r = m' + m'_x - 1.5 Cb B/L, N'_beta = k, N'_r = -0.54 k + k^2
    (beta = -v': Y'_v = -Y'_beta, N'_v = -N'_beta). m'_x = 0.05 m' (see :func:`added_mass`).
    """
    m, mx = h.mass_nd, added_mass(h)["mx"]
    return {
        "Yv": -(0.5 * math.pi * h.k + 1.4 * h.cb_b_l),
        "Yr": m + mx - 1.5 * h.cb_b_l,
        "Nv": -h.k,
        "Nr": -0.54 * h.k + h.k**2,
    }


def kijima_nonlinear(h: Hull) -> dict[str, float]:
    """Non-linear hull coefficients of Kijima et al. (1990), in their form
    Y' = ... + Y'_bb beta|beta| + Y'_rr r'|r'| + (Y'_bbr beta + Y'_brr r') beta r', likewise N',
    with beta = -v' (so the beta^2 r' term reads v'^2 r' and beta r'^2 reads -v' r'^2)."""
    d_b, cbl = h.draught / h.beam, h.cb_b_l
    return {
        "Ybb": 2.5 * d_b * (1.0 - h.cb) + 0.5,
        "Yrr": 0.343 * d_b * h.cb - 0.07,
        "Ybbr": 1.5 * d_b * h.cb - 0.65,
        "Ybrr": 5.95 * d_b * (1.0 - h.cb),
        "Nbb": -0.96 * d_b * (1.0 - h.cb) + 0.066,
        "Nrr": 0.5 * cbl - 0.09,
        "Nbbr": -(57.5 * cbl**2 - 18.4 * cbl + 1.6),
        "Nbrr": -(0.5 * d_b * h.cb - 0.05),
    }


def clarke_linear(h: Hull) -> dict[str, float]:
    """Linear derivatives and added masses of Clarke et al. (1983), eqs. (9)-(16), in MMG units.

    Clarke's derivatives are on 1/2 rho L^2 U (forces) and 1/2 rho L^3 U (moments) with
    c = pi (d/L)^2: -Y_v = c (1 + 0.40 Cb B/d), -Y_r = c (-1/2 + 2.2 B/L - 0.080 B/d),
    -N_v = c (1/2 + 2.4 d/L), -N_r = c (1/4 + 0.039 B/d - 0.56 B/L), -Y_vdot = c (1 + 0.16 Cb B/d
    - 5.1 (B/L)^2), -N_rdot = c (1/12 + 0.017 Cb B/d - 0.33 B/L). Multiplying by L/d gives the
    MMG normalisation; m'_y = -Y'_vdot, J'_z = -N'_rdot. Clarke's Y_r is the total sway force per
    unit yaw rate; the MMG hull force leaves (m + m_x) u r on the left-hand side (Yasukawa &
    Yoshimura 2015, eq. 4), so Y'_r(MMG) = Y'_r(Clarke) + m'_x (Y_v, N_v, N_r are unchanged).
    """
    c = math.pi * (h.draught / h.length) ** 2
    b_d, b_l, d_l = h.beam / h.draught, h.beam / h.length, h.draught / h.length
    to_mmg = h.length / h.draught
    return {
        "Yv": -c * (1.0 + 0.40 * h.cb * b_d) * to_mmg,
        "Yr": -c * (-0.5 + 2.2 * b_l - 0.080 * b_d) * to_mmg + MX_FRACTION * h.mass_nd,
        "Nv": -c * (0.5 + 2.4 * d_l) * to_mmg,
        "Nr": -c * (0.25 + 0.039 * b_d - 0.56 * b_l) * to_mmg,
        "my": c * (1.0 + 0.16 * h.cb * b_d - 5.1 * b_l**2) * to_mmg,
        "Jz": c * (1.0 / 12.0 + 0.017 * h.cb * b_d - 0.33 * b_l) * to_mmg,
    }


def added_mass(h: Hull) -> dict[str, float]:
    """m'_x, m'_y, J'_z: m'_y and J'_z of Clarke et al. (1983) eqs. (13), (16); m'_x = 0.05 m'
    (the customary estimate for merchant hulls, e.g. Yoshimura & Masumoto 2012)."""
    cl = clarke_linear(h)
    return {"mx": MX_FRACTION * h.mass_nd, "my": cl["my"], "Jz": cl["Jz"]}


def yoshimura_surge(h: Hull, my: float) -> dict[str, float]:
    """Surge hull coefficients of Yoshimura & Masumoto (2012), Table 3, with x_G = 0:
    X'_vv = 1.15 Cb B/L - 0.18, X'_vr - m'_y = -1.91 Cb B/L + 0.08, X'_rr = -0.085 Cb B/L + 0.008,
    X'_vvvv = -6.68 Cb B/L + 1.1."""
    c = h.cb_b_l
    return {"Xvv": 1.15 * c - 0.18, "Xvr": my - 1.91 * c + 0.08, "Xrr": -0.085 * c + 0.008, "Xvvvv": -6.68 * c + 1.1}


KIJIMA_EPS_PEAK = 41.6 / (2.0 * 156.5)  # Cb B/L of the maximum of Kijima et al. (1990)'s eps quadratic
KIJIMA_EPS_MAX = 41.6**2 / (4.0 * 156.5) - 1.76  # that maximum, 1.004


def kijima_eps(h: Hull) -> float:
    """eps = -156.5 (Cb B/L)^2 + 41.6 Cb B/L - 1.76 (Kijima et al. 1990)."""
    c = h.cb_b_l
    return -156.5 * c**2 + 41.6 * c - 1.76


def lee_shin_eps(h: Hull) -> float:
    """eps = -2.3281 + 8.697 Cb - 3.78 k + 1.19 Cb^2 + 292 k^2 - 81.51 Cb k, k = 2 d / L (Lee & Shin
    1998, as transcribed in the mmgdynamics package; see the module docstring)."""
    k = h.k
    return -2.3281 + 8.697 * h.cb - 3.78 * k + 1.19 * h.cb**2 + 292.0 * k**2 - 81.51 * h.cb * k


def fine_for_kijima_eps(h: Hull) -> bool:
    """True for a hull finer than the maximum of Kijima et al. (1990)'s eps quadratic in Cb B/L, where
    eps is taken from Lee & Shin (1998) instead (:func:`eps`)."""
    return h.cb_b_l < KIJIMA_EPS_PEAK


def eps(h: Hull) -> float:
    """The build's eps: Kijima et al. (1990) at and above the maximum of its quadratic; finer than
    that, Lee & Shin (1998) clipped to [Kijima's value, Kijima's maximum] (continuous at the switch)."""
    if not fine_for_kijima_eps(h):
        return kijima_eps(h)
    return min(max(lee_shin_eps(h), kijima_eps(h)), KIJIMA_EPS_MAX)


def eps_source(h: Hull) -> str:
    """The regression that gives this hull's eps (:func:`eps`), and the clip when it acts."""
    if not fine_for_kijima_eps(h):
        return "Kijima et al. (1990)"
    ls = lee_shin_eps(h)
    if ls > KIJIMA_EPS_MAX:
        return f"Lee & Shin (1998)'s {ls:.3f} cut to the maximum of Kijima et al. (1990)'s quadratic"
    if ls < kijima_eps(h):
        return f"Kijima et al. (1990), Lee & Shin (1998)'s lower {ls:.3f} raised to it"
    return "Lee & Shin (1998)"


def interaction(h: Hull) -> dict[str, float]:
    """Hull-propeller-rudder interaction coefficients (Kijima et al. 1990; Harvald 1983):
    1 - t_R = 0.28 Cb + 0.55, a_H = 0.627 Cb - 0.153, x'_H = -(0.4 + 0.1 Cb), gamma_R = -22.2 (Cb B/L)^2
    + 0.02 Cb B/L + 0.68, l'_R = -0.9, eps of :func:`eps` (Kijima's, or for hulls finer than its
    maximum Lee & Shin's, clipped); kappa = 0.5 (assumed, KVLCC2's value);
    w_P0 = 0.5 Cb - 0.05 (Taylor), t_P = 0.6 w_P0."""
    c = h.cb_b_l
    w = 0.5 * h.cb - 0.05
    return {
        "tR": 1.0 - (0.28 * h.cb + 0.55),
        "aH": 0.627 * h.cb - 0.153,
        "xH": -(0.4 + 0.1 * h.cb),
        "gammaR": -22.2 * c**2 + 0.02 * c + 0.68,
        "lR": -0.9,
        "eps": eps(h),
        "kappa": 0.5,
        "wP0": w,
        "tP": 0.6 * w,
    }


def rudder_lift_slope(aspect_ratio: float) -> float:
    """Rudder normal-force gradient f_alpha = 6.13 L / (L + 2.25) (Fujii & Tuda 1961; MMG eq. 22)."""
    return 6.13 * aspect_ratio / (aspect_ratio + 2.25)


def wetted_surface(h: Hull) -> float:
    """Denny-Mumford wetted surface S = 1.7 L d + V / d [m^2]."""
    return 1.7 * h.length * h.draught + h.volume / h.draught


def form_factor(h: Hull) -> float:
    """1 + k with Watanabe's k = -0.095 + 25.6 Cb / ((L/B)^2 sqrt(B/d)) (as cited by Kijima et al. 1990)."""
    return 1.0 + (-0.095 + 25.6 * h.cb / ((h.length / h.beam) ** 2 * math.sqrt(h.beam / h.draught)))


def friction_ittc57(speed: float, length: float, nu: float = NU_WATER) -> float:
    """ITTC-1957 model-ship correlation line C_F = 0.075 / (log10 Re - 2)^2."""
    re = max(speed, 1e-3) * length / nu
    return 0.075 / (math.log10(re) - 2.0) ** 2


def resistance_nd(h: Hull, speed: float, nu: float = NU_WATER) -> float:
    """Straight-ahead resistance R'_0 = (1 + k) C_F S / (L d), on 1/2 rho L d U^2 (friction and form
    only: the wave resistance of a displacement ship below Fn ~ 0.2 is a few per cent)."""
    return form_factor(h) * friction_ittc57(speed, h.length, nu) * wetted_surface(h) / (h.length * h.draught)


def twin_screw_interaction(h: Hull) -> dict[str, float]:
    """Wake, thrust deduction and eps of a ship with two off-centre screws (twin screws or pods):
    Taylor's twin-screw wake w_P0 = 0.55 Cb - 0.20 (Taylor 1943, "The speed and power of ships";
    at least 0), Schoenherr's twin-screw thrust deduction t_P = 0.7 w + 0.06 (open shafts on
    struts; Schoenherr 1939, Principles of Naval Architecture, as quoted in textbooks: its source
    was not available to us); eps = 1 (assumed: each rudder sits in its own screw's wake, off the
    centre line, so w_R is taken equal to w_P)."""
    w = max(0.55 * h.cb - 0.20, 0.0)
    return {"wP0": w, "tP": 0.7 * w + 0.06, "eps": 1.0}
