"""A battery of KVLCC2 recordings simulated with the MMG standard model (not the product's
model), each with one concealed effect, for judging ``shiptrial diagnose`` (issue 13).

Every case has, seeded:

- calm-water reference runs for ``--fit-on``: the standard manoeuvres of the delivery trials
  (IMO MSC.137(76)), of the ship as the model was made (no current, no wind, no fault; in the
  same water depth as the other runs): 35 deg turning circles to both sides, a 10/10 zig-zag
  to starboard and a 20/20 zig-zag to port. A trials engineer has these; one zig-zag alone
  (the battery's first choice, a 15/15) cannot teach a baseline the turning circle, and the
  structural misfit left (about 5 noise units in surge and sway) buried the effects;
- three runs to diagnose (10/10 zig-zag to starboard, 20/20 zig-zag to port, 35 deg turning
  circle to starboard) and two held-out runs for ``--validate`` (10/10 to port, 20/20 to
  starboard), all with the concealed effect;
- measurement noise, white or coloured (AR(1), coefficient 0.9, same variance);
- a ground truth: the effect names the diagnosis should report (names of BRIEF section 7)
  and, for each, the parameter keys of the diagnosis findings with the true value and the
  tolerance of the issue (current 30 % and 25 deg, delay 0.3 s, offset 0.5 deg, thrust loss
  5 points, wind 40 %; at model scale the delay tolerance is Froude-scaled).

Recordings are written as the CSV of BRIEF section 7 (columns t, x, y, psi, u, v, r, delta,
n and, when there is wind, wind_speed, wind_dir) with metadata lines ``# ship: kvlcc2``,
``# sample_time``, ``# scale``, ``# scale_factor``, ``# environment: sea`` and ``# rudder_sign: starboard-positive``
(the rudder angle in MMG's convention, converted to the ``kvlcc2`` profile's port-positive one on
reading), with wind ``# wind_reference: true`` (the anemometer's true wind, 0.3 m/s and 2 deg noise,
read through the ship's flow distortion: :func:`flow_distortion`). The wind loads are
Isherwood's (1972) (``tests.physics.isherwood``), with speed and direction gusts.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from tests.physics.mmg_kvlcc2 import (
    MODEL_SCALE,
    RHO,
    Environment,
    MMGShip,
    kvlcc2,
    self_propulsion_rps,
    wind_forces,
    with_effects,
)
from tests.physics.mmg_sim import Manoeuvre, Run
from tests.physics.mmg_sim import simulate_runs as _simulate_runs

CALM = [
    Manoeuvre("turn", 35, 0, 1, 800),
    Manoeuvre("turn", 35, 0, -1, 800),
    Manoeuvre("zigzag", 10, 10, 1, 550),
    Manoeuvre("zigzag", 20, 20, -1, 650),
]
DIAGNOSE = [Manoeuvre("zigzag", 10, 10, 1, 550), Manoeuvre("zigzag", 20, 20, -1, 650), Manoeuvre("turn", 35, 0, 1, 800)]
VALIDATE = [Manoeuvre("zigzag", 10, 10, -1, 550), Manoeuvre("zigzag", 20, 20, 1, 650)]

# full-scale measurement noise (std): u, v [m/s], r [rad/s], psi [rad], x, y [m]
NOISE_FULL = {"u": 0.02, "v": 0.01, "r": 2.0e-4, "psi": 2.0e-3, "xy": 1.0}
AR_COEF = 0.9
ANEMOMETER = (0.3, np.radians(2.0))  # anemometer noise (std): speed (full-scale m/s), direction (rad)
LEAD_IN_S = 300.0  # straight approach under the autopilot before each manoeuvre (full-scale s)
# a shallow-water-like change of the hull (not a published shallow-water model): larger sway
# and yaw damping and resistance, larger sway added mass. It applies to every run, the calm one
# included, so a baseline fitted on the calm run already holds it: nothing should be claimed.
SHALLOW = {"Y_v": -0.315 * 1.5, "N_r": -0.049 * 1.4, "N_v": -0.137 * 1.3, "R_0": 0.022 * 1.25, "m_y": 0.223 * 1.6}


@dataclass(frozen=True)
class Case:
    """One battery case. Magnitudes are full-scale values (Froude-scaled for a model)."""

    name: str
    effect: str | None  # None: control; "shallow_water": outside the candidate list
    magnitude: dict = field(default_factory=dict)
    scale: float = 1.0
    noise: str = "white"
    seed: int = 1
    n_diagnose: int = 3  # the first n of DIAGNOSE are diagnosed (2: the two zig-zags, no turning circle)


CASES: tuple[Case, ...] = (
    Case("control", None),
    Case("control-ar1", None, noise="ar1", seed=2),
    Case("current-0.7", "current", {"speed": 0.7, "toward_deg": 60.0}),
    Case("current-0.5-ar1", "current", {"speed": 0.5, "toward_deg": 215.0}, noise="ar1", seed=3),
    Case("delay-2.5", "actuator_delay", {"delay_s": 2.5}),
    Case("delay-4", "actuator_delay", {"delay_s": 4.0}, seed=4),
    Case("offset-1.5", "input_offset", {"offset_deg": 1.5}),
    Case("thrust-loss-20", "thrust_loss", {"loss": 0.20}),
    Case("wind-18", "wind", {"speed": 18.0, "from_deg": 45.0}),
    # issue 26: a gusty wind (15 % turbulence intensity, 20 s gusts) with the anemometer recorded
    Case("wind-18-gusty", "wind", {"speed": 18.0, "from_deg": 300.0, "gust": 0.15}, seed=11),
    # the same with the anemometer's relative (apparent) wind recorded, '# wind_reference: relative'
    Case("wind-18-gusty-relative", "wind", {"speed": 18.0, "from_deg": 300.0, "gust": 0.15, "reference": "relative"}, seed=11),
    # issue 26: a delay told from quadratic damping with two runs (the two zig-zags) only
    Case("delay-3-two-runs", "actuator_delay", {"delay_s": 3.0}, seed=12, n_diagnose=2),
    Case("gyro-bias", "sensor_bias", {"signal": "r", "bias": 5.0e-4}),
    Case("yaw-damping", "quadratic_damping", {"N_rr": -0.03}),
    Case("shallow-water", "shallow_water", {}),
    Case("model-control", None, scale=MODEL_SCALE, seed=5),
    Case("model-current-0.6", "current", {"speed": 0.6, "toward_deg": 300.0}, scale=MODEL_SCALE, seed=6),
    Case("model-delay-3", "actuator_delay", {"delay_s": 3.0}, scale=MODEL_SCALE, noise="ar1", seed=7),
    Case("model-offset-1", "input_offset", {"offset_deg": 1.0}, scale=MODEL_SCALE, seed=8),
    Case("model-thrust-loss-20", "thrust_loss", {"loss": 0.20}, scale=MODEL_SCALE, seed=9),
    Case("model-wind-15", "wind", {"speed": 15.0, "from_deg": 300.0}, scale=MODEL_SCALE, seed=10),
)


def case(name: str) -> Case:
    for c in CASES:
        if c.name == name:
            return c
    raise KeyError(f"no battery case {name!r}; cases: {', '.join(c.name for c in CASES)}")


@dataclass
class Generated:
    case: Case
    calm: list[Run]
    diagnose: list[Run]
    validate: list[Run]
    noisy: dict[str, list[dict[str, np.ndarray]]]  # role -> per-run recorded columns
    truth: dict
    sample_time: float
    calm_manoeuvres: list[Manoeuvre] | None = None  # None: CALM


def _setup(c: Case) -> tuple[MMGShip, MMGShip, Environment, dict]:
    """(calm ship, ship with the effect, environment of the effect runs, actuator settings)."""
    ship = kvlcc2(c.scale)
    ts = ship.time_scale
    if c.effect == "shallow_water":
        ship = with_effects(ship, **SHALLOW)
    eff_ship, env, act = ship, Environment(), {"delay_s": 0.0, "offset_rad": 0.0}
    m = c.magnitude
    if c.effect == "current":
        spd = m["speed"] * ts  # Froude: speeds scale as times, 1/sqrt(lambda)
        a = np.radians(m["toward_deg"])
        env = Environment(current_ne=(spd * np.cos(a), spd * np.sin(a)))
    elif c.effect == "wind":
        spd = m["speed"] * ts
        a = np.radians(m["from_deg"])
        gust = m.get("gust", 0.0)  # direction gusts 0.8 of the speed's (lateral vs longitudinal turbulence)
        env = Environment(wind_ne=(-spd * np.cos(a), -spd * np.sin(a)), gust=gust, gust_dir=0.8 * gust, gust_seed=c.seed)
    elif c.effect == "actuator_delay":
        act["delay_s"] = m["delay_s"] * ts
    elif c.effect == "input_offset":
        act["offset_rad"] = np.radians(m["offset_deg"])
    elif c.effect == "thrust_loss":
        eff_ship = with_effects(ship, thrust_factor=1.0 - m["loss"])
    elif c.effect == "quadratic_damping":
        eff_ship = with_effects(ship, extra_N_rr=m["N_rr"])
    return ship, eff_ship, env, act


_SIMULATED: dict[str, list[Run]] = {}


def simulate_runs(ship: MMGShip, mans: list[Manoeuvre], n: float, **kw) -> list[Run]:
    """``mmg_sim.simulate_runs``, remembered per process: the runs are noise-free (the noise and
    the anemometer are drawn afterwards, and the gusts' seed is part of ``env``), so the seeds of
    one case share them; a battery over five seeds simulates each case once (read-only use)."""
    key = repr((ship, mans, n, sorted(kw.items())))
    if key not in _SIMULATED:
        _SIMULATED[key] = _simulate_runs(ship, mans, n, **kw)
    return _SIMULATED[key]


def _noise(rng: np.random.Generator, shape: tuple[int, ...], std: float, kind: str) -> np.ndarray:
    w = rng.standard_normal(shape)
    if kind != "ar1":
        return std * w
    e = np.empty(shape)
    e[0] = w[0]
    g = np.sqrt(1.0 - AR_COEF**2)
    for k in range(1, shape[0]):
        e[k] = AR_COEF * e[k - 1] + g * w[k]
    return std * e


def _measure(
    run: Run,
    ship: MMGShip,
    rng: np.random.Generator,
    kind: str,
    bias: dict | None,
    wind_ne: tuple[float, float] | None,
    anemo: np.random.Generator | None = None,
    relative: bool = False,
) -> dict[str, np.ndarray]:
    """Recorded columns: the run plus measurement noise (and a sensor bias, if any)."""
    n = len(run.t)
    sq = ship.time_scale  # Froude: speeds and times x ts, rates / ts, lengths x ts^2
    cols = {
        "t": run.t.copy(),
        "x": run.x + _noise(rng, (n,), NOISE_FULL["xy"] * ship.time_scale**2, kind),
        "y": run.y + _noise(rng, (n,), NOISE_FULL["xy"] * ship.time_scale**2, kind),
        "psi": run.psi + _noise(rng, (n,), NOISE_FULL["psi"], kind),
        "u": run.u + _noise(rng, (n,), NOISE_FULL["u"] * sq, kind),
        "v": run.v + _noise(rng, (n,), NOISE_FULL["v"] * sq, kind),
        "r": run.r + _noise(rng, (n,), NOISE_FULL["r"] / ship.time_scale, kind),
        "delta": run.delta_mmg.copy(),  # MMG's convention (starboard-positive), said in the header
        "n": run.n.copy(),
    }
    if bias:
        cols[bias["signal"]] = cols[bias["signal"]] + bias["value"]
    if wind_ne is not None:  # the anemometer: true wind, or relative when asked
        spd, frm = _anemometer(run, wind_ne, relative)
        cols["wind_speed"] = spd + _noise(anemo, (n,), ANEMOMETER[0] * sq, "white")
        cols["wind_dir"] = (frm + _noise(anemo, (n,), ANEMOMETER[1], "white")) % (2 * np.pi)
    return cols


def flow_distortion(gamma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(speed factor, direction error rad) of a mast-top anemometer for the relative wind
    coming from ``gamma`` off the bow: the flow sped up over the bow and superstructure front
    (+4 % from ahead), slowed in their wake (-9 % from astern) and turned by up to 4 deg, of the
    size measured on merchant ships and research vessels (Yelland et al. 2002; Moat, Yelland &
    Pascal 2005: -10 to +5 % in speed depending on the relative direction)."""
    return 1.0 + 0.04 * np.cos(gamma) - 0.05 * (1.0 - np.cos(gamma)) ** 2 / 4.0, np.radians(4.0) * np.sin(2.0 * gamma)


def _anemometer(run: Run, wind_ne: tuple[float, float], relative: bool) -> tuple[np.ndarray, np.ndarray]:
    """The anemometer's noise-free reading (speed, direction it comes from): the relative wind
    on the mast, distorted by the ship's flow (:func:`flow_distortion`), and for a true-wind
    record converted to the earth frame with the ship's velocity and heading, as the ship's
    wind system does (the distortion stays in it)."""
    wn, we = run.wind_ne(wind_ne)  # air velocity toward, north/east, the gusts included
    c, s = np.cos(run.psi), np.sin(run.psi)
    qa, qv = c * wn + s * we - run.u, -s * wn + c * we - run.v  # the air relative to the ship, body axes
    frm = np.arctan2(-qv, -qa)  # the angle off the bow it comes from
    gain, turn = flow_distortion(frm)
    spd, frm = np.hypot(qa, qv) * gain, frm + turn
    if relative:
        return spd, frm
    qa, qv = -spd * np.cos(frm), -spd * np.sin(frm)  # read back to the air's velocity, body axes
    ta, tv = qa + run.u, qv + run.v  # plus the ship's: the true wind in body axes
    tn, te = c * ta - s * tv, s * ta + c * tv
    return np.hypot(tn, te), np.arctan2(-te, -tn)


def _wind_truth(ship: MMGShip, runs: list[Run], wind_ne: tuple[float, float]) -> dict:
    """The true wind as the diagnosis reports it, from the truth alone: the wind's mean
    acceleration of the ship per DOF (surge, sway m/s^2; yaw rad/s^2) over every step of the
    diagnosed runs, the truth's (Isherwood) loads with the gusts beyond the still-air drag of the
    ship's own motion (which the calm runs have too, so a baseline fitted on them holds it), at
    the true velocities, through the truth's mass matrix; and each DOF's share of the wind effect
    (its mean over the noise per unit time), which weights the relative errors into one figure."""
    Minv = np.linalg.inv(ship.mass_matrix())
    acc = []
    for r in runs:
        wn, we = r.wind_ne(wind_ne)  # the gusts included
        wind = np.stack(wind_forces(ship, r.u, r.v, r.psi, np.stack([wn, we])), axis=-1)
        still = np.stack(wind_forces(ship, r.u, r.v, r.psi, np.zeros(2)), axis=-1)
        acc.append(((wind - still) @ Minv.T)[:-1])  # the steps k -> k+1
    mean = np.concatenate(acc).mean(axis=0)
    ts = ship.time_scale
    sig = (NOISE_FULL["u"] * ts, NOISE_FULL["v"] * ts, NOISE_FULL["r"] / ts)
    keys = ("wind_accel_surge", "wind_accel_sway", "wind_accel_yaw")
    return {
        "coefficients": {k: float(m) for k, m in zip(keys, mean)},
        "weights": {k: float((m / s) ** 2) for k, m, s in zip(keys, mean, sig)},
    }


def truth_of(c: Case, ship: MMGShip, runs: list[Run], env: Environment, Ts: float) -> dict:
    """What a right diagnosis says: effect names and, per effect, {key: [true, tolerance, kind]}
    (kind: abs, rel, angle; tolerances of issue 13, Froude-scaled where they carry units)."""
    ts = ship.time_scale
    m = c.magnitude
    base = {
        "case": c.name,
        "scale": "model" if c.scale != 1.0 else "full",
        "scale_factor": c.scale,
        "noise": c.noise,
        "seed": c.seed,
        "concealed": c.effect,
        "magnitude": m,
    }
    if c.effect is None or c.effect == "shallow_water":
        return base | {"effects": [], "checks": {}}
    if c.effect == "current":
        chk = {"speed_mps": [m["speed"] * ts, 0.30, "rel"], "toward_deg": [m["toward_deg"], 25.0, "angle"]}
    elif c.effect == "actuator_delay":
        chk = {"delay_s": [m["delay_s"] * ts, 0.3 * ts, "abs"]}
    elif c.effect == "input_offset":
        chk = {"offset_deg": [m["offset_deg"], 0.5, "abs"]}
    elif c.effect == "thrust_loss":
        chk = {"loss_percent": [100.0 * m["loss"], 5.0, "abs"]}
    elif c.effect == "sensor_bias":
        chk = {"signal": [m["signal"], None, "equal"], "bias": [m["bias"] / ts if m["signal"] == "r" else m["bias"], 0.30, "rel"]}
    elif c.effect == "quadratic_damping":
        Minv = np.linalg.inv(ship.mass_matrix())
        val = Ts * Minv[2, 2] * m["N_rr"] * 0.5 * RHO * ship.L**4 * ship.d  # per-sample coefficient of r|r|
        chk = {"dof": ["yaw", None, "equal"], "term": ["r*|r|", None, "equal"], "value": [val, 0.40, "rel"]}
    elif c.effect == "wind":  # 40 %: the truth's and the estimator's published coefficients differ in shape
        w = _wind_truth(ship, runs, env.wind_ne)
        chk = {"wind": [w["coefficients"], 0.40, "wind"], "weights": [w["weights"], None, "info"]}
    else:
        raise ValueError(c.effect)
    return base | {"effects": [c.effect], "checks": {c.effect: chk}}


def _visibility(c: Case, ship: MMGShip, n: float, runs: list[Run], Ts: float, mans: list[Manoeuvre]) -> dict[str, float]:
    """How visible the effect is: RMS over the diagnosed runs of (run with the effect - the same
    manoeuvre without it) per channel, in units of the measurement noise (noise-free runs)."""
    calm = simulate_runs(ship, mans[: len(runs)], n, sample_time=Ts, lead_in_s=LEAD_IN_S)
    bias = c.magnitude["bias"] / Ts if c.effect == "sensor_bias" else 0.0
    sig = {"u": NOISE_FULL["u"] * Ts, "v": NOISE_FULL["v"] * Ts, "r": NOISE_FULL["r"] / Ts}
    out = {}
    for k in ("u", "v", "r"):
        d = np.concatenate(
            [
                getattr(a, k)[:m] - getattr(b, k)[:m] + (bias if k == c.magnitude.get("signal") else 0.0)
                for a, b in zip(runs, calm)
                for m in [min(len(a.t), len(b.t))]
            ]
        )
        out[k] = float(np.sqrt(np.mean(d**2)) / sig[k])
    return out


def oracle_manoeuvres() -> list[Manoeuvre]:
    """The calm runs of the oracle study: the diagnosed and the validation manoeuvres themselves."""
    return DIAGNOSE + VALIDATE


def lasting(mans: list[Manoeuvre], duration_s: float | None) -> list[Manoeuvre]:
    """``mans`` each lasting ``duration_s`` (full-scale s; None: as they are)."""
    return list(mans) if duration_s is None else [replace(m, duration_s=duration_s) for m in mans]


def generate(c: Case, *, visibility: bool = False, oracle_calm: bool = False, duration_s: float | None = None) -> Generated:
    """Simulate every run of the case (seeded) and its ground truth (with ``visibility``: also
    how far the effect moves the diagnosed runs, in noise units). With ``duration_s`` every
    manoeuvre lasts that long instead (full-scale s; the recording starts 30 s before it): the
    size of the issue's battery (benchmarks/bench_diagnose_size.py).

    With ``oracle_calm`` the calm (--fit-on) runs are instead the diagnosed and validation
    manoeuvres without the effect (:func:`oracle_manoeuvres`, noise from their own seeded
    stream): a baseline fitted on them carries almost no structural misfit, which isolates the
    search's own defects (a study, not a user's situation). The other runs are unchanged."""
    ship, eff_ship, env, act = _setup(c)
    Ts = ship.time_scale  # 1 s at full scale, Froude-scaled for a model
    n = self_propulsion_rps(kvlcc2(c.scale))  # the approach rpm the crew sets, for every run
    calm_m, diag_m, val_m = (lasting(m, duration_s) for m in (CALM, DIAGNOSE, VALIDATE))
    calm = simulate_runs(ship, calm_m, n, sample_time=Ts, lead_in_s=LEAD_IN_S)
    runs = simulate_runs(eff_ship, diag_m + val_m, n, env=env, sample_time=Ts, lead_in_s=LEAD_IN_S, **act)
    diag, val = runs[: c.n_diagnose], runs[len(diag_m) :]
    rng = np.random.default_rng(c.seed)
    bias = {"signal": c.magnitude["signal"], "value": c.magnitude["bias"] / Ts} if c.effect == "sensor_bias" else None
    rel = c.magnitude.get("reference") == "relative"
    anemo = np.random.default_rng([c.seed, 27])  # its own stream: the motion's noise is as before the anemometer's
    noisy = {
        "calm": [_measure(r, ship, rng, c.noise, None, None) for r in calm],
        "diagnose": [_measure(r, ship, rng, c.noise, bias, env.wind_ne, anemo, rel) for r in diag],
        "validate": [_measure(r, ship, rng, c.noise, bias, env.wind_ne, anemo, rel) for r in val],
    }
    truth = truth_of(c, eff_ship, diag, env, Ts)
    if visibility:
        truth["visibility_rms_over_noise"] = _visibility(c, ship, n, diag, Ts, diag_m)
    if not oracle_calm:
        return Generated(c, calm, diag, val, noisy, truth, Ts)
    mans = lasting(oracle_manoeuvres(), duration_s)
    calm = simulate_runs(ship, mans, n, sample_time=Ts, lead_in_s=LEAD_IN_S)
    rng_o = np.random.default_rng([c.seed, 1])  # its own stream: the other runs' noise is unchanged
    noisy["calm"] = [_measure(r, ship, rng_o, c.noise, None, None) for r in calm]
    truth["oracle_calm"] = True
    return Generated(c, calm, diag, val, noisy, truth, Ts, calm_manoeuvres=mans)


def csv_text(cols: dict[str, np.ndarray], meta: dict[str, str]) -> str:
    head = [f"# {k}: {v}" for k, v in meta.items()]
    names = list(cols)
    arr = np.column_stack([cols[k] for k in names])
    body = "\n".join(",".join(f"{x:.9g}" for x in row) for row in arr)
    return "\n".join(head + [",".join(names), body]) + "\n"


def write_case(g: Generated, out: str | Path) -> dict[str, list[Path]]:
    """Write the case's recordings (CSV) and truth.json into ``out``; the paths by role."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    c = g.case
    meta = {
        "ship": "kvlcc2",
        "sample_time": f"{g.sample_time:.9g}",
        "scale": "model" if c.scale != 1.0 else "full",
        "scale_factor": f"{c.scale:g}",
        "generated": "tests/physics/mmg_battery.py (MMG standard model, Yasukawa & Yoshimura 2015)",
        "environment": "sea",
        "rudder_sign": "starboard-positive",  # MMG's convention, converted to the kvlcc2 profile's on reading
    }
    if c.effect == "wind":
        meta["wind_reference"] = c.magnitude.get("reference", "true")
    paths: dict[str, list[Path]] = {}
    mans = {"calm": g.calm_manoeuvres or CALM, "diagnose": DIAGNOSE, "validate": VALIDATE}
    for role, runs in g.noisy.items():
        paths[role] = []
        for m, cols in zip(mans[role], runs):
            p = out / f"{c.name}_{role}_{m.label}.csv"
            p.write_text(csv_text(cols, meta | {"manoeuvre": m.label}), encoding="utf-8")
            paths[role].append(p)
    (out / "truth.json").write_text(json.dumps(g.truth, indent=2), encoding="utf-8")
    return paths
