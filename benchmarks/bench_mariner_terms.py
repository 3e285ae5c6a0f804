"""Why the Mariner built from its particulars turns too wide (issue 31's second ship): its MMG
model (primitives.particulars) term by term against the Mariner's planar-motion-mechanism model
(Chislett & Strom-Tejsen 1965, benchmarks/mariner_pmm.py), and the 35 deg tactical diameter of
the MMG model with one group of coefficients replaced at a time.

    python benchmarks/bench_mariner_terms.py

1. Linearised forces of the whole MMG model (hull + rudder + screw) at the approach, in the PMM's
   normalisation (1/2 rho L^2 U^2, 1/2 rho L^3 U^2, r' = r L / U), next to the PMM's derivatives.
   The PMM's Y_r and N_r are totals that include -m' and -m' x_G; our MMG model keeps (m + m_x) u r
   on the left-hand side and has x_G = 0, so our Y_r is shown as Y_r - m' - m'_x and our N_r as is.
2. The rudder's inflow: the terms of the MMG rudder model (Yasukawa & Yoshimura 2015, eqs. 17-27).
3. One substitution at a time: the PMM's linear hull derivatives (its totals less our rudder's
   share, Y_r + m' + m'_x, N_r as is), the non-linear hull terms off, eps of each regression
   (the build takes Lee & Shin (1998)'s, clipped to [Kijima's value, Kijima's maximum 1.004], below
   the maximum of Kijima et al. (1990)'s quadratic at Cb B/L 0.133; Kijima's, 0.666 here, is what
   the build used before), and the interaction
   coefficients of the training ship Seiun Maru (L 105 m, Cb 0.508, Cb B/L 0.087, close to the
   Mariner's 0.086) from the table of calibrated vessels in the mmgdynamics package
   (calibrated_vessels.py), which cites Yoshimura & Masumoto (2012), MARSIM 2012, for the vessel and
   Quadvlieg (2013) for a_H: gamma_R 0.394 / 0.312 (mean 0.353), l'_R -0.947, a_H 0.236, t_R 0.341,
   kappa 0.676, eps 1.033. That eps is not a measurement: Lee & Shin's formula as the same package
   transcribes it gives 1.0329 at the Seiun Maru's particulars. Kijima's eps constant appears as
   -156.5 (ours) and -156.2 (another public transcription); both are shown.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import mariner_pmm as mp  # noqa: E402

from primitives.particulars import regressions as rg  # noqa: E402
from primitives.particulars.build import Particulars, approach_rps, mmg_ship  # noqa: E402
from primitives.particulars.mmg import MMGShip, fixed_helm, run  # noqa: E402
from primitives.particulars.trials import turn_figures  # noqa: E402

MARINER = Particulars("mariner", mp.L, mp.B, mp.T, mp.CB, 15.0)
SEIUN_MARU = {"eps": 1.033, "gammaR": 0.5 * (0.394 + 0.312), "lR": -0.947, "aH": 0.236, "tR": 0.341, "kappa": 0.676}
SEIUN_MARU_HULL = rg.Hull(105.0, 17.91, 5.966, 0.508)


def tactical(ship: MMGShip, p: Particulars = MARINER) -> float:
    """35 deg tactical diameter [m] of an MMG model from a steady approach at p.speed (1 s steps, 2.32 deg/s)."""
    n0 = approach_rps(ship, p.speed)
    r = run(ship, "tc", fixed_helm(math.radians(35), n0), p.speed, 3000, 1.0, math.radians(2.32), math.radians(35))
    return turn_figures(np.column_stack([r.xy, r.psi]))[1]


def linearised(ship: MMGShip, p: Particulars = MARINER) -> dict[str, tuple[float, float]]:
    """(total, rudder share) of d(Y, N)/d(v', r', delta) at the approach, in the PMM's units x 1e5."""
    U, L = p.speed, p.length
    n0 = approach_rps(ship, U)
    q = 0.5 * rg.RHO * L**2 * U**2

    def forces(v: float, r: float, delta: float) -> np.ndarray:
        vp, rp = v / U, r * L / U
        _, yh, nh = ship.hull_forces(vp, rp, U)
        _, u_p = ship.propeller_force(U, n0, -vp, rp)
        _, yr, nr = ship.rudder_forces(delta, n0, u_p, U, -vp, rp)
        return np.array([yh + yr, (nh + nr) / L, yr, nr / L]) / q

    e, f0, out = 1e-4, forces(0, 0, 0), {}
    for name, args in (("v", (e * U, 0, 0)), ("r", (0, e * U / L, 0)), ("delta", (0, 0, e))):
        d = (forces(*args) - f0) / e * 1e5
        out[f"Y_{name}"], out[f"N_{name}"] = (d[0], d[2]), (d[1], d[3])
    return out


def main() -> None:
    p, ship = MARINER, mmg_ship(MARINER, 0.75)
    m_pmm = 2 * p.cb * p.beam * p.draught / p.length**2 * 1e5  # m / (1/2 rho L^3) x 1e5
    mx_pmm = ship.mass["mx"] * p.draught / p.length * 1e5  # m'_x from MMG (1/2 rho L^2 T) to PMM units
    lin = linearised(ship)
    # the PMM's rudder sign is reversed in mariner_pmm (positive delta to starboard): Y_delta -278, N_delta +139
    pmm = {"Y_v": mp.Y["v"], "Y_r": mp.Y["r"], "N_v": mp.N["v"], "N_r": mp.N["r"], "Y_delta": -mp.Y["d"], "N_delta": -mp.N["d"]}
    print("1. linearised forces at the approach, x 1e-5 (PMM units; ours Y_r - m' - m'_x, N_r as is: x_G = 0)")
    print(f"   {'term':8s} {'ours':>8s} {'of it rudder':>13s} {'PMM':>8s} {'ours/PMM':>9s}")
    for k, (tot, rud) in lin.items():
        tot_cmp = tot - m_pmm - mx_pmm if k == "Y_r" else tot
        print(f"   {k:8s} {tot_cmp:8.0f} {rud:13.0f} {pmm[k]:8.0f} {tot_cmp / pmm[k]:9.2f}")
    it = ship.inter
    print("2. the rudder model's terms (Yasukawa & Yoshimura 2015, eqs. 17-27) for the Mariner:")
    print(
        f"   A_R {ship.rudder_area:.1f} m^2 (DNV rule guidance, A_R/(L T) = 1/{p.length * p.draught / ship.rudder_area:.1f}), "
        f"f_alpha {ship.f_alpha:.2f}, a_H {it['aH']:.3f}, screw {ship.prop_diameter:.2f} m (0.6 T), w_P0 {it['wP0']:.3f}"
    )
    kv = rg.Hull(320, 58, 20.8, 0.81)
    c = p.hull.cb_b_l
    print(
        f"   eps = (1 - w_R)/(1 - w_P) at Cb B/L {c:.4f}, k = 2T/L {p.hull.k:.4f}: Lee & Shin (1998) {rg.lee_shin_eps(p.hull):.3f}"
        f" (built: {rg.eps(p.hull):.3f}, {rg.eps_source(p.hull)}); Kijima et al. (1990) {rg.kijima_eps(p.hull):.3f} (-156.5) / {-156.2 * c * c + 41.6 * c - 1.76:.3f} (-156.2)"
    )
    print(
        f"   Seiun Maru: Lee & Shin {rg.lee_shin_eps(SEIUN_MARU_HULL):.4f} (mmgdynamics tabulates 1.033), Kijima "
        f"{rg.kijima_eps(SEIUN_MARU_HULL):.3f}; KVLCC2 (captive 1.09): Kijima {rg.kijima_eps(kv):.3f} (built), "
        f"Lee & Shin {rg.lee_shin_eps(kv):.3f}"
    )
    y_d = linearised(dataclasses.replace(ship, inter=it | {"eps": SEIUN_MARU["eps"]}))["Y_delta"][0]
    print(f"   with eps {SEIUN_MARU['eps']}: Y_delta {y_d:.0f} (x 1e-5, {y_d / pmm['Y_delta']:.2f} of the PMM's)")
    ref = [mp_turn(s) for s in (1.0, -1.0)]
    print(f"3. 35 deg tactical diameter of the MMG model, one substitution at a time (PMM model: {ref[0]:.0f} / {ref[1]:.0f} m):")
    rep = dataclasses.replace
    k = p.length / p.draught * 1e-5
    rud = {name: lin[name][1] for name in ("Y_v", "Y_r", "N_v", "N_r")}
    pmm_hull = {  # the PMM's totals less our rudder's share, in MMG units ((m + m_x) u r moved left; x_G = 0)
        "Yv": (mp.Y["v"] - rud["Y_v"]) * k,
        "Yr": (mp.Y["r"] + m_pmm + mx_pmm - rud["Y_r"]) * k,
        "Nv": (mp.N["v"] - rud["N_v"]) * k,
        "Nr": (mp.N["r"] - rud["N_r"]) * k,
    }
    nonlin = ("Ybb", "Yrr", "Ybbr", "Ybrr", "Nbb", "Nrr", "Nbbr", "Nbrr")
    cases = {
        "as built (regressions)": ship,
        "linear hull: the PMM's": rep(ship, hull=ship.hull | pmm_hull),
        "non-linear hull terms off": rep(ship, hull=ship.hull | {x: 0.0 for x in nonlin}),
        "eps: Kijima (1990)'s (the build before)": rep(ship, inter=it | {"eps": rg.kijima_eps(p.hull)}),
        **{f"{k_}: Seiun Maru's {v:.3g}": rep(ship, inter=it | {k_: v}) for k_, v in SEIUN_MARU.items()},
        "all six Seiun Maru interaction values": rep(ship, inter=it | SEIUN_MARU),
        "rudder area x 1.5": rep(ship, rudder_area=1.5 * ship.rudder_area),
        "screw 0.8 T": rep(ship, prop_diameter=0.8 * p.draught),
    }
    for name, s in cases.items():
        td = tactical(s)
        print(f"   {name:40s} {td:6.0f} m  {td / p.length:5.2f} L  {100 * (td - ref[0]) / ref[0]:+6.1f} % vs PMM")


def mp_turn(side: float) -> float:
    track, _ = mp.simulate(lambda k, psi: side * math.radians(35), 3000, 1.0, math.radians(2.32))
    return turn_figures(track)[1]


if __name__ == "__main__":
    main()
