"""The library of candidate physics: each an augmentation of the model with physical parameters.

Every candidate adds one or more *slots* to the augmented simulator (:mod:`diagnose.model`):

- ``term``: an extra regressor term (or a change of a surge term the model has: resistance,
  thrust deduction) with a coefficient in one DOF of ``nu(k+1) = nu(k) +
  Phi^T theta`` ((3.60), (9.1)) - quadratic damping (v|v|, r|r|, r|v|, v|r|, u|u|), missing
  coupling (v r, u r, u v, r^2), speed-dependent thrust (u tau_x, u n), wind loads (when
  wind is measured; :mod:`diagnose.windload`) and roll coupling (phi, when roll is measured);
- ``steady_wind``: a steady wind not recorded, its air velocity (north, east) over the recording
  set, the yaw arm of its lateral load and the scale of its surge load, whose loads follow the relative wind angle as the ship turns (:mod:`diagnose.windload`);
- ``current``: a constant n-frame current (north, east) entering through u_r, v_r (Fossen 2021, ch. 2;
  in predictor form the cos psi / sin psi regressors of (5.67)-(5.70));
- ``delay``: a common actuator time delay (seconds; fractional, linear interpolation);
- ``offset``: a constant input offset, the input acts as ``x - x0`` (neutral rudder angle,
  thruster misalignment);
- ``bias``: a constant sensor bias, measured = true + b (Källström 1977, theta15..theta17);
- ``scale``: an inertia change of one DOF, its increment scaled by ``1 + s`` (the podded-ship MSc thesis, 5.2);
- ``thrust``: a thrust loss, every surge term in the thrust signal scaled by ``1 - f`` and the
  rudder terms (sway/yaw terms in delta or n) by ``1 - s f``, s the rudder's slipstream share
  (profile ``rudder_thrust_share``, changed by a following ``thrust_share`` slot).

Names of effects are fixed (they are model.json's keys).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diagnose import current_direct, windload
from diagnose.recording import Recording
from primitives.ship import DOFS, ShipProfile

SIGNALS = ("u", "v", "r")
STEADY_WIND = "wind:not-recorded"  # the key of the steady-wind candidate (no wind columns)

QUADRATIC = {0: ["u_r*|u_r|"], 1: ["v_r*|v_r|", "r*|v_r|", "v_r*|r|", "r*|r|"], 2: ["r*|r|", "r*|v_r|", "v_r*|r|", "v_r*|v_r|"]}
COUPLING = {0: ["v_r*r", "r^2", "v_r^2"], 1: ["u_r*r", "u_r*v_r"], 2: ["u_r*v_r", "u_r*r"]}


@dataclass(frozen=True)
class Slot:
    """One augmentation parameter: kind in (term, current, steady_wind, delay, offset, bias, scale, thrust, thrust_share)."""

    kind: str
    name: str
    dof: int | None = None
    term: str | None = None
    index: int | None = None  # input index (offset), signal index (bias), 0/1 north/east (current)


@dataclass(frozen=True)
class Candidate:
    effect: str
    key: str  # unique, e.g. "quadratic_damping:yaw:r*|r|"
    slots: tuple[Slot, ...]
    dof: int | None = None
    description: str = ""


def canonical_term(term: str) -> frozenset[str]:
    """Term identity without current (u_r == u when the model has no current)."""
    return frozenset(f.strip().replace("u_r", "u").replace("v_r", "v").replace("r^2", "r*r") for f in term.split("*"))


def _has(profile: ShipProfile, dof: int, term: str) -> bool:
    return canonical_term(term) in {canonical_term(t) for t in profile.model_terms[dof]}


def _factors(term: str) -> set[str]:
    """The signals a term multiplies (powers, absolute values and lever arms dropped)."""
    return {f.strip("|").split("^")[0].split("@")[0] for f in term.split("*")}


def thrust_signal(profile: ShipProfile) -> str:
    return {"rudder_propeller": "n"}.get(profile.actuator, "tau_x")


def build_library(profile: ShipProfile, recordings: list[Recording]) -> tuple[list[Candidate], list[dict]]:
    """All candidates for this ship and these recordings, and the ones that cannot be tested.

    A candidate cannot be tested when the recordings do not excite it (constant heading for a
    current, constant inputs for a delay, constant speed for thrust loss, no measured wind or
    roll, no motion in the term's signals); it is then listed with the reason instead of being
    guessed.
    """
    cands: list[Candidate] = []
    untestable: list[dict] = []
    y = np.concatenate([r.y for r in recordings])
    for add in (_environment, _actuators, _propulsion, _hull_terms, _sensors_and_inertia):
        c, u = add(profile, recordings, y)
        cands += c
        untestable += u
    return _excited(cands, untestable, y)


Found = tuple[list[Candidate], list[dict]]  # candidates, and those that cannot be tested (with the reason)


def _environment(profile: ShipProfile, recordings: list[Recording], y: np.ndarray) -> Found:
    """A current (through u_r, v_r, when the heading turns enough) and, when measured, wind;
    neither for a run recorded in a basin or towing tank (header ``# environment:``), which has
    no current and no wind: a misfit there is the model's, not the water's."""
    cands: list[Candidate] = []
    untestable: list[dict] = []
    tank = [r.source for r in recordings if r.in_tank]
    if tank:
        why = (
            f"recorded in a basin or towing tank (header '# environment:' of {', '.join(tank)}), which has no current and no wind"
        )
        windy = [r.source for r in recordings if r.in_tank and r.wind_ne is not None]
        wind_why = why + (f"; the recorded wind columns of {', '.join(windy)} are not used" if windy else "")
        return cands, [{"effect": "current", "reason": why}, {"effect": "wind", "reason": wind_why}]
    used = {f for dof in profile.model_terms for t in dof for f in t.replace("|", "").split("*")}
    spread = float(np.ptp(np.concatenate([r.psi for r in recordings])))
    measured = current_direct.measure(recordings)
    if current_direct.from_track_alone(recordings):
        untestable.append(
            {
                "effect": "current",
                "reason": "u, v were derived from the track (no u, v columns, or a model test's track derivatives) and "
                "no speed through the water was recorded: a current would be a misfit rotating with the heading, which a model error can mimic, so "
                "it cannot be told from one; record the speed through the water (columns u_water, v_water) to measure it",
            }
        )
    elif measured is not None and measured.speed < 2.0 * measured.std:
        untestable.append({"effect": "current", "reason": f"none: {measured.text()}, within 2 std of no current"})
    elif not ({"u_r", "v_r"} & {f.split("^")[0] for f in used}):
        untestable.append({"effect": "current", "reason": "the model has no terms in u_r or v_r through which a current acts"})
    elif spread < np.radians(45.0):
        untestable.append(
            {
                "effect": "current",
                "reason": f"the heading spans only {np.degrees(spread):.0f} deg; a current "
                "fixed in the earth frame is told apart from a constant force only when the heading "
                "changes (run a turn of at least 45 deg, better 360 deg)",
            }
        )
    else:
        cands.append(
            Candidate(
                "current",
                "current",
                (Slot("current", "current_n", index=0), Slot("current", "current_e", index=1)),
                description="constant current in the earth frame (through u_r, v_r)"
                + (f"; {measured.text()}" if measured is not None else ""),
            )
        )
    if all(r.wind_ne is not None for r in recordings):
        cands.append(
            Candidate(
                "wind",
                "wind",
                tuple(
                    Slot("term", name, dof=i, term=t)
                    for name, i, t in zip(
                        ("wind_surge", "wind_sway", "wind_yaw", "wind_yaw_arm"), windload.DOF_OF, windload.SIGNALS
                    )
                ),
                description="wind loads of the recorded wind: Blendermann's (1994) loaded-tanker coefficients "
                "on areas from the main particulars, the magnitude of each DOF and the yaw arm refitted",
            )
        )
    elif any(r.wind_ne is not None for r in recordings):
        untestable.append(
            {
                "effect": "wind",
                "reason": "wind recorded in some runs only (columns wind_speed, wind_dir): record it in every run or in none",
            }
        )
    elif spread < np.radians(45.0):
        untestable.append(
            {
                "effect": "wind",
                "reason": f"no measured wind (columns wind_speed, wind_dir), and the heading spans only {np.degrees(spread):.0f} deg: "
                "a steady wind is told from a constant force only by its loads changing as the ship turns",
            }
        )
    else:
        cands.append(
            Candidate(
                "wind",
                STEADY_WIND,
                (
                    Slot("steady_wind", "wind_n", index=0),
                    Slot("steady_wind", "wind_e", index=1),
                    Slot("steady_wind", "wind_yaw_arm", index=2),
                    Slot("steady_wind", "wind_surge_scale", index=3),
                ),
                description="wind (not recorded): a steady wind of unknown speed and direction, its loads following the "
                "relative wind angle as the ship turns (Blendermann's (1994) loaded-tanker coefficients on areas from the "
                "main particulars, scaled by the ship's mass and added mass; the yaw arm and the surge load's scale refitted)",
            )
        )
    return cands, untestable


def _actuators(profile: ShipProfile, recordings: list[Recording], y: np.ndarray) -> Found:
    """A common actuator delay (when the inputs move) and a constant offset of each input."""
    cands: list[Candidate] = []
    untestable: list[dict] = []
    x = np.concatenate([r.inputs_for(profile.inputs) for r in recordings])
    moving = np.std(np.diff(x, axis=0), axis=0) > 1e-9 * (1 + np.abs(x).max(axis=0))
    if np.any(moving):
        cands.append(
            Candidate("actuator_delay", "actuator_delay", (Slot("delay", "delay_s"),), description="time delay of all actuators")
        )
    else:
        untestable.append({"effect": "actuator_delay", "reason": "the inputs never change, so a delay has no effect"})
    for j, name in enumerate(profile.inputs):
        if profile.actuator == "rudder_propeller" and name == "n":
            continue  # an rpm offset is a thrust scale: covered by thrust_loss / refit
        cands.append(
            Candidate(
                "input_offset",
                f"input_offset:{name}",
                (Slot("offset", f"offset_{name}", index=j),),
                description=f"constant offset of input {name}",
            )
        )
    return cands, untestable


def _propulsion(profile: ShipProfile, recordings: list[Recording], y: np.ndarray) -> Found:
    """Thrust falling with speed, a constant thrust fraction (the rudder's slipstream share with
    it) and resistance changes: a surge deficiency is named instead of masking the rest."""
    cands: list[Candidate] = []
    untestable: list[dict] = []
    tsig = thrust_signal(profile)
    if _has(profile, 0, f"u_r*{tsig}"):
        untestable.append({"effect": "thrust_loss", "reason": f"the model already has u_r*{tsig}"})
    elif np.ptp(y[:, 0]) < 0.05 * max(np.abs(y[:, 0]).max(), 1e-9):
        untestable.append(
            {
                "effect": "thrust_loss",
                "reason": "the speed hardly changes, so a speed-dependent thrust "
                "cannot be told from a constant one (run an acceleration or a speed change)",
            }
        )
    else:
        cands.append(
            Candidate(
                "thrust_loss",
                "thrust_loss",
                (Slot("term", "coefficient", dof=0, term=f"u_r*{tsig}"),),
                dof=0,
                description=f"thrust falling with speed (u_r*{tsig})",
            )
        )
    thrust_terms = [t for t in profile.model_terms[0] if tsig in _factors(t)]
    if thrust_terms:  # one fraction of the whole thrust (every term in n): a fouled propeller, a changed thrust deduction
        slots = (Slot("thrust", "loss_fraction", dof=0),)
        what = f"thrust lower by a constant fraction ({', '.join(thrust_terms)} scaled together)"
        if profile.rudder_thrust_share > 0 and tsig == "n":  # the rudder in the slipstream loses its share of it
            slots += (Slot("thrust_share", "rudder_share_change", dof=0),)
            what += f", the rudder force by its slipstream share of it (profile {profile.rudder_thrust_share:g})"
        cands.append(Candidate("thrust_loss", "thrust_loss:fraction", slots, dof=0, description=what))
    for t in profile.model_terms[0]:
        if _factors(t) <= {"u", "u_r"}:
            cands.append(
                Candidate(
                    "resistance_change",
                    f"resistance_change:{t}",
                    (Slot("term", "coefficient", dof=0, term=t),),
                    dof=0,
                    description=f"hull resistance changed ({t})",
                )
            )
    return cands, untestable


def _hull_terms(profile: ShipProfile, recordings: list[Recording], y: np.ndarray) -> Found:
    """Quadratic damping and missing coupling terms per DOF."""
    cands: list[Candidate] = []
    for i in range(3):
        for t in QUADRATIC[i]:
            # a term the model has is offered as a change of it (a coefficient added to the
            # profile's): a finding only while the baseline holds that term (select drops it
            # when the term's own parameter is refitted, which would take the change itself);
            # in surge that change is the resistance_change of _propulsion
            if i == 0 and _has(profile, i, t):
                continue
            what = f"{t} in {DOFS[i]}" + (" changed" if _has(profile, i, t) else "")
            cands.append(
                Candidate(
                    "quadratic_damping",
                    f"quadratic_damping:{DOFS[i]}:{t}",
                    (Slot("term", "value", dof=i, term=t),),
                    dof=i,
                    description=what,
                )
            )
        for t in COUPLING[i]:
            if not _has(profile, i, t):
                cands.append(
                    Candidate(
                        "missing_coupling",
                        f"missing_coupling:{DOFS[i]}:{t}",
                        (Slot("term", "value", dof=i, term=t),),
                        dof=i,
                        description=f"{t} in {DOFS[i]}",
                    )
                )
    return cands, []


def _sensors_and_inertia(profile: ShipProfile, recordings: list[Recording], y: np.ndarray) -> Found:
    """Sensor biases, inertia changes and, when roll is measured, roll coupling."""
    cands: list[Candidate] = []
    untestable: list[dict] = []
    for i, s in enumerate(SIGNALS):
        cands.append(
            Candidate(
                "sensor_bias",
                f"sensor_bias:{s}",
                (Slot("bias", f"bias_{s}", dof=i, index=i),),
                dof=i,
                description=f"constant bias of measured {s}",
            )
        )
    for i in range(3):
        cands.append(
            Candidate(
                "inertia_change",
                f"inertia_change:{DOFS[i]}",
                (Slot("scale", "scale", dof=i),),
                dof=i,
                description=f"{DOFS[i]} inertia differs (increment scaled)",
            )
        )
    if all("phi" in r.channels for r in recordings):
        cands.append(
            Candidate(
                "roll_coupling",
                "roll_coupling",
                (Slot("term", "phi_sway", dof=1, term="phi"), Slot("term", "phi_yaw", dof=2, term="phi")),
                description="roll angle feeding sway and yaw",
            )
        )
    else:
        untestable.append({"effect": "roll_coupling", "reason": "no measured roll (column phi)"})
    return cands, untestable


def _excited(cands: list[Candidate], untestable: list[dict], y: np.ndarray) -> Found:
    """The candidates whose term signals move beyond the noise in the recordings; the others
    are added to the untestable ones."""
    keep = []
    d2 = y[2:] - 2 * y[1:-1] + y[:-2]
    noise = np.median(np.abs(d2), axis=0) * 1.4826 / np.sqrt(6.0)
    for c in cands:
        if c.effect in ("quadratic_damping", "missing_coupling"):
            sigs = {f.strip("|").split("^")[0].replace("_r", "") for f in c.slots[0].term.split("*")}
            idx = [SIGNALS.index(s) for s in sigs if s in SIGNALS]
            if any(np.std(y[:, k]) < max(3 * noise[k], 1e-9) for k in idx):
                untestable.append(
                    {
                        "effect": c.effect,
                        "dof": DOFS[c.dof],
                        "term": c.slots[0].term,
                        "reason": f"{'/'.join(sorted(sigs))} hardly moves beyond the noise in the recordings",
                    }
                )
                continue
        keep.append(c)
    return keep, untestable
