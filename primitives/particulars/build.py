"""A profile from a ship's main particulars: regressions -> MMG model -> simulated standard and
excitation manoeuvres -> the profile's per-sample model fitted to them -> TOML with the source of
every coefficient and a prior spread per coefficient.

    from primitives.particulars.build import Particulars, build_profile
    built = build_profile(Particulars("my-ship", 320, 58, 20.8, 0.81, 15.5, rudder_area=142, prop_diameter=9.86))
    built.text  # the TOML document; built.profile the loaded ShipProfile
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace

import numpy as np

from primitives.particulars import regressions as rg
from primitives.particulars.document import header, profile_document, split, toml_text
from primitives.particulars.fit import balance_thrust, excitation_runs, fit_profile, one_step_ls
from primitives.particulars.inputs import KNOT, Particulars, ParticularsError, check_particulars
from primitives.particulars.mmg import MMGShip
from primitives.particulars.propeller import BSeries
from primitives.particulars.units import HOUSING_AREA_D2, UNIT_OFFSET_B
from primitives.profile_document import profile_from_dict
from primitives.ship import ShipProfile

__all__ = ["Built", "Particulars", "ParticularsError", "build_profile"]

SHAFT_EFFICIENCY = 0.97  # delivered / brake power, shaft and gearing losses (Harvald 1983)

RUDDER_ASPECT = 1.8  # geometric aspect ratio of a spade/semi-spade rudder when the span is not given

LINEAR = ("Yv", "Yr", "Nv", "Nr")  # Clarke et al. (1983); the non-linear hull terms are Kijima et al. (1990)


@dataclass
class Built:
    """The generated profile: TOML text, the loaded profile, the MMG model behind it and notes."""

    text: str
    profile: ShipProfile
    mmg: MMGShip
    approach_rps: float
    notes: list[str] = field(default_factory=list)


# -- the MMG model --------------------------------------------------------------


def rule_rudder_area(p: Particulars) -> float:
    """Rudder area from the DNV rule guidance A_R = T L / 100 (1 + 25 (B/L)^2) [m^2] (DNV Rules for
    Ships, Pt. 3 Ch. 3 Sec. 2, A 200), when the user gives none."""
    return p.draught * p.length / 100.0 * (1.0 + 25.0 * (p.beam / p.length) ** 2)


def mmg_ship(p: Particulars, pitch_ratio: float) -> MMGShip:
    """The MMG model of the particulars (regressions in :mod:`primitives.particulars.regressions`)."""
    h = p.hull
    diameter = p.prop_diameter or default_diameter(p)
    area = p.rudder_area or rule_rudder_area(p)
    inter = rg.interaction(h)
    layout, y_unit = "single", 0.0
    if p.actuator != "rudder_propeller":
        layout, y_unit = ("twin" if p.actuator == "twin_screw" else "pods"), UNIT_OFFSET_B * p.beam / p.length
        inter |= rg.twin_screw_interaction(h)
    if p.actuator == "twin_screw":
        area /= 2.0  # each rudder
    if p.actuator == "azimuth":
        area, span = HOUSING_AREA_D2 * diameter**2, diameter
        inter["housing"] = 1.0  # scale of the housing's force (its prior spread)
    else:
        span = min(math.sqrt(RUDDER_ASPECT * area), 0.8 * p.draught)
    mass = rg.added_mass(h)
    linear = {k: v for k, v in rg.clarke_linear(h).items() if k in LINEAR}
    hull = {"R0": rg.resistance_nd(h, p.speed)} | rg.yoshimura_surge(h, mass["my"]) | linear | rg.kijima_nonlinear(h)
    return MMGShip(
        length=p.length,
        draught=p.draught,
        volume=h.volume,
        hull=hull,
        mass=mass,
        inter=inter,
        prop_diameter=diameter,
        kt=BSeries(pitch_ratio).quadratic_fit(),
        rudder_area=area,
        rudder_span=span,
        f_alpha=rg.rudder_lift_slope(span**2 / area),
        layout=layout,
        y_unit=y_unit,
    )


def default_diameter(p: Particulars) -> float:
    """Screw diameter when not given: 0.6 x the draught (single-screw merchant ships: 0.45-0.75)."""
    return 0.6 * p.draught


def approach_rps(ship: MMGShip, speed: float) -> float:
    """Shaft speed [rev/s] at which the MMG model's thrust balances its resistance at ``speed``
    on a straight course (eq. 4, u' = 0 with v = r = delta = 0): a quadratic in n (eq. 15)."""
    D, t, w = ship.prop_diameter, ship.inter["tP"], ship.inter["wP0"]
    k0, k1, k2 = ship.kt
    up = (1.0 - w) * speed
    resist = 0.5 * rg.RHO * ship.length * ship.draught * speed**2 * ship.hull["R0"] / ship.units  # per screw
    a, b, c = k0 * D**4, k1 * up * D**3, k2 * up**2 * D**2 - resist / (rg.RHO * (1.0 - t))
    return (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)


def delivered_power_kw(ship: MMGShip, pitch_ratio: float, speed: float, n: float) -> float:
    """P_D = 2 pi rho n^3 D^5 K_Q(J) [kW] at the approach (B-series torque, Oosterveld & van Oossanen 1975),
    summed over the ship's screws."""
    D = ship.prop_diameter
    j = (1.0 - ship.inter["wP0"]) * speed / (n * D)
    return ship.units * 2.0 * math.pi * rg.RHO * n**3 * D**5 * float(BSeries(pitch_ratio).kq(j)) / 1000.0


def _pitch_for_rpm(p: Particulars) -> float:
    """The B-series pitch ratio at which the given rpm makes the given speed (bisection on P/D)."""
    lo, hi = 0.5, 1.4
    n_target = p.rpm / 60.0
    n_at = [approach_rps(mmg_ship(p, x), p.speed) for x in (lo, hi)]
    if not n_at[1] <= n_target <= n_at[0]:
        raise ParticularsError(
            f"--rpm {p.rpm:g}: a B-series screw of {mmg_ship(p, lo).prop_diameter:.3g} m makes {p.speed_kn:g} kn at "
            f"{60 * n_at[1]:.0f}-{60 * n_at[0]:.0f} rpm (pitch ratio 1.4-0.5); give an rpm in that range or --pitch-ratio"
        )
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if approach_rps(mmg_ship(p, mid), p.speed) > n_target else (lo, mid)
    return 0.5 * (lo + hi)


# An --mcr-kw in W for kW is 1000 x a rating that makes the speed (a smaller one is refused above). The power it is
# set against is the hull's need at Froude 0.2 or the approach speed, the higher: a slow approach (Froude 0.05 is
# allowed) needs a thousandth of the rating, so a ratio to it would refuse real ships. Measured (build._check_power,
# P/D 0.75): a 33 m tug of 5 MW 54 x its 92 kW at Froude 0.2, a 45 m escort tug of 9 MW 41 x, a 110 m icebreaker of
# 20 MW 11 x, the README's coaster 3.3 x; in W: KVLCC2 (25 MW) 543 x, a 180 m bulker of 7 MW 1092 x.
MCR_OVER_NEED = 300.0
MCR_FROUDE = 0.2


def _check_power(p: Particulars, pitch: float) -> float:
    """Brake power [kW] at the approach; refuse a speed the given MCR cannot make."""

    def brake(speed_kn: float) -> float:
        q = replace(p, speed_kn=speed_kn)
        ship = mmg_ship(q, pitch)
        return delivered_power_kw(ship, pitch, q.speed, approach_rps(ship, q.speed)) / SHAFT_EFFICIENCY

    need = brake(p.speed_kn)
    if p.mcr_kw is not None and need > p.mcr_kw:
        lo, hi = 0.0, p.speed_kn
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if brake(mid) < p.mcr_kw else (lo, mid)
        raise ParticularsError(
            f"--speed {p.speed_kn:g} kn: needs about {need:,.0f} kW with these particulars (ITTC-57 friction, B-series screw), "
            f"over --mcr-kw {p.mcr_kw:,.0f}; this hull makes at most {lo:.1f} kn with it"
        )
    if p.mcr_kw is None:
        return need
    ref_kn = max(p.speed_kn, MCR_FROUDE * math.sqrt(9.81 * p.length) / KNOT)
    scale = need if ref_kn == p.speed_kn else brake(ref_kn)  # only with an --mcr-kw to judge: a hull's power is not free
    if p.mcr_kw > MCR_OVER_NEED * scale:
        # a unit slip (W for kW): the full-power manoeuvres (acceleration) would be drawn from it
        raise ParticularsError(
            f"--mcr-kw {p.mcr_kw:,.0f}: {p.mcr_kw / scale:,.0f} times the about {scale:,.0f} kW this hull needs at "
            f"{ref_kn:.3g} kn (built ships: under {MCR_OVER_NEED:g} x): in W? give the engine's rating in kW"
        )
    return need


def sample_time(p: Particulars) -> float:
    """A fortieth of a ship length per sample, between 0.1 and 1 s (KVLCC2: 1 s)."""
    return float(np.clip(round(0.025 * p.length / p.speed, 1), 0.1, 1.0))


# -- prior spread --------------------------------------------------------------

# 1-sigma relative spread of each group of MMG coefficients. Linear hull derivatives: the larger of
# 20 % and the difference between Clarke et al. (1983) and Kijima et al. (1990) for this ship
# (two independent regressions); likewise eps of a hull finer than Kijima's eps maximum, where the
# choice of Lee & Shin (1998) (clipped) over Kijima is ours: the larger of 20 % and the gap between
# the chosen eps and Kijima's (Lee & Shin beyond the clip is not counted: values no database
# supports, and a spread of 70 % or more would reverse the rudder in some draws); the
# non-linear ones and the other interaction coefficients: the regressions publish no scatter, 50 %
# and 20 % are assumed; resistance 30 %: the one published
# check, the KVLCC2 model (L 7 m, 1.179 m/s) at R'_0 = 0.022 (Yasukawa & Yoshimura 2015, Table 2),
# is 25 % above friction and form alone (wave resistance, the form factor's scale effect).
NONLINEAR_SPREAD, INTERACTION_SPREAD, RESISTANCE_SPREAD, LINEAR_FLOOR = 0.5, 0.2, 0.3, 0.2
HOUSING_SPREAD = 0.3  # a pod housing's force: its area and lift gradient are assumed (units.HOUSING_AREA_D2)


def coefficient_spreads(p: Particulars) -> dict[str, float]:
    """Relative 1-sigma spread per MMG coefficient name (hull and interaction)."""
    h = p.hull
    cl, kj = rg.clarke_linear(h), rg.kijima_linear(h)
    out = {k: max(LINEAR_FLOOR, abs(cl[k] - kj[k]) / abs(cl[k])) for k in LINEAR}
    out |= {k: NONLINEAR_SPREAD for k in rg.kijima_nonlinear(h)}
    out |= {k: NONLINEAR_SPREAD for k in ("Xvv", "Xvr", "Xrr", "Xvvvv")}
    out |= {k: INTERACTION_SPREAD for k in ("tR", "aH", "xH", "gammaR", "lR", "eps", "wP0", "tP")}
    if p.actuator != "rudder_propeller":
        # Kijima's single-screw hull-rudder regressions applied to two off-centre rudders or pods,
        # outside their database: twice the spread
        out |= {k: 2 * INTERACTION_SPREAD for k in ("tR", "aH", "xH", "gammaR", "lR")}
        out["housing"] = HOUSING_SPREAD
        return out | {"R0": RESISTANCE_SPREAD}
    if rg.fine_for_kijima_eps(h):
        chosen = rg.eps(h)
        out["eps"] = max(INTERACTION_SPREAD, abs(chosen - rg.kijima_eps(h)) / chosen)
    out["R0"] = RESISTANCE_SPREAD
    return out


def prior_std(p: Particulars, ship: MMGShip, n0: float, ts: float, n_max: float, draws: int, seed: int) -> np.ndarray:
    """Std of each per-sample coefficient over ``draws`` MMG models whose coefficients are drawn
    from their regressions' spread (:func:`coefficient_spreads`), each fitted by one-step least
    squares; draws whose MMG model diverges are dropped (at least half must survive)."""
    rng = np.random.default_rng(seed)
    spread = coefficient_spreads(p)
    shell = profile_from_dict(profile_document(p, ts, n0, n_max), p.name)
    thetas = []
    for _ in range(draws):
        hull = {k: v * (1.0 + spread.get(k, 0.0) * rng.standard_normal()) for k, v in ship.hull.items()}
        inter = {k: v * (1.0 + spread.get(k, 0.0) * rng.standard_normal()) for k, v in ship.inter.items()}
        drawn = replace(ship, hull=hull, inter=inter)
        try:
            runs = excitation_runs(drawn, p.speed, approach_rps(drawn, p.speed), ts)
        except (FloatingPointError, ValueError):
            continue
        th = balance_thrust(shell, one_step_ls(shell, runs), p.speed, n0)
        if np.all(np.isfinite(th)):
            thetas.append(th)
    if len(thetas) < max(2, draws // 2):
        raise FloatingPointError(f"only {len(thetas)} of {draws} drawn MMG models could be simulated")
    return np.std(np.array(thetas), axis=0, ddof=1)


ACTUATOR_NOTES = {
    "twin_screw": [
        "twin screws and twin rudders: the profile's inputs are one rudder angle for both rudders and one rpm for"
        " both shafts (trials are sailed so); the two-unit MMG model behind it has no published ship to check it"
        " against (see the profile's header)"
    ],
    "azimuth": [
        "two pods: the standard manoeuvres steer both pods to the IMO rudder angles (35, 10, 20 deg); IMO MSC.137(76)"
        " lets an Administration set comparative angles for such ships, and Reichel (2019) found no single pod"
        " angle equivalent to 35 deg of rudder: read the IMO lines below as indicative",
        "the pods' per-sample model is fitted at the approach rpm and steering angles up to 35 deg (plus one run"
        " with unequal thrust); at rest or with the pods turned further it extrapolates",
    ],
}

PRIOR_NOTE = """Prior spread (1 sigma) of each coefficient above: the std over MMG models whose coefficients are drawn
from their regressions' spread (linear hull: max(20 %, |Clarke - Kijima|); non-linear hull 50 %,
interaction 20 % (eps of a fine hull: max(20 %, |eps - Kijima's|); t_R, a_H, x'_H, gamma_R, l'_R of
twin rudders or pods 40 %, a pod housing's force 30 %), resistance 30 %, assumed where the
regressions publish no scatter), each refitted by one-step
least squares only (the coefficients above are also fitted by output error)."""


def fine_hull_note(p: Particulars) -> str:
    """What `profile new` says of a hull finer than the maximum of Kijima's eps quadratic."""
    h = p.hull
    return (
        f"eps {rg.eps(h):.3f} (the rudder's inflow): {rg.eps_source(h)}; Kijima et al. (1990)'s quadratic gives"
        f" {rg.kijima_eps(h):.3f} for a hull this fine (Cb B/L {h.cb_b_l:.4f} < {rg.KIJIMA_EPS_PEAK:.4f}); Lee & Shin's range"
        " of validity is not known to us: the rudder's strength is the least certain part of this profile"
    )


def build_profile(p: Particulars, *, oe_nfev: int = 15, draws: int = 12, seed: int = 0) -> Built:
    """The profile of the particulars ``p`` (see the module docstring); raises ParticularsError on
    particulars no ship has, FloatingPointError if the MMG model or the fit diverges."""
    check_particulars(p)
    if seed < 0:
        raise ParticularsError(f"--seed {seed}: give an integer >= 0 (the seed of the prior's draws)")
    pitch = p.pitch_ratio or (_pitch_for_rpm(p) if p.rpm else 0.75)
    power = _check_power(p, pitch)
    ship = mmg_ship(p, pitch)
    n0 = approach_rps(ship, p.speed)
    n_max = 1.15 * n0 if not p.mcr_kw else n0 * max(1.0, p.mcr_kw / power) ** (1.0 / 3.0)
    ts = sample_time(p)
    theta, fits = fit_profile(p, ship, n0, ts, n_max, oe_nfev)
    doc = profile_document(p, ts, n0, n_max, theta)
    doc["prior"] = {
        "source": "regression scatter propagated through the fit",
        "draws": draws,
        "seed": seed,
        "std": split(prior_std(p, ship, n0, ts, n_max, draws, seed), p.actuator),
    }
    made_of = {
        "length_m": p.length, "beam_m": p.beam, "draught_m": p.draught, "block_coefficient": p.cb, "speed_kn": p.speed_kn,
        "rudder_area_m2": ship.units * ship.rudder_area if p.actuator != "azimuth" else None,
        "housing_area_m2": ship.rudder_area if p.actuator == "azimuth" else None,
        "propeller_diameter_m": ship.prop_diameter, "pitch_ratio": pitch, "mcr_kw": p.mcr_kw,
    }  # fmt: skip
    doc["particulars"] = {k: float(v) for k, v in made_of.items() if v is not None}
    text = header(p, ship, pitch, n0, power, fits, RUDDER_ASPECT) + toml_text(doc, {"prior": PRIOR_NOTE}) + "\n"
    profile = profile_from_dict(tomllib.loads(text), f"{p.name}.toml")
    notes = [fine_hull_note(p)] if rg.fine_for_kijima_eps(p.hull) and p.actuator == "rudder_propeller" else []
    notes += ACTUATOR_NOTES.get(p.actuator, [])
    if p.rpm and p.pitch_ratio:
        notes.append(f"the screw of P/D {pitch:g} holds {p.speed_kn:g} kn at {60 * n0:.1f} rpm, not the given {p.rpm:g} rpm")
    return Built(text, profile, ship, n0, notes)
