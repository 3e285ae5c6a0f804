"""The optional tables of a ship profile document, checked (:func:`primitives.profile_document.profile_from_dict`
reads them in this order after the sizes, the inputs, the model and the parameter sets): [[thrusters]] of an azimuth
ship, the predictor, the manoeuvre library, [helm] and [engine] of a rudder/propeller ship, [prior], [input_limits],
[disturbances] and [diagnosis]."""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from primitives.diagnosed_sections import diagnosed_current
from primitives.physical_tables import Engine, Helm, parse_helm_engine
from primitives.profile_fields import per_dof
from primitives.ship import BASE_SIGNALS, DEFAULT_STRUCTURE_PRIOR, LIBRARIES, ProfileError, Thruster
from primitives.terms import TermError, TermSet, signals_used
from primitives.unit_ranges import check_angle_limits
from primitives.validate import check_table_keys, finite, in_range, positive


def read_azimuth_thrusters(d: dict, src: str, actuator: str, inputs: tuple[str, ...]) -> tuple[Thruster, ...]:
    """[[thrusters]]; an azimuth profile's inputs must be n1, alpha1, ... with one thruster each."""
    thrusters = _thrusters(d, src)
    if actuator == "azimuth":
        expect = tuple(x for i in range(1, len(thrusters) + 1) for x in (f"n{i}", f"alpha{i}"))
        if not thrusters or inputs != expect:
            raise ProfileError(
                f"{src}: field 'inputs' of an azimuth profile must be {list(expect) or ['n1', 'alpha1']} with one [[thrusters]] entry each"
            )
    return thrusters


def read_predictor(d: dict, src: str) -> tuple[tuple[tuple, ...] | None, tuple[tuple, ...] | None]:
    """The optional linear-in-parameters predictor's terms and names (3 DOFs)."""
    if "predictor" not in d:
        return None, None
    pred = per_dof(d, "predictor", src, str, "regressor term strings", table_of=(src, "predictor"))
    pred_names = per_dof(d, "predictor_names", src, str, "parameter names", table_of=(src, "predictor_names"))
    try:
        TermSet(pred)
    except TermError as exc:
        raise ProfileError(f"{src}: field 'predictor': {exc}") from None
    return pred, pred_names


def read_library(d: dict, src: str) -> str:
    library = d.get("library", "")
    if library and library not in LIBRARIES:
        raise ProfileError(f"{src}: field 'library' must be one of {LIBRARIES} (or absent), got {library!r}")
    return library


def ship_name_words(name: str) -> tuple[str, ...]:
    """A ship's name without case and punctuation: its runs of letters and digits ('KVLCC2_Linear', 'kvlcc2 linear'
    and 'KVLCC2.linear' are all ('kvlcc2', 'linear'); 'modelship' is not 'model-ship'). The one rule by which
    ``diagnose``, ``mass`` and ``plan-trial --resume`` compare a recording's ``# ship:`` header with a profile or a
    plan's ship (stop 62: diagnose and mass had two, resume an exact match)."""
    return tuple(w for w in re.split(r"[\W_]+", name.casefold()) if w)


def names_ship(header: str, name: str, vessel: str = "") -> bool:
    """Whether a ``# ship:`` header names the profile ``name`` or the ship it models (``vessel``, see
    :func:`read_vessel`), by :func:`ship_name_words`."""
    said = ship_name_words(header)
    return said in (ship_name_words(name), ship_name_words(vessel or name))


def read_vessel(d: dict, src: str) -> str:
    """``vessel``: the ship a profile is a model of, as a recording's ``# ship:`` header names it (``kvlcc2`` for
    ``kvlcc2-linear``); diagnose and mass accept a header naming it or the profile (:func:`names_ship`). Empty: absent."""
    vessel = d.get("vessel", "")
    ok = isinstance(vessel, str) and any(c.isalnum() for c in vessel) and not any(ord(c) < 32 for c in vessel)
    if "vessel" in d and not ok:
        raise ProfileError(
            f"{src}: field 'vessel' must name the ship this profile models as a recording's '# ship:' header does, "
            f'one line with a letter or digit (e.g. vessel = "kvlcc2"), or be left out; got {vessel!r}'
        )
    return vessel.strip()


def read_helm_engine(
    d: dict, src: str, actuator: str, inputs: tuple[str, ...], limits: dict, model: TermSet, theta: np.ndarray, cruise: float
) -> tuple[Helm, Engine]:
    """[helm] and [engine] of a rudder/propeller ship (inputs delta, n); defaults for the others."""
    if actuator != "rudder_propeller":
        return Helm(), Engine()
    if inputs != ("delta", "n"):
        raise ProfileError(
            f"{src}: field 'inputs' of a rudder_propeller profile must be ['delta', 'n'] (rudder rad, propeller rev/s)"
        )
    return parse_helm_engine(
        d, src, limits, lambda: _starboard_sign(model, theta, cruise), ProfileError, lambda n: _thrust_at_rest(model, theta, n)
    )


PRIOR_KEYS = ("std", "source", "draws", "seed")


def read_prior(d: dict, src: str, model: TermSet, dofs: tuple[str, ...]) -> np.ndarray | None:
    """[prior] std: one finite value >= 0 per model term, the 1-sigma spread of the simulation
    set's coefficients (``shiptrial profile new`` writes it from the regressions' scatter)."""
    if "prior" not in d:
        return None
    table = d["prior"]
    if not isinstance(table, dict) or not isinstance(table.get("std"), dict):
        raise ProfileError(f"{src}: field 'prior' must be a table with a [prior.std] table of surge/sway/yaw lists")
    check_table_keys(table, PRIOR_KEYS, src, "[prior]", ProfileError)
    vals = per_dof({"p": table["std"]}, "p", f"{src} [prior.std]", (int, float), "numbers", dofs, (src, "prior.std"))
    for i, dof in enumerate(dofs):
        if len(vals[i]) != len(model.terms[i]):
            raise ProfileError(f"{src}: field 'prior.std.{dof}' has {len(vals[i])} values for {len(model.terms[i])} terms")
    arr = np.array([v for dof in vals for v in dof], dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ProfileError(f"{src}: field 'prior.std' must hold finite numbers >= 0 (a 1-sigma spread per coefficient)")
    return arr


def read_input_limits(d: dict, src: str) -> dict[str, tuple[float, float]]:
    """[input_limits]: ``input = [min, max]`` (that each names an input is checked once the
    actuator's inputs are, so a wrong input list is reported as such)."""
    table = d.get("input_limits", {})
    if not isinstance(table, dict):
        raise ProfileError(f"{src}: field 'input_limits' must be a table of name = [min, max]")

    limits = {}
    for k, v in table.items():
        what = f"{src}: field 'input_limits.{k}'"
        if not (isinstance(v, list) and len(v) == 2):
            raise ProfileError(f"{what} must be [min, max] of finite numbers with min < max, got {v!r}")
        lo, hi = (finite(x, what, "the input's units", ProfileError) for x in v)
        if not lo < hi:
            raise ProfileError(f"{what} must be [min, max] with min < max, got {v!r}")
        check_angle_limits(str(k), lo, hi, what, ProfileError)
        limits[k] = (lo, hi)
    return limits


THRUSTER_KEYS = ("name", "x", "y")


def _thrusters(d: dict, src: str) -> tuple[Thruster, ...]:
    table = d.get("thrusters", [])
    if not isinstance(table, list) or not all(isinstance(t, dict) and "x" in t for t in table):
        raise ProfileError(f"{src}: field 'thrusters' must be a list of [[thrusters]] tables with x (and y) in metres")
    for i, t in enumerate(table):
        check_table_keys(t, THRUSTER_KEYS, src, f"[[thrusters]] number {i + 1}", ProfileError)
    return tuple(
        Thruster(
            str(t.get("name", f"thruster{i + 1}")),
            finite(t["x"], f"{src}: field 'thrusters.{i}.x'", "m", ProfileError),
            finite(t.get("y", 0.0), f"{src}: field 'thrusters.{i}.y'", "m", ProfileError),
        )
        for i, t in enumerate(table)
    )


# Disturbance levels a profile may state (Disturbances.from_profile reads them): key -> length
# (0 = scalar, None = true/false).
DISTURBANCE_KEYS: dict[str, int | None] = {
    "current_mean_ne": 2,
    "current_sample_std": 0,
    "measurement_std": 3,
    "heading_std": 0,
    "current_turning": None,
}


def read_disturbances(d: dict, src: str, cruise_speed: float) -> dict[str, Any]:
    """[disturbances]: the levels, checked. ``current_turning`` (the current fixed in the earth
    frame turns in body axes as the ship turns, primitives.simulate.Disturbances) defaults to on
    for a diagnosed model.json whose findings include a current: the diagnosis scored that current
    so (diagnose.model), and the same model must simulate the same way when it plans a trial."""
    table = d.get("disturbances", {})
    if not isinstance(table, dict):
        raise ProfileError(f"{src}: field 'disturbances' must be a table")
    check_table_keys(table, DISTURBANCE_KEYS, src, "[disturbances]", ProfileError)
    table = dict(table)
    if "current_turning" in table:
        if not isinstance(table["current_turning"], bool):
            raise ProfileError(
                f"{src}: field 'disturbances.current_turning' must be true or false, got {table['current_turning']!r}"
            )
    elif diagnosed_current(d):
        table["current_turning"] = True
    for k, v in table.items():
        n = DISTURBANCE_KEYS[k]
        if n is None:
            continue
        vals = v if n else [v]
        if not isinstance(vals, list) or len(vals) != max(n, 1):
            raise ProfileError(f"{src}: field 'disturbances.{k}' must be {f'a list of {n} numbers' if n else 'a number'}")
        for x in vals:
            y = finite(x, f"{src}: field 'disturbances.{k}'", "SI units", ProfileError)
            if k != "current_mean_ne" and y < 0:
                raise ProfileError(f"{src}: field 'disturbances.{k}' is a standard deviation: must be >= 0, got {x!r}")
    speed = float(np.hypot(*table.get("current_mean_ne", (0.0, 0.0))))
    if speed >= cruise_speed:
        raise ProfileError(
            f"{src}: field 'disturbances.current_mean_ne' is a current of {speed:.3g} m/s, not below the ship's "
            f"cruise_speed_mps {cruise_speed:g}: give the current in m/s (north, east), slower than the ship"
        )
    return table


DIAGNOSIS_KEYS = ("structure", "structure_prior", "rudder_thrust_share")


def read_diagnosis(
    d: dict, src: str, dofs: tuple[str, ...], known: set[str]
) -> tuple[tuple[tuple[str, ...], ...] | None, float, float]:
    """The optional [diagnosis] table: ``structure`` (term lists per DOF that a --fit-on refit
    adds to the model), ``structure_prior`` (> 0: the prior std of their coefficients, as a
    fraction of the coefficient that alone would explain the increments' spread) and
    ``rudder_thrust_share`` (0..1: the fraction of a thrust loss the rudder force loses with
    the propeller slipstream, ``ShipProfile.rudder_thrust_share``)."""
    table = d.get("diagnosis")
    if table is None:
        return None, DEFAULT_STRUCTURE_PRIOR, 0.0
    if not isinstance(table, dict):
        raise ProfileError(f"{src}: field 'diagnosis' must be a table with 'structure' (and 'structure_prior')")
    check_table_keys(table, DIAGNOSIS_KEYS, src, "[diagnosis]", ProfileError)
    prior = positive(
        table.get("structure_prior", DEFAULT_STRUCTURE_PRIOR), f"{src}: field 'diagnosis.structure_prior'", "", ProfileError
    )
    share = in_range(
        table.get("rudder_thrust_share", 0.0), f"{src}: field 'diagnosis.rudder_thrust_share'", 0.0, 1.0, "", ProfileError
    )
    if "structure" not in table:
        return None, prior, share
    terms = per_dof(
        table,
        "structure",
        f"{src} [diagnosis]",
        str,
        "regressor term strings like 'v_r^3*U^-1'",
        dofs,
        (src, "diagnosis.structure"),
    )
    try:
        unknown = signals_used(terms) - known
        TermSet(terms)
    except TermError as exc:
        raise ProfileError(f"{src}: field 'diagnosis.structure': {exc}") from None
    if unknown:
        raise ProfileError(f"{src}: field 'diagnosis.structure' uses unknown signals {sorted(unknown)}; known: {sorted(known)}")
    return terms, prior, share


def _starboard_sign(model: TermSet, theta: np.ndarray, cruise: float) -> float:
    """+1 if a positive delta gives a starboard (positive) yaw acceleration at cruise speed, else -1."""
    rates = []
    for delta in (0.0, 0.1):
        sig = {k: 0.0 for k in BASE_SIGNALS} | {"u": cruise, "u_r": cruise, "u_q": cruise, "U": cruise, "delta": delta, "n": 0.0}
        rates.append(float(model.increments(sig, theta)[2]))
    return 1.0 if rates[1] >= rates[0] else -1.0


def _thrust_at_rest(model: TermSet, theta: np.ndarray, n: float) -> float:
    """Surge increment of the model at rest, rudder midships, shaft at ``n`` rev/s."""
    # U is a divisor (floored in the kernel); at rest every term it divides holds a zero velocity
    sig = {k: 0.0 for k in BASE_SIGNALS} | {"U": 1.0, "delta": 0.0, "n": n}
    return float(model.increments(sig, theta)[0])
