"""A profile from a ship's main particulars: regressions -> MMG model -> simulated standard and
excitation manoeuvres -> the profile's per-sample model fitted to them (one-step least squares,
then output error, as ``benchmarks/fit_kvlcc2.py`` fits the MARIN runs) -> TOML.

    from primitives.particulars.build import Particulars, build_profile
    doc = build_profile(Particulars("my-ship", 320, 58, 20.8, 0.81, 15.5, rudder_area=142, prop_diameter=9.86))
    doc.text  # the TOML document; doc.profile the loaded ShipProfile
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from primitives import jitloop
from primitives.errors import UserError
from primitives.particulars import regressions as rg
from primitives.particulars.mmg import MMGShip, Run, fixed_helm, run, zigzag_helm
from primitives.particulars.propeller import BSeries
from primitives.profile_document import profile_from_dict
from primitives.regressors import predictor_regressors
from primitives.ship import ShipProfile
from primitives.simulate import simulate

KNOT = 1852.0 / 3600.0
MAX_RUDDER_DEG = 35.0  # SOLAS II-1 reg. 29.3.2: 35 deg each side
RUDDER_RATE_DEG_S = 2.32  # SOLAS II-1 reg. 29.3.2: 35 deg port to 30 deg stbd in 28 s
SHAFT_EFFICIENCY = 0.97  # delivered / brake power, shaft and gearing losses (Harvald 1983)
RUDDER_ASPECT = 1.8  # geometric aspect ratio of a spade/semi-spade rudder when the span is not given
ACTUATORS = ("rudder_propeller",)
LINEAR = ("Yv", "Yr", "Nv", "Nr")  # Clarke et al. (1983); the non-linear hull terms are Kijima et al. (1990)
PLANNED_ACTUATORS = ("twin_screw", "azimuth")

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


class ParticularsError(UserError):
    """A main particular out of the range ships have, or one the chosen actuator needs missing."""


@dataclass(frozen=True)
class Particulars:
    """What an owner or a yard knows before the trial [m, -, kn, m^2, m, -, rpm, kW]."""

    name: str
    length: float
    beam: float
    draught: float
    cb: float
    speed_kn: float
    rudder_area: float | None = None
    prop_diameter: float | None = None
    pitch_ratio: float | None = None
    rpm: float | None = None
    mcr_kw: float | None = None
    actuator: str = "rudder_propeller"

    @property
    def hull(self) -> rg.Hull:
        return rg.Hull(self.length, self.beam, self.draught, self.cb)

    @property
    def speed(self) -> float:
        return self.speed_kn * KNOT


@dataclass
class Built:
    """The generated profile: TOML text, the loaded profile, the MMG model behind it and notes."""

    text: str
    profile: ShipProfile
    mmg: MMGShip
    approach_rps: float
    notes: list[str] = field(default_factory=list)
    fit_percent: dict[str, tuple[float, float, float]] = field(default_factory=dict)


# -- input checks ------------------------------------------------------------------------------


def _positive(name: str, value: float | None, unit: str) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise ParticularsError(f"--{name} {value!r}: must be a number > 0 {unit}".rstrip())


def check_particulars(p: Particulars) -> None:
    """Refuse particulars no ship has, one line naming the value and the plausible range."""
    if p.actuator in PLANNED_ACTUATORS:
        raise ParticularsError(
            f"--actuator {p.actuator}: not built from particulars yet; use --actuator rudder_propeller (single screw, one rudder)"
        )
    if p.actuator not in ACTUATORS:
        raise ParticularsError(f"--actuator {p.actuator!r}: must be rudder_propeller")
    for name, val, unit in (
        ("length", p.length, "m"),
        ("beam", p.beam, "m"),
        ("draught", p.draught, "m"),
        ("block-coefficient", p.cb, ""),
        ("speed", p.speed_kn, "kn"),
        ("rudder-area", p.rudder_area, "m^2"),
        ("propeller-diameter", p.prop_diameter, "m"),
        ("pitch-ratio", p.pitch_ratio, ""),
        ("rpm", p.rpm, "rpm"),
        ("mcr-kw", p.mcr_kw, "kW"),
    ):
        _positive(name, val, unit)
    if not 0.35 <= p.cb <= 0.9:
        raise ParticularsError(f"--block-coefficient {p.cb:g}: outside 0.35-0.9, the range of displacement ships")
    if p.beam >= p.length:
        raise ParticularsError(f"--beam {p.beam:g} m: not below the length {p.length:g} m; ships have L/B 3-9")
    if p.draught >= p.beam:
        raise ParticularsError(f"--draught {p.draught:g} m: not below the beam {p.beam:g} m; ships have B/T 1.5-5")
    lt = p.length * p.draught
    if p.rudder_area is not None and p.rudder_area > 0.05 * lt:
        raise ParticularsError(
            f"--rudder-area {p.rudder_area:g} m^2: over 5 % of L*T ({0.05 * lt:.4g} m^2); rudders are 1-5 % of L*T "
            f"({0.01 * lt:.4g}-{0.05 * lt:.4g} m^2 for this ship)"
        )
    if p.prop_diameter is not None and p.prop_diameter > p.draught:
        raise ParticularsError(
            f"--propeller-diameter {p.prop_diameter:g} m: larger than the draught {p.draught:g} m; screws are 0.4-0.8 x the draught"
        )
    if p.pitch_ratio is not None and not 0.5 <= p.pitch_ratio <= 1.4:
        raise ParticularsError(f"--pitch-ratio {p.pitch_ratio:g}: outside 0.5-1.4, the range of the Wageningen B-series")
    fn = p.speed / math.sqrt(9.81 * p.length)
    if fn > 0.45:
        raise ParticularsError(
            f"--speed {p.speed_kn:g} kn: Froude number {fn:.2f} on a {p.length:g} m hull; a displacement ship's regressions "
            f"hold below 0.45 (at most {0.45 * math.sqrt(9.81 * p.length) / KNOT:.1f} kn)"
        )


# -- the MMG model -----------------------------------------------------------------------------


def rule_rudder_area(p: Particulars) -> float:
    """Rudder area from the DNV rule guidance A_R = T L / 100 (1 + 25 (B/L)^2) [m^2] (DNV Rules for
    Ships, Pt. 3 Ch. 3 Sec. 2, A 200), when the user gives none."""
    return p.draught * p.length / 100.0 * (1.0 + 25.0 * (p.beam / p.length) ** 2)


def mmg_ship(p: Particulars, pitch_ratio: float) -> MMGShip:
    """The MMG model of the particulars (regressions in :mod:`primitives.particulars.regressions`)."""
    h = p.hull
    area = p.rudder_area or rule_rudder_area(p)
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
        inter=rg.interaction(h),
        prop_diameter=p.prop_diameter or default_diameter(p),
        kt=BSeries(pitch_ratio).quadratic_fit(),
        rudder_area=area,
        rudder_span=span,
        f_alpha=rg.rudder_lift_slope(span**2 / area),
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
    resist = 0.5 * rg.RHO * ship.length * ship.draught * speed**2 * ship.hull["R0"]
    a, b, c = k0 * D**4, k1 * up * D**3, k2 * up**2 * D**2 - resist / (rg.RHO * (1.0 - t))
    return (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)


def delivered_power_kw(ship: MMGShip, pitch_ratio: float, speed: float, n: float) -> float:
    """P_D = 2 pi rho n^3 D^5 K_Q(J) [kW] at the approach (B-series torque, Oosterveld & van Oossanen 1975)."""
    D = ship.prop_diameter
    j = (1.0 - ship.inter["wP0"]) * speed / (n * D)
    return 2.0 * math.pi * rg.RHO * n**3 * D**5 * float(BSeries(pitch_ratio).kq(j)) / 1000.0


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
    return need


# -- manoeuvres and fit ------------------------------------------------------------------------


def sample_time(p: Particulars) -> float:
    """A fortieth of a ship length per sample, between 0.1 and 1 s (KVLCC2: 1 s)."""
    return float(np.clip(round(0.025 * p.length / p.speed, 1), 0.1, 1.0))


def excitation_runs(ship: MMGShip, speed: float, n0: float, ts: float) -> list[Run]:
    """The standard manoeuvres (IMO MSC.137(76)) the per-sample model is fitted to: a 35 deg turning
    circle, 10/10 and 20/20 zig-zags, and an engine step to half rpm with 10 deg rudder (it
    separates resistance from thrust). One side only: the MMG model is symmetric (x_G = 0, no
    propeller side force), so the port runs would mirror these."""
    rate, dmax = math.radians(RUDDER_RATE_DEG_S), math.radians(MAX_RUDDER_DEG)
    lengths = ship.length / speed / ts  # samples per ship length at the approach

    def go(name: str, helm, n_lengths: float) -> Run:
        return run(ship, name, helm, speed, int(n_lengths * lengths), ts, rate, dmax)

    return [
        go("tc35", fixed_helm(dmax, n0), 25),
        go("zz10", zigzag_helm(math.radians(10), 1.0, n0), 14),
        go("zz20", zigzag_helm(math.radians(20), 1.0, n0), 14),
        go("engine-half", fixed_helm(math.radians(10), n0, n_after=0.5 * n0, at=int(2 * lengths)), 14),
    ]


def _document(p: Particulars, ts: float, n0: float, n_max: float, theta: np.ndarray | None) -> dict:
    per = {}
    if theta is not None:
        i = 0
        for dof in ("surge", "sway", "yaw"):
            per[dof] = [float(x) for x in theta[i : i + len(MODEL[dof])]]
            i += len(MODEL[dof])
    else:
        per = {dof: [0.0] * len(MODEL[dof]) for dof in MODEL}
    return {
        "name": p.name,
        "description": f"{p.name}: 3-DOF model made from main particulars (shiptrial profile new)",
        "source": "main particulars -> MMG standard model (Yasukawa & Yoshimura 2015) -> fitted by shiptrial",
        "sample_time": ts,
        "length_m": float(p.length),
        "beam_m": float(p.beam),
        "draught_m": float(p.draught),
        "cruise_speed_mps": p.speed,
        "actuator": "rudder_propeller",
        "inputs": ["delta", "n"],
        "simulation_set": "particulars",
        "instrument_set": "particulars",
        "input_limits": {"delta": [-math.radians(MAX_RUDDER_DEG), math.radians(MAX_RUDDER_DEG)], "n": [0.0, n_max]},
        "helm": {"max_rudder_deg": MAX_RUDDER_DEG, "rudder_rate_deg_s": RUDDER_RATE_DEG_S, "starboard_sign": 1},
        "engine": {"rps_limits": [0.0, n_max], "approach_rpm": 60.0 * n0},
        "model": MODEL,
        "parameter_names": NAMES,
        "parameters": {"particulars": per},
    }


def one_step_ls(profile: ShipProfile, runs: list[Run]) -> np.ndarray:
    """Equation-error start: per DOF least squares of nu(k+1) - nu(k) on the regressors, each run
    weighted by the spread of its own increments (a zig-zag weighs as much as a turning circle)."""
    phis, dys = [], []
    for r in runs:
        phi, dy = predictor_regressors(profile, r.nu, r.inputs, terms=profile.model)
        w = 1.0 / np.maximum(dy.std(axis=0), 1e-12)
        phis.append((phi, w)), dys.append(dy * w)
    th = np.zeros(profile.model.n_params)
    for i in range(3):
        s = profile.model.dof_slice(i)
        A = np.concatenate([phi[:, s] * w[i] for phi, w in phis])
        th[s] = np.linalg.lstsq(A, np.concatenate([d[:, i] for d in dys]), rcond=None)[0]
    return th


def balance_thrust(profile: ShipProfile, theta: np.ndarray, speed: float, n0: float) -> np.ndarray:
    """Xnn so that the model holds ``speed`` at ``n0`` (surge increment zero): u|u| Xuu + n^2 Xnn = 0."""
    th = theta.copy()
    th[1] = -th[0] * speed * abs(speed) / n0**2
    return th


def output_error(profile: ShipProfile, theta: np.ndarray, runs: list[Run], max_nfev: int = 15) -> np.ndarray:
    """Output-error least squares of every parameter on the open-loop simulated runs, each run's
    residual scaled by its own spread (batched finite-difference Jacobian through ``simulate``)."""
    # the fit simulates every run some 15 x (p + 1) times in all: worth loading the compiled loop
    # (jitloop.use decides per call, and each call here is below its threshold)
    jitloop.use(jitloop.MIN_WORK)
    scale = [np.std(r.nu, axis=0) * math.sqrt(len(r.nu)) + 1e-12 for r in runs]
    typ = np.where(theta != 0, theta, 1e-9)

    def resid(Z: np.ndarray) -> np.ndarray:
        P = (1.0 + np.atleast_2d(Z)) * typ
        parts = []
        with np.errstate(all="ignore"):
            for r, s in zip(runs, scale):
                nu = simulate(profile, r.inputs, P, nu0=r.nu[0], batch=len(P), positions=False).nu
                parts.append(((r.nu[None] - nu)[:, 1:] / s).reshape(len(P), -1))
        R = np.concatenate(parts, axis=1)
        return np.where(np.isfinite(R), np.clip(R, -1e3, 1e3), 1e3)

    def jac(z: np.ndarray) -> np.ndarray:
        h = 1e-5
        Z = np.repeat(z[None], len(z) + 1, axis=0)
        Z[1:] += h * np.eye(len(z))
        R = resid(Z)
        return ((R[1:] - R[0]) / h).T

    sol = least_squares(lambda z: resid(z)[0], np.zeros_like(theta), jac=jac, method="trf", x_scale=0.05, max_nfev=max_nfev)
    return (1.0 + sol.x) * typ


def fit_percent(profile: ShipProfile, theta: np.ndarray, r: Run) -> tuple[float, float, float]:
    """Open-loop NRMSE fit % per DOF of the profile on one MMG run."""
    nu = simulate(profile, r.inputs, theta, nu0=r.nu[0], positions=False).nu[0]
    err = np.linalg.norm(r.nu - nu, axis=0)
    dev = np.linalg.norm(r.nu - r.nu.mean(axis=0), axis=0)
    return tuple(float(x) for x in 100.0 * (1.0 - err / np.maximum(dev, 1e-12)))


def fit_profile(p: Particulars, ship: MMGShip, n0: float, ts: float, n_max: float, oe_nfev: int = 15) -> tuple[np.ndarray, dict]:
    """The per-sample model fitted to the MMG model's manoeuvres; per-run fit % as evidence."""
    shell = profile_from_dict(_document(p, ts, n0, n_max, None), p.name)
    runs = excitation_runs(ship, p.speed, n0, ts)
    theta = balance_thrust(shell, one_step_ls(shell, runs), p.speed, n0)
    if oe_nfev:
        theta = balance_thrust(shell, output_error(shell, theta, runs, oe_nfev), p.speed, n0)
    if not np.all(np.isfinite(theta)):
        raise FloatingPointError("the fit of the per-sample model diverged")
    return theta, {r.name: fit_percent(shell, theta, r) for r in runs}


# -- prior spread ------------------------------------------------------------------------------

# 1-sigma relative spread of each group of MMG coefficients. Linear hull derivatives: the larger of
# 20 % and the difference between Clarke et al. (1983) and Kijima et al. (1990) for this ship
# (two independent regressions); the non-linear ones and the interaction coefficients: the
# regressions publish no scatter, 50 % and 20 % are assumed; resistance 30 %: the one published
# check, the KVLCC2 model (L 7 m, 1.179 m/s) at R'_0 = 0.022 (Yasukawa & Yoshimura 2015, Table 2),
# is 25 % above friction and form alone (wave resistance, the form factor's scale effect).
NONLINEAR_SPREAD, INTERACTION_SPREAD, RESISTANCE_SPREAD, LINEAR_FLOOR = 0.5, 0.2, 0.3, 0.2


def coefficient_spreads(p: Particulars) -> dict[str, float]:
    """Relative 1-sigma spread per MMG coefficient name (hull and interaction)."""
    h = p.hull
    cl, kj = rg.clarke_linear(h), rg.kijima_linear(h)
    out = {k: max(LINEAR_FLOOR, abs(cl[k] - kj[k]) / abs(cl[k])) for k in LINEAR}
    out |= {k: NONLINEAR_SPREAD for k in rg.kijima_nonlinear(h)}
    out |= {k: NONLINEAR_SPREAD for k in ("Xvv", "Xvr", "Xrr", "Xvvvv")}
    out |= {k: INTERACTION_SPREAD for k in ("tR", "aH", "xH", "gammaR", "lR", "eps", "wP0", "tP")}
    out["R0"] = RESISTANCE_SPREAD
    return out


def prior_std(p: Particulars, ship: MMGShip, n0: float, ts: float, n_max: float, draws: int, seed: int) -> np.ndarray:
    """Std of each per-sample coefficient over ``draws`` MMG models whose coefficients are drawn
    from their regressions' spread (:func:`coefficient_spreads`), each fitted by one-step least
    squares; draws whose MMG model diverges are dropped (at least half must survive)."""
    rng = np.random.default_rng(seed)
    spread = coefficient_spreads(p)
    shell = profile_from_dict(_document(p, ts, n0, n_max, None), p.name)
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


# -- the document ------------------------------------------------------------------------------


def _fmt(x: float) -> str:
    return repr(float(x))


def _lists(table: dict[str, list[float]]) -> str:
    return "\n".join(f"{k} = [{', '.join(_fmt(v) for v in vals)}]" for k, vals in table.items())


def _split(theta: np.ndarray) -> dict[str, list[float]]:
    out, i = {}, 0
    for dof, terms in MODEL.items():
        out[dof] = [float(x) for x in theta[i : i + len(terms)]]
        i += len(terms)
    return out


def _header(p: Particulars, ship: MMGShip, pitch: float, n0: float, power_kw: float, fits: dict) -> str:
    given = lambda v, what: "given" if v is not None else what  # noqa: E731
    h = ship.hull
    lines = [
        f"# {p.name}: made by `shiptrial profile new` from main particulars, before any trial.",
        f"# L {p.length:g} m, B {p.beam:g} m, T {p.draught:g} m, Cb {p.cb:g}, {p.speed_kn:g} kn ({p.speed:.3f} m/s);",
        f"# rudder {ship.rudder_area:.4g} m^2 ({given(p.rudder_area, 'DNV rule guidance T L/100 (1 + 25 (B/L)^2)')}),"
        f" span {ship.rudder_span:.3g} m (aspect {RUDDER_ASPECT:g}, at most 0.8 T);",
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
        "#   Y'_v {Yv:.4f}, Y'_r {Yr:.4f}, N'_v {Nv:.4f}, N'_r {Nr:.4f}: Clarke, Gedling & Hine (1983), eqs. (9)-(12)".format(
            **h
        ),
        "#   Y'_bb {Ybb:.4f}, Y'_rr {Yrr:.4f}, Y'_bbr {Ybbr:.4f}, Y'_brr {Ybrr:.4f}, N'_bb {Nbb:.4f}, N'_rr {Nrr:.4f},".format(
            **h
        ),
        "#   N'_bbr {Nbbr:.4f}, N'_brr {Nbrr:.4f}: Kijima, Katsuno, Nakiri & Furukawa (1990), even keel".format(**h),
        "#   m'_y {my:.4f}, J'_z {Jz:.5f}: Clarke et al. (1983), eqs. (13), (16); m'_x {mx:.4f} = 0.05 m'".format(**ship.mass),
        "#   t_R {tR:.3f}, a_H {aH:.3f}, x'_H {xH:.3f}, gamma_R {gammaR:.3f}, l'_R {lR:.2f}, eps {eps:.3f}, kappa {kappa:.2f}:"
        " Kijima et al. (1990)".format(**ship.inter),
        "#   w_P0 {wP0:.3f} (Taylor 0.5 Cb - 0.05), t_P {tP:.3f} (0.6 w_P0): Harvald (1983)".format(**ship.inter),
        f"#   K_T = {ship.kt[0]:.4f} {ship.kt[1]:+.4f} J {ship.kt[2]:+.4f} J^2: Wageningen B-series (Oosterveld & van Oossanen"
        " 1975), quadratic fit",
        f"#   f_alpha {ship.f_alpha:.3f}: Fujii & Tuda (1961); steering gear 35 deg, 2.32 deg/s: SOLAS II-1 reg. 29",
        "#",
        "# [parameters.particulars]: the per-sample model (kvlcc2.toml's structure) fitted by one-step least squares",
        "# then output error on the MMG model's 35 deg turning circle, 10/10 and 20/20 zig-zags (starboard; the MMG model is symmetric) and an",
        "# engine step to half rpm; Xnn then holds the approach speed. Open-loop fit % (surge / sway / yaw) on them:",
    ]
    lines += [f"#   {name:12s} {a:5.1f} / {b:5.1f} / {c:5.1f}" for name, (a, b, c) in fits.items()]
    return "\n".join(lines) + "\n"


def render(
    p: Particulars,
    ship: MMGShip,
    pitch: float,
    n0: float,
    n_max: float,
    power_kw: float,
    ts: float,
    theta,
    std,
    fits,
    draws,
    seed,
) -> str:
    """The profile as TOML text, with the source of every coefficient in its comments."""
    doc = _document(p, ts, n0, n_max, theta)
    top = "\n".join(
        f"{k} = {_fmt(v) if isinstance(v, float) else repr(v).replace(chr(39), chr(34))}"
        for k, v in doc.items()
        if not isinstance(v, dict)
    )
    body = [
        _header(p, ship, pitch, n0, power_kw, fits) + top,
        "[input_limits]\n" + _lists(doc["input_limits"]),
        "[helm]\nmax_rudder_deg = {max_rudder_deg!r}\nrudder_rate_deg_s = {rudder_rate_deg_s!r}\nstarboard_sign = 1".format(**doc["helm"]),
        f"[engine]\nrps_limits = [0.0, {_fmt(n_max)}]\napproach_rpm = {_fmt(60.0 * n0)}",
        "[model]\n" + "\n".join(f"{k} = {v!r}".replace("'", '"') for k, v in MODEL.items()),
        "[parameter_names]\n" + "\n".join(f"{k} = {v!r}".replace("'", '"') for k, v in NAMES.items()),
        "[parameters.particulars]\n" + _lists(_split(theta)),
        "# Prior spread (1 sigma) of each coefficient above: the std over MMG models whose coefficients are drawn\n"
        "# from their regressions' spread (linear hull: max(20 %, |Clarke - Kijima|); non-linear hull 50 %,\n"
        "# interaction 20 %, resistance 30 %, assumed where the regressions publish no scatter), each refitted.\n"
        f"[prior]\nsource = \"regression scatter propagated through the fit\"\ndraws = {draws}\nseed = {seed}\n"
        "[prior.std]\n" + _lists(_split(std)),
        "[particulars]\n"
        + "\n".join(
            f"{k} = {_fmt(v)}"
            for k, v in (
                ("length_m", p.length), ("beam_m", p.beam), ("draught_m", p.draught), ("block_coefficient", p.cb),
                ("speed_kn", p.speed_kn), ("rudder_area_m2", ship.rudder_area), ("propeller_diameter_m", ship.prop_diameter),
                ("pitch_ratio", pitch), ("mcr_kw", p.mcr_kw),
            )
            if v is not None
        ),
    ]  # fmt: skip
    return "\n\n".join(body) + "\n"


def build_profile(p: Particulars, *, oe_nfev: int = 15, draws: int = 12, seed: int = 0) -> Built:
    """The profile of the particulars ``p`` (see the module docstring); raises ParticularsError on
    particulars no ship has, FloatingPointError if the MMG model or the fit diverges."""
    check_particulars(p)
    pitch = p.pitch_ratio or (_pitch_for_rpm(p) if p.rpm else 0.75)
    power = _check_power(p, pitch)
    ship = mmg_ship(p, pitch)
    n0 = approach_rps(ship, p.speed)
    n_max = 1.15 * n0 if not p.mcr_kw else n0 * max(1.0, p.mcr_kw / power) ** (1.0 / 3.0)
    ts = sample_time(p)
    theta, fits = fit_profile(p, ship, n0, ts, n_max, oe_nfev)
    std = prior_std(p, ship, n0, ts, n_max, draws, seed)
    text = render(p, ship, pitch, n0, n_max, power, ts, theta, std, fits, draws, seed)
    profile = profile_from_dict(tomllib.loads(text), f"{p.name}.toml")
    notes = []
    if p.rpm and p.pitch_ratio:
        notes.append(f"the screw of P/D {pitch:g} holds {p.speed_kn:g} kn at {60 * n0:.1f} rpm, not the given {p.rpm:g} rpm")
    return Built(text, profile, ship, n0, notes, fits)
