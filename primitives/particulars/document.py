"""The profile document of a ship made from particulars: its tables, and the TOML text with the
source of every coefficient in its comments."""

from __future__ import annotations

import json
import math

import numpy as np

from primitives.maneuvers import MAX_RUDDER_DEG  # SOLAS II-1 reg. 29.3.2: 35 deg each side
from primitives.particulars import regressions as rg
from primitives.particulars.inputs import Particulars
from primitives.particulars.mmg import MMGShip
from primitives.particulars.units import HOUSING_AREA_D2, UNIT_OFFSET_B

RUDDER_RATE_DEG_S = 2.32  # SOLAS II-1 reg. 29.3.2: 35 deg port to 30 deg stbd in 28 s

# the per-sample model: kvlcc2.toml's structure (Ljungberg 2022, eq. 3.60, with quadratic
# resistance and thrust, cross-flow drag and rudder force growing with inflow and slipstream)
MODEL = {
    "surge": ["u_r*|u_r|", "n^2", "v_r*r"],
    "sway": ["u_r*v_r", "u_r*r", "v_r*|v_r|", "delta*u_r^2", "delta*n^2"],
    "yaw": ["u_r*r", "u_r*v_r", "r*|r|", "delta*u_r^2", "delta*n^2"],
}

NAMES = {
    "surge": ["Xuu", "Xnn", "Xvr"],
    "sway": ["Yuv", "Yur", "Yvv", "Ydelta", "Ydnn"],
    "yaw": ["Nur", "Nuv", "Nrr", "Ndelta", "Ndnn"],
}

# the per-sample model of a podded (azimuth) ship: full-scale.toml's form, the thrusters' generalized
# forces of Ljungberg (2022), eq. 3.55 (tau_x = sum n cos alpha, tau_y = sum n sin alpha, tau_n =
# sum n (x sin alpha - y cos alpha)), each also scaled by the speed (the thrust falls as the advance
# ratio rises), with kvlcc2.toml's hull terms and the housings' damping, which grows with their
# slipstream (v_r tau_x, r tau_x): on a 35 deg turn a podded ship keeps its rpm and loses most of its
# speed; with them the open-loop yaw fit to the MMG model's turning circle rose from 79-80 % to
# 86-89 % and on the engine step from 61-65 % to 79-82 % (a 100 m coaster and a 150 m ferry)
AZIMUTH_MODEL = {
    "surge": ["u_r*|u_r|", "v_r*r", "tau_x", "u_r*tau_x"],
    "sway": ["u_r*v_r", "u_r*r", "v_r*|v_r|", "tau_y", "u_r*tau_y", "v_r*tau_x"],
    "yaw": ["u_r*r", "u_r*v_r", "r*|r|", "tau_n", "u_r*tau_n", "r*tau_x", "v_r*tau_x"],
}

AZIMUTH_NAMES = {
    "surge": ["Xuu", "Xvr", "Xtau", "Xutau"],
    "sway": ["Yuv", "Yur", "Yvv", "Ytau", "Yutau", "Yvtau"],
    "yaw": ["Nur", "Nuv", "Nrr", "Ntau", "Nutau", "Nrtau", "Nvtau"],
}


def model_terms(actuator: str) -> dict[str, list[str]]:
    """The per-sample model's terms of a ship built with ``actuator``."""
    return AZIMUTH_MODEL if actuator == "azimuth" else MODEL


def split(theta: np.ndarray, actuator: str = "rudder_propeller") -> dict[str, list[float]]:
    """A parameter vector as the profile's per-DOF lists."""
    out, i = {}, 0
    for dof, terms in model_terms(actuator).items():
        out[dof] = [float(x) for x in theta[i : i + len(terms)]]
        i += len(terms)
    return out


def profile_document(p: Particulars, ts: float, n0: float, n_max: float, theta: np.ndarray | None = None) -> dict:
    """The profile's tables (parameters zero when ``theta`` is None: the shell the fit's regressors
    are built from)."""
    terms = model_terms(p.actuator)
    per = split(theta, p.actuator) if theta is not None else {dof: [0.0] * len(t) for dof, t in terms.items()}
    doc = {
        "name": p.name,
        "description": f"{p.name}: 3-DOF model made from main particulars (shiptrial profile new, {p.actuator})",
        "source": "main particulars -> MMG standard model (Yasukawa & Yoshimura 2015) -> fitted by shiptrial",
        "sample_time": ts,
        "length_m": float(p.length),
        "beam_m": float(p.beam),
        "draught_m": float(p.draught),
        "cruise_speed_mps": p.speed,
    }
    if p.actuator == "azimuth":
        x, y = MMGShip.x_p * p.length, UNIT_OFFSET_B * p.beam
        doc |= {
            "actuator": "azimuth",
            "inputs": ["n1", "alpha1", "n2", "alpha2"],
            "simulation_set": "particulars",
            "instrument_set": "particulars",
            "thrusters": [{"name": "port pod", "x": x, "y": -y}, {"name": "starboard pod", "x": x, "y": y}],
            "input_limits": {k: v for i in (1, 2) for k, v in ((f"n{i}", [0.0, n_max]), (f"alpha{i}", [-math.pi, math.pi]))},
            "model": AZIMUTH_MODEL,
            "parameter_names": AZIMUTH_NAMES,
        }
    else:
        doc |= {
            "actuator": "rudder_propeller",
            "inputs": ["delta", "n"],
            "simulation_set": "particulars",
            "instrument_set": "particulars",
            "input_limits": {"delta": [-math.radians(MAX_RUDDER_DEG), math.radians(MAX_RUDDER_DEG)], "n": [0.0, n_max]},
            "helm": {"max_rudder_deg": MAX_RUDDER_DEG, "rudder_rate_deg_s": RUDDER_RATE_DEG_S, "starboard_sign": 1},
            "engine": {"rps_limits": [0.0, n_max], "approach_rpm": round(60.0 * n0, 1)},
            "model": MODEL,
            "parameter_names": NAMES,
        }
    doc["parameters"] = {"particulars": per}
    return doc


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a JSON string is a TOML basic string
    return "[" + ", ".join(_value(x) for x in v) + "]"


def toml_text(doc: dict, comments: dict[str, str] | None = None, path: str = "") -> str:
    """``doc`` as TOML: scalars and lists first, then each sub-table under its dotted header (a table
    of tables only, like [parameters], gets no header of its own); ``comments[path]`` (lines
    without the '#') is written above that table."""
    comments = comments or {}

    def table_list(v) -> bool:
        return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)

    parts = ["\n".join(f"{k} = {_value(v)}" for k, v in doc.items() if not isinstance(v, dict) and not table_list(v))]
    for k, v in doc.items():
        if table_list(v):  # an array of tables, e.g. [[thrusters]]
            parts += [f"[[{k}]]\n" + "\n".join(f"{a} = {_value(b)}" for a, b in x.items()) for x in v]
        if isinstance(v, dict):
            sub = f"{path}.{k}" if path else k
            note = "".join(f"# {line}\n" for line in comments.get(sub, "").splitlines())
            head = f"[{sub}]\n" if any(not isinstance(x, dict) for x in v.values()) else ""
            parts.append(note + head + toml_text(v, comments, sub))
    return "\n\n".join(p for p in parts if p)


def _unit_lines(p: Particulars, ship: MMGShip, aspect: float) -> list[str]:
    """The header's lines on the rudders or pods."""
    area = "DNV rule guidance T L/100 (1 + 25 (B/L)^2)"
    if p.actuator == "rudder_propeller":
        given = "given" if p.rudder_area is not None else area
        return [
            f"# rudder {ship.rudder_area:.4g} m^2 ({given}), span {ship.rudder_span:.3g} m (aspect {aspect:g}, at most 0.8 T);"
        ]
    where = f"x = {ship.x_p * p.length:.4g} m, y = -+{ship.y_unit * p.length:.4g} m ({UNIT_OFFSET_B:g} B, assumed)"
    if p.actuator == "twin_screw":
        given = "given, in total" if p.rudder_area is not None else area + " in total"
        return [
            f"# twin screws and twin rudders at {where}; each rudder {ship.rudder_area:.4g} m^2 ({given}),",
            f"# span {ship.rudder_span:.3g} m (aspect {aspect:g}, at most 0.8 T); both rudders move together, both shafts turn alike;",
        ]
    return [
        f"# two steerable pods at {where}, each a screw and a housing of {ship.rudder_area:.4g} m^2",
        f"# ({HOUSING_AREA_D2:g} D^2, span D: assumed); pod 1 is the port pod; alpha + turns the thrust to starboard;",
    ]


def _interaction_lines(p: Particulars, ship: MMGShip) -> list[str]:
    """The header's lines on the hull-propeller-rudder interaction and where each value comes from."""
    it = ship.inter
    kijima = "#   t_R {tR:.3f}, a_H {aH:.3f}, x'_H {xH:.3f}, gamma_R {gammaR:.3f}, l'_R {lR:.2f}: Kijima et al. (1990)".format(
        **it
    )
    kappa = f"kappa {it['kappa']:.2f} assumed (KVLCC2's, Yasukawa & Yoshimura 2015)"
    if p.actuator == "rudder_propeller":
        return [
            kijima + ";",
            f"#   eps {it['eps']:.3f}: {rg.eps_source(p.hull)}; {kappa}",
            "#   w_P0 {wP0:.3f} (Taylor 0.5 Cb - 0.05), t_P {tP:.3f} (0.6 w_P0): Harvald (1983)".format(**it),
        ]
    lines = [
        kijima + ", single-screw regressions applied",
        "#   to "
        + ("each rudder" if p.actuator == "twin_screw" else "each pod's housing")
        + " (outside their database; prior spread doubled to 40 %); "
        + kappa
        + ";",
        "#   w_P0 {wP0:.3f} (Taylor's twin-screw 0.55 Cb - 0.20), t_P {tP:.3f} (Schoenherr's twin-screw 0.7 w + 0.06);".format(
            **it
        ),
        "#   eps 1 assumed (each " + ("rudder" if p.actuator == "twin_screw" else "housing") + " in its own screw's wake);"
        " model of the two units: primitives/particulars/units.py",
    ]
    if p.actuator == "twin_screw":
        lines.append("#   (Khanfir et al. 2011's twin-rudder form without its measured per-rudder coefficients)")
    else:
        lines.append(
            "#   thrust along each pod's axis, housing as an MMG rudder at delta = -alpha (after Gierusz 2015's pod model)"
        )
    return lines


def header(p: Particulars, ship: MMGShip, pitch: float, n0: float, power_kw: float, fits: dict, aspect: float) -> str:
    given = lambda v, what: "given" if v is not None else what  # noqa: E731
    pods = p.actuator == "azimuth"
    h = ship.hull
    lines = [
        f"# {p.name}: made by `shiptrial profile new` from main particulars, before any trial.",
        f"# L {p.length:g} m, B {p.beam:g} m, T {p.draught:g} m, Cb {p.cb:g}, {p.speed_kn:g} kn ({p.speed:.3f} m/s);",
        *_unit_lines(p, ship, aspect),
        f"# screw {ship.prop_diameter:.3g} m ({given(p.prop_diameter, 'assumed 0.6 T')}), B-series Z = 4, A_E/A_0 = 0.55,"
        f" P/D {pitch:.3f} ({given(p.pitch_ratio, 'solved for the rpm' if p.rpm else 'assumed 0.75')});",
        f"# approach {60 * n0:.1f} rpm (thrust = resistance at {p.speed_kn:g} kn), brake power {power_kw:,.0f} kW"
        + (f" of MCR {p.mcr_kw:,.0f} kW" if p.mcr_kw else "")
        + ".",
        "#",
        "# Sources (an MMG standard model, Yasukawa & Yoshimura 2015, eqs. 4-27; non-dimensional as there):",
        f"#   R'_0 = {h['R0']:.5f}: ITTC-1957 friction x Watanabe form factor 1+k = {rg.form_factor(p.hull):.3f},"
        " Denny-Mumford wetted surface",
        "#   X'_vv {Xvv:.4f}, X'_vr {Xvr:.4f}, X'_rr {Xrr:.4f}, X'_vvvv {Xvvvv:.4f}: Yoshimura & Masumoto (2012), Table 3".format(
            **h
        ),
        "#   Y'_v {Yv:.4f}, Y'_r {Yr:.4f}, N'_v {Nv:.4f}, N'_r {Nr:.4f}: Clarke, Gedling & Hine (1983), eqs. (9)-(12); Y'_r + m'_x".format(
            **h
        ),
        "#   Y'_bb {Ybb:.4f}, Y'_rr {Yrr:.4f}, Y'_bbr {Ybbr:.4f}, Y'_brr {Ybrr:.4f}, N'_bb {Nbb:.4f}, N'_rr {Nrr:.4f},".format(
            **h
        ),
        "#   N'_bbr {Nbbr:.4f}, N'_brr {Nbrr:.4f}: Kijima, Katsuno, Nakiri & Furukawa (1990), even keel".format(**h),
        "#   m'_y {my:.4f}, J'_z {Jz:.5f}: Clarke et al. (1983), eqs. (13), (16); m'_x {mx:.4f} = 0.05 m'".format(**ship.mass),
        *_interaction_lines(p, ship),
        f"#   K_T = {ship.kt[0]:.4f} {ship.kt[1]:+.4f} J {ship.kt[2]:+.4f} J^2: Wageningen B-series (Oosterveld & van Oossanen"
        " 1975), quadratic fit",
        f"#   f_alpha {ship.f_alpha:.3f}: Fujii & Tuda (1961); steering gear 35 deg, 2.32 deg/s: SOLAS II-1 reg. 29"
        + (" (taken for the pods' steering too)" if pods else ""),
        "#",
        "# [parameters.particulars]: the per-sample model ("
        + ("full-scale.toml's thruster forces, kvlcc2.toml's hull terms" if pods else "kvlcc2.toml's structure")
        + ") fitted by one-step least squares",
        "# then output error on the MMG model's 35 deg turning circle, 10/10 and 20/20 zig-zags (starboard; the MMG model is symmetric) and an",
        "# engine step to half rpm"
        + ("; then 60 % rpm on the starboard pod" if pods else "")
        + f"; {'Xtau' if pods else 'Xnn'} then holds the approach speed. Open-loop fit % (surge / sway / yaw) on them:",
    ]
    lines += [f"#   {name:12s} {a:5.1f} / {b:5.1f} / {c:5.1f}" for name, (a, b, c) in fits.items()]
    if rg.fine_for_kijima_eps(p.hull) and p.actuator == "rudder_propeller":
        lines += [
            "#",
            f"# Fine hull (Cb B/L {p.hull.cb_b_l:.4f} < {rg.KIJIMA_EPS_PEAK:.4f}, the maximum of Kijima et al. (1990)'s eps"
            f" quadratic, which gives {rg.kijima_eps(p.hull):.3f} here):",
            f"# eps {ship.inter['eps']:.3f} is Lee & Shin (1998)'s regression in Cb and 2 d / L ({rg.lee_shin_eps(p.hull):.3f} here),"
            f" clipped to between Kijima's value and its maximum {rg.KIJIMA_EPS_MAX:.3f};",
            "# transcribed second-hand (mmgdynamics package): its database and range of validity were not available to us."
            " Its prior spread is",
            "# the gap to Kijima's value (at least 20 %). A low eps weakens the rudder: with Kijima's eps the Mariner"
            " (Cb B/L 0.086) turned 60 % wider",
            "# than its captive-test (PMM) model.",
        ]
    return "\n".join(lines) + "\n"
