"""A ship profile document (decoded TOML or JSON) checked and turned into a :class:`ShipProfile`.

:func:`profile_from_dict` reads the document table by table, in named steps, each refusing a bad
field in one line that names the file, the field and what to give (the physical tables [helm],
[engine], [rigid_body], [[pods]], [pod_model] are read by :mod:`primitives.physical_tables`);
:func:`read_profile_file` decodes a .toml/.json file into such a document.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from primitives.errors import UserError
from primitives.model_json_ship import left_out, left_out_warning
from primitives.physical_tables import Engine, Helm, parse_helm_engine, parse_pods, parse_rigid_body
from primitives.ship import (
    ACTUATORS,
    BASE_SIGNALS,
    DEFAULT_STRUCTURE_PRIOR,
    DOFS,
    LIBRARIES,
    ROLL_DOFS,
    ROLL_SIGNALS,
    ProfileError,
    ShipProfile,
    Thruster,
)
from primitives.terms import TermError, TermSet, signals_used
from primitives.unit_ranges import check_angle_limits
from primitives.validate import MAX_PRIMITIVE_SAMPLES, check_table_keys, finite, in_range, manoeuvre_samples, positive

# Every top-level key a profile may hold: one list, so an engineer adding a table adds one line.
PROFILE_KEYS = frozenset(
    {
        "name",
        "description",
        "source",
        "sample_time",
        "length_m",
        "beam_m",
        "draught_m",
        "cruise_speed_mps",
        "actuator",
        "inputs",
        "input_limits",
        "model",
        "parameter_names",
        "parameters",
        "simulation_set",
        "instrument_set",
        "predictor",
        "predictor_names",
        "thrusters",
        "disturbances",
        "helm",  # optional helm table (rudder-ship manoeuvres)
        "engine",  # optional engine table (rudder-ship manoeuvres)
        "library",  # which built-in manoeuvre dictionary the ship uses (primitives.library)
        "augmentations",  # effects a diagnosed model.json lists beside its terms (diagnose.report.model_dict)
        "diagnosed_model",  # what a diagnosed model.json was scored on (diagnose.model_file)
        "rigid_body",  # mass, inertias, CoG and added mass of a 4-DOF physical model (primitives.rigidbody)
        "pods",
        "pod_model",  # podded propulsion (primitives.pods), actuator = "pods"
        "diagnosis",  # baseline structure a --fit-on refit may add (ShipProfile.structure_terms)
        "prior",  # prior spread (1 sigma) of each coefficient of the simulation set (ShipProfile.prior_std)
        "particulars",  # the main particulars a profile was made from (primitives.particulars), a record
    }
)
# Physical sizes a profile must give, all finite and > 0 (unit in the message).
MAX_LENGTHS_PER_SAMPLE = 2.0
POSITIVE_FIELDS = (("sample_time", "s"), ("length_m", "m"), ("beam_m", "m"), ("draught_m", "m"), ("cruise_speed_mps", "m/s"))


def _check_keys(d: dict, src: str) -> None:
    """Refuse unknown top-level keys, suggesting the nearest known one (a misspelt key must not
    silently fall back to a default)."""
    check_table_keys(d, sorted(PROFILE_KEYS), src, "the top level", ProfileError)


def _check_sizes(d: dict, src: str) -> dict[str, float]:
    sizes = {
        k: positive(_need(d, k, src, (int, float), f"a number in {unit}, > 0"), f"{src}: field '{k}'", unit, ProfileError)
        for k, unit in POSITIVE_FIELDS
    }
    # a manoeuvre spans ~20 ship lengths: too slow a ship or too short a sample time makes it endless
    n = manoeuvre_samples(20 * sizes["length_m"], sizes["cruise_speed_mps"], sizes["sample_time"])
    if n > MAX_PRIMITIVE_SAMPLES:
        raise ProfileError(
            f"{src}: 20 ship lengths ({20 * sizes['length_m']:g} m) at cruise_speed_mps {sizes['cruise_speed_mps']:g} m/s "
            f"take {n:.3g} samples of {sizes['sample_time']:g} s (limit {MAX_PRIMITIVE_SAMPLES:,}): check the units of "
            "length_m, cruise_speed_mps and sample_time"
        )
    # a discrete-time manoeuvring model samples many times per ship length (the thesis's ships: 8
    # and 10 times); a sample time in which the ship sails lengths is a unit mistake (ms, minutes)
    lengths = sizes["sample_time"] * sizes["cruise_speed_mps"] / sizes["length_m"]
    if lengths > MAX_LENGTHS_PER_SAMPLE:
        raise ProfileError(
            f"{src}: field 'sample_time' = {sizes['sample_time']:g} s: at cruise_speed_mps {sizes['cruise_speed_mps']:g} m/s the "
            f"ship sails {lengths:.3g} ship lengths per sample, too coarse for a manoeuvring model (at most "
            f"{MAX_LENGTHS_PER_SAMPLE:g}); give sample_time in seconds, e.g. {0.1 * sizes['length_m'] / sizes['cruise_speed_mps']:.3g} s "
            "(a tenth of a ship length per sample)"
        )
    return sizes


# Tables only one kind of actuator reads: in another ship's profile they would be silently ignored.
ACTUATOR_TABLES = {
    "helm": "rudder_propeller",
    "engine": "rudder_propeller",
    "pods": "pods",
    "pod_model": "pods",
    "thrusters": "azimuth",
}


def _check_actuator_tables(d: dict, src: str, actuator: str) -> None:
    """Refuse a table that only another actuator's ships read ([helm] in an azimuth profile, ...)."""
    for key, reader in ACTUATOR_TABLES.items():
        if d.get(key) not in (None, {}, []) and actuator != reader:  # an empty one says nothing
            table = f"[[{key}]]" if key in ("pods", "thrusters") else f"[{key}]"
            raise ProfileError(
                f"{src}: table {table} is read only in an actuator = {reader!r} profile, and this one's actuator "
                f"is {actuator!r}: remove {table} (or make the ship {reader!r})"
            )


def profile_from_dict(d: dict[str, Any], src: str = "<profile>") -> ShipProfile:
    """Validate a decoded TOML/JSON document and build a profile. The steps run in the order a
    reader meets the fields (sizes, inputs, model, parameters, actuators, optional tables), so the
    first bad field is the one reported."""
    _check_keys(d, src)
    name = _need(d, "name", src, str, "the profile name, e.g. 'my-ship'")
    check_file_stem(name, f"{src}: field 'name'", ProfileError)
    sizes = _check_sizes(d, src)
    actuator, inputs = _actuator_inputs(d, src)
    _check_actuator_tables(d, src, actuator)
    dofs, model, names, known = _model(d, src, inputs)
    sets, sim_set, ins_set = _parameter_sets(d, src, model, dofs)
    limits = _input_limits(d, src)
    thrusters = _azimuth_thrusters(d, src, actuator, inputs)
    structure, structure_prior, rudder_share = _diagnosis(d, src, dofs, known)
    rigid_body = parse_rigid_body(d, src, len(dofs), ProfileError)
    pods, pod_model = parse_pods(d, src, inputs, ProfileError) if actuator == "pods" else ((), None)
    pred, pred_names = _predictor(d, src)
    library = _library(d, src)
    helm, engine = _helm_engine(d, src, actuator, inputs, limits, model, sets[sim_set], sizes["cruise_speed_mps"])
    check_table_keys(limits, inputs, src, "[input_limits]", ProfileError)
    check_diagnosed_sections(d, src)
    check_model_json_as_ship(d, src, actuator, inputs, sizes["sample_time"])
    dropped = left_out(d, model.terms)
    return ShipProfile(
        name=name,
        description=str(d.get("description", "")),
        sample_time=sizes["sample_time"],
        length_m=sizes["length_m"],
        beam_m=sizes["beam_m"],
        draught_m=sizes["draught_m"],
        cruise_speed_mps=sizes["cruise_speed_mps"],
        actuator=actuator,
        inputs=inputs,
        input_limits=limits,
        model_terms=model.terms,
        parameter_names=names,
        parameter_sets=sets,
        simulation_set=sim_set,
        instrument_set=ins_set,
        predictor_terms=pred,
        predictor_names=pred_names,
        thrusters=thrusters,
        disturbances=_disturbances(d, src, sizes["cruise_speed_mps"]),
        source=str(d.get("source", "")),
        helm=helm,
        engine=engine,
        library=library,
        rigid_body=rigid_body,
        pods=pods,
        pod_model=pod_model,
        structure_terms=structure,
        structure_prior=structure_prior,
        prior_std=_prior(d, src, model, dofs),
        rudder_thrust_share=rudder_share,
        load_warnings=(left_out_warning(src, dropped),) if dropped else (),
    )


def _actuator_inputs(d: dict, src: str) -> tuple[str, tuple[str, ...]]:
    """``actuator`` (default generalized forces) and the distinct input names."""
    actuator = d.get("actuator", "generalized")
    if actuator not in ACTUATORS:
        raise ProfileError(f"{src}: field 'actuator' must be one of {ACTUATORS}, got {actuator!r}")
    inputs = tuple(_need(d, "inputs", src, list, "a list of input names"))
    if not inputs or not all(isinstance(x, str) and x for x in inputs) or len(set(inputs)) != len(inputs):
        raise ProfileError(f"{src}: field 'inputs' must be a non-empty list of distinct input names, got {list(inputs)!r}")
    return actuator, inputs


def _model(d: dict, src: str, inputs: tuple[str, ...]) -> tuple[tuple[str, ...], TermSet, tuple[tuple, ...], set[str]]:
    """[model] term lists and [parameter_names] per DOF (a roll list makes the ship 4-DOF): the
    DOFs, the compiled terms, the names and the signals a term may read."""
    dofs = ROLL_DOFS if isinstance(d.get("model"), dict) and "roll" in d["model"] else DOFS
    terms = _per_dof(d, "model", src, str, "regressor term strings like 'u_r*|u_r|'", dofs, (src, "model"), ROLL_DOFS)
    names = _per_dof(d, "parameter_names", src, str, "parameter names", dofs, (src, "parameter_names"))
    try:
        model = TermSet(terms)
        used = signals_used(terms)
    except TermError as exc:
        raise ProfileError(f"{src}: field 'model': {exc}") from None
    known = BASE_SIGNALS | set(inputs) | (ROLL_SIGNALS if dofs == ROLL_DOFS else set())
    unknown = used - known
    if unknown:
        raise ProfileError(
            f"{src}: field 'model' uses unknown signals {sorted(unknown)}; known: {sorted(known)}"
            + (" (p, phi, tau_k need the roll DOF: add model.roll)" if unknown & ROLL_SIGNALS else "")
        )
    for i, dof in enumerate(dofs):
        if len(names[i]) != len(terms[i]):
            raise ProfileError(f"{src}: field 'parameter_names.{dof}' has {len(names[i])} names for {len(terms[i])} terms")
    return dofs, model, names, known


def _parameter_sets(d: dict, src: str, model: TermSet, dofs: tuple[str, ...]) -> tuple[dict[str, np.ndarray], str, str]:
    """[parameters.SET] vectors (one finite value per term) and the simulation and instrument sets."""
    terms = model.terms
    sets_raw = _need(d, "parameters", src, dict, "a table of parameter sets, e.g. [parameters.true]")
    sets = {}
    for set_name, table in sets_raw.items():
        vals = _per_dof(
            {"p": table}, "p", f"{src} [parameters.{set_name}]", (int, float), "numbers", dofs, (src, f"parameters.{set_name}")
        )
        for i, dof in enumerate(dofs):
            if len(vals[i]) != len(terms[i]):
                raise ProfileError(
                    f"{src}: field 'parameters.{set_name}.{dof}' has {len(vals[i])} values for {len(terms[i])} terms"
                )
        arr = np.array([v for dof in vals for v in dof], dtype=float)
        if not np.all(np.isfinite(arr)):
            raise ProfileError(f"{src}: field 'parameters.{set_name}' holds a value that is not a finite number")
        sets[set_name] = arr
    if not sets:
        raise ProfileError(f"{src}: field 'parameters' holds no parameter set")
    sim_set = d.get("simulation_set", next(iter(sets)))
    ins_set = d.get("instrument_set", sim_set)
    for key, val in (("simulation_set", sim_set), ("instrument_set", ins_set)):
        if not isinstance(val, str) or val not in sets:
            raise ProfileError(f"{src}: field '{key}' names {val!r}, which is not in [parameters]")
    return sets, sim_set, ins_set


def _azimuth_thrusters(d: dict, src: str, actuator: str, inputs: tuple[str, ...]) -> tuple[Thruster, ...]:
    """[[thrusters]]; an azimuth profile's inputs must be n1, alpha1, ... with one thruster each."""
    thrusters = _thrusters(d, src)
    if actuator == "azimuth":
        expect = tuple(x for i in range(1, len(thrusters) + 1) for x in (f"n{i}", f"alpha{i}"))
        if not thrusters or inputs != expect:
            raise ProfileError(
                f"{src}: field 'inputs' of an azimuth profile must be {list(expect) or ['n1', 'alpha1']} with one [[thrusters]] entry each"
            )
    return thrusters


def _predictor(d: dict, src: str) -> tuple[tuple[tuple, ...] | None, tuple[tuple, ...] | None]:
    """The optional linear-in-parameters predictor's terms and names (3 DOFs)."""
    if "predictor" not in d:
        return None, None
    pred = _per_dof(d, "predictor", src, str, "regressor term strings", table_of=(src, "predictor"))
    pred_names = _per_dof(d, "predictor_names", src, str, "parameter names", table_of=(src, "predictor_names"))
    try:
        TermSet(pred)
    except TermError as exc:
        raise ProfileError(f"{src}: field 'predictor': {exc}") from None
    return pred, pred_names


def _library(d: dict, src: str) -> str:
    library = d.get("library", "")
    if library and library not in LIBRARIES:
        raise ProfileError(f"{src}: field 'library' must be one of {LIBRARIES} (or absent), got {library!r}")
    return library


def _helm_engine(
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


def _prior(d: dict, src: str, model: TermSet, dofs: tuple[str, ...]) -> np.ndarray | None:
    """[prior] std: one finite value >= 0 per model term, the 1-sigma spread of the simulation
    set's coefficients (``shiptrial profile new`` writes it from the regressions' scatter)."""
    if "prior" not in d:
        return None
    table = d["prior"]
    if not isinstance(table, dict) or not isinstance(table.get("std"), dict):
        raise ProfileError(f"{src}: field 'prior' must be a table with a [prior.std] table of surge/sway/yaw lists")
    check_table_keys(table, PRIOR_KEYS, src, "[prior]", ProfileError)
    vals = _per_dof({"p": table["std"]}, "p", f"{src} [prior.std]", (int, float), "numbers", dofs, (src, "prior.std"))
    for i, dof in enumerate(dofs):
        if len(vals[i]) != len(model.terms[i]):
            raise ProfileError(f"{src}: field 'prior.std.{dof}' has {len(vals[i])} values for {len(model.terms[i])} terms")
    arr = np.array([v for dof in vals for v in dof], dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ProfileError(f"{src}: field 'prior.std' must hold finite numbers >= 0 (a 1-sigma spread per coefficient)")
    return arr


def check_file_stem(name: str, what: str, err: type[Exception]) -> None:
    """A ship's name names the files written for it (``<name>-trial.gpx``, the plan cache's entries): text that
    stays one file name in the output directory, never a path out of it."""
    if not name.strip() or name.strip(".") == "" or any(c in name for c in "/\\") or any(ord(c) < 32 for c in name):
        raise err(
            f"{what} {name!r} names the files written for the ship: give a plain name (no '/', '\\', control "
            "characters; not empty, '.' or '..'), e.g. 'my-ship'"
        )


def _need(d: dict, key: str, src: str, kind: type | tuple[type, ...], hint: str) -> Any:
    if key not in d:
        raise ProfileError(f"{src}: missing field '{key}' ({hint})")
    val = d[key]
    if not isinstance(val, kind) or isinstance(val, bool):
        raise ProfileError(f"{src}: field '{key}' must be {hint}, got {val!r}")
    return val


def _per_dof(
    d: dict,
    key: str,
    src: str,
    item: type,
    hint: str,
    dofs: tuple[str, ...] = DOFS,
    table_of: tuple[str, str] | None = None,
    accept: tuple[str, ...] | None = None,
) -> tuple[tuple, ...]:
    """The lists of a per-DOF table; ``table_of`` (file, table name) refuses keys other than
    ``accept`` (default the DOFs)."""
    table = _need(d, key, src, dict, f"a table with {', '.join(dofs)} lists")
    if table_of is not None:
        check_table_keys(table, accept or dofs, table_of[0], f"[{table_of[1]}]", ProfileError)
    out = []
    for dof in dofs:
        vals = _need(table, dof, f"{src} [{key}]", list, hint)
        for v in vals:
            if not isinstance(v, item) or isinstance(v, bool):
                raise ProfileError(f"{src}: field '{key}.{dof}' must hold only {hint}, got {v!r}")
        out.append(tuple(float(v) if item is not str else v for v in vals))
    return tuple(out)


def _input_limits(d: dict, src: str) -> dict[str, tuple[float, float]]:
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


def _disturbances(d: dict, src: str, cruise_speed: float) -> dict[str, Any]:
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
    elif _diagnosed_current(d):
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


def _diagnosed_current(d: dict) -> bool:
    """Whether ``d`` is a diagnosed model.json whose findings include a current (in the summary,
    ``augmentations``, or in the exact model, ``diagnosed_model.candidates``)."""
    dm = d.get("diagnosed_model")
    if not isinstance(dm, dict):
        return False
    listed = [a for a in (d.get("augmentations"), dm.get("candidates")) if isinstance(a, list)]
    return any(isinstance(a, dict) and a.get("effect") == "current" for lst in listed for a in lst)


DIAGNOSIS_KEYS = ("structure", "structure_prior", "rudder_thrust_share")


def _diagnosis(
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
    terms = _per_dof(
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


# The sections a diagnosed model.json (diagnose.model_file) adds beside the profile. A profile
# read from such a file reads neither, but refuses a malformed one; diagnose.model_file.load_model
# checks the rest of what it reads (the baseline profile, the candidates and their values).
AUGMENTATION_KEYS = ("effect", "dof", "parameters")
DIAGNOSED_MODEL_KEYS = ("format", "note", "baseline_profile", "half_sample_s", "candidates")
MODEL_JSON_FIX = "write the model.json again with `shiptrial diagnose --out DIR`, or remove the field"


def check_diagnosed_sections(d: dict[str, Any], src: str, error: type[UserError] = ProfileError) -> None:
    """Refuse a malformed ``augmentations`` list or ``diagnosed_model`` table of a diagnosed
    model.json in one line naming the file, the field and the fix."""
    aug = d.get("augmentations")
    if aug is not None:
        if not isinstance(aug, list) or not all(isinstance(a, dict) for a in aug):
            raise error(
                f"{src}: field 'augmentations' must be a list of tables with {', '.join(AUGMENTATION_KEYS)}: {MODEL_JSON_FIX}"
            )
        for i, a in enumerate(aug):
            check_table_keys(a, AUGMENTATION_KEYS, src, f"[[augmentations]] number {i + 1}", error)
            if not isinstance(a.get("effect"), str) or not a["effect"]:
                raise error(
                    f"{src}: field 'augmentations.{i}.effect' must name the effect (e.g. 'current'), got {a.get('effect')!r}: "
                    f"{MODEL_JSON_FIX}"
                )
            if a.get("dof") not in (None, *ROLL_DOFS):
                raise error(
                    f"{src}: field 'augmentations.{i}.dof' must be one of {list(ROLL_DOFS)} or null, got {a.get('dof')!r}: "
                    f"{MODEL_JSON_FIX}"
                )
            if not isinstance(a.get("parameters", {}), dict):
                raise error(
                    f"{src}: field 'augmentations.{i}.parameters' must be a table of the effect's values, got "
                    f"{a['parameters']!r}: {MODEL_JSON_FIX}"
                )
    dm = d.get("diagnosed_model")
    if dm is not None:
        if not isinstance(dm, dict):
            raise error(
                f"{src}: field 'diagnosed_model' must be a table with {', '.join(DIAGNOSED_MODEL_KEYS)}: {MODEL_JSON_FIX}"
            )
        check_table_keys(dm, DIAGNOSED_MODEL_KEYS, src, "[diagnosed_model]", error)


# diagnose.model_file.FORMAT (the library layer does not import the diagnosis; a test keeps them equal)
DIAGNOSED_FORMAT = "shiptrial-diagnosed-model/1"


def check_model_json_as_ship(d: dict[str, Any], src: str, actuator: str, inputs: tuple[str, ...], sample_time: float) -> None:
    """A diagnosed model.json given as a ship (``--ship model.json``): the profile part is what
    the commands read, so what would make it another model than the one scored is refused in one
    line naming the file, the field and the fix: a format of another version, a
    ``diagnosed_model`` whose baseline is another ship (actuator, inputs, sample time) or whose
    half-sample shift or candidate list is malformed, and a current among the findings that the
    profile part has lost (``disturbances.current_mean_ne``)."""
    dm = d.get("diagnosed_model")
    if dm is None:
        return
    if dm.get("format") != DIAGNOSED_FORMAT:
        raise ProfileError(
            f"{src}: field 'diagnosed_model.format' must be {DIAGNOSED_FORMAT!r}, got {dm.get('format')!r}: {MODEL_JSON_FIX}"
        )
    base = dm.get("baseline_profile")
    if not isinstance(base, dict):
        raise ProfileError(
            f"{src}: field 'diagnosed_model.baseline_profile' must be the scored ship profile (a table): {MODEL_JSON_FIX}"
        )
    ours = {"actuator": actuator, "inputs": list(inputs), "sample_time": sample_time}
    theirs = {
        "actuator": base.get("actuator", "generalized"),
        "inputs": base.get("inputs"),
        "sample_time": base.get("sample_time"),
    }
    for k, v in ours.items():
        if theirs[k] != v:
            raise ProfileError(
                f"{src}: field 'diagnosed_model.baseline_profile.{k}' is {theirs[k]!r} and the profile's '{k}' is "
                f"{v!r}: the two parts are different ships; {MODEL_JSON_FIX}"
            )
    half = dm.get("half_sample_s", 0.0)
    if isinstance(half, bool) or not isinstance(half, int | float) or not 0.0 <= half <= sample_time:
        raise ProfileError(
            f"{src}: field 'diagnosed_model.half_sample_s' must be a number of seconds in 0..{sample_time:g} "
            f"(the model's half-sample shift), got {half!r}: {MODEL_JSON_FIX}"
        )
    cands = dm.get("candidates", [])
    if not isinstance(cands, list) or not all(isinstance(c, dict) for c in cands):
        raise ProfileError(f"{src}: field 'diagnosed_model.candidates' must be a list of tables: {MODEL_JSON_FIX}")
    if _diagnosed_current(d) and "current_mean_ne" not in (d.get("disturbances") or {}):
        raise ProfileError(
            f"{src}: field 'disturbances.current_mean_ne' is missing, and the findings ('augmentations') include "
            f"a current: {MODEL_JSON_FIX}"
        )


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


def read_profile_file(path: Path) -> ShipProfile:
    """The profile in a .toml or .json file."""
    from primitives.io import read_input_text

    if path.suffix.lower() not in (".json", ".toml"):
        raise ProfileError(f"{path}: a profile file must end in .toml or .json")
    text = read_input_text(path, ProfileError, "a .toml/.json ship profile")
    try:
        data = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ProfileError(f"{path}: not valid {path.suffix[1:].upper()}: {exc}") from None
    except RecursionError:
        raise ProfileError(f"{path}: nested too deeply to be a profile") from None
    if not isinstance(data, dict):
        raise ProfileError(f"{path}: the document must be a table/object")
    return profile_from_dict(data, str(path))
