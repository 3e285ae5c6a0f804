"""A ship profile document (decoded TOML or JSON) checked and turned into a :class:`ShipProfile`.

:func:`profile_from_dict` reads the document table by table, in named steps, each refusing a bad
field in one line that names the file, the field and what to give. This module reads the sizes, the
inputs, the model and the parameter sets; the optional tables are read by :mod:`primitives.profile_tables`,
the physical tables [helm], [engine], [rigid_body], [[pods]], [pod_model] by :mod:`primitives.physical_tables`,
a diagnosed model.json's own sections by :mod:`primitives.diagnosed_sections`, each with the field readers
of :mod:`primitives.profile_fields`; :func:`read_profile_file` decodes a .toml/.json file into such a document.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from primitives.diagnosed_sections import DIAGNOSED_FORMAT, MODEL_JSON_FIX, check_diagnosed_sections, check_model_json_as_ship
from primitives.model_json_ship import left_out, left_out_warning
from primitives.physical_tables import parse_pods, parse_rigid_body
from primitives.profile_fields import check_file_stem, need, per_dof
from primitives.profile_tables import (
    read_azimuth_thrusters,
    read_diagnosis,
    read_disturbances,
    read_helm_engine,
    read_input_limits,
    read_library,
    read_predictor,
    read_prior,
    read_vessel,
)
from primitives.ship import ACTUATORS, BASE_SIGNALS, DOFS, ROLL_DOFS, ROLL_SIGNALS, ProfileError, ShipProfile
from primitives.terms import TermError, TermSet, signals_used
from primitives.validate import MAX_PRIMITIVE_SAMPLES, check_table_keys, manoeuvre_samples, positive

# the names other modules import from here (the checks of a diagnosed model.json's sections moved out at stop 61)
__all__ = [
    "DIAGNOSED_FORMAT",
    "MODEL_JSON_FIX",
    "PROFILE_KEYS",
    "ProfileError",
    "check_diagnosed_sections",
    "check_file_stem",
    "check_model_json_as_ship",
    "profile_from_dict",
    "read_profile_file",
]

# Every top-level key a profile may hold: one list, so an engineer adding a table adds one line.
PROFILE_KEYS = frozenset(
    {
        "name",
        "vessel",  # the ship the profile models, as a recording's '# ship:' header names it (default: name)
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
        k: positive(need(d, k, src, (int, float), f"a number in {unit}, > 0"), f"{src}: field '{k}'", unit, ProfileError)
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
    name = need(d, "name", src, str, "the profile name, e.g. 'my-ship'")
    check_file_stem(name, f"{src}: field 'name'", ProfileError)
    vessel = read_vessel(d, src)
    sizes = _check_sizes(d, src)
    actuator, inputs = _actuator_inputs(d, src)
    _check_actuator_tables(d, src, actuator)
    dofs, model, names, known = _model(d, src, inputs)
    sets, sim_set, ins_set = _parameter_sets(d, src, model, dofs)
    limits = read_input_limits(d, src)
    thrusters = read_azimuth_thrusters(d, src, actuator, inputs)
    structure, structure_prior, rudder_share = read_diagnosis(d, src, dofs, known)
    rigid_body = parse_rigid_body(d, src, len(dofs), ProfileError)
    pods, pod_model = parse_pods(d, src, inputs, ProfileError) if actuator == "pods" else ((), None)
    pred, pred_names = read_predictor(d, src)
    library = read_library(d, src)
    helm, engine = read_helm_engine(d, src, actuator, inputs, limits, model, sets[sim_set], sizes["cruise_speed_mps"])
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
        disturbances=read_disturbances(d, src, sizes["cruise_speed_mps"]),
        source=str(d.get("source", "")),
        helm=helm,
        engine=engine,
        library=library,
        rigid_body=rigid_body,
        pods=pods,
        pod_model=pod_model,
        structure_terms=structure,
        structure_prior=structure_prior,
        prior_std=read_prior(d, src, model, dofs),
        rudder_thrust_share=rudder_share,
        load_warnings=(left_out_warning(src, dropped),) if dropped else (),
        vessel=vessel,
    )


def _actuator_inputs(d: dict, src: str) -> tuple[str, tuple[str, ...]]:
    """``actuator`` (default generalized forces) and the distinct input names."""
    actuator = d.get("actuator", "generalized")
    if actuator not in ACTUATORS:
        raise ProfileError(f"{src}: field 'actuator' must be one of {ACTUATORS}, got {actuator!r}")
    inputs = tuple(need(d, "inputs", src, list, "a list of input names"))
    if not inputs or not all(isinstance(x, str) and x for x in inputs) or len(set(inputs)) != len(inputs):
        raise ProfileError(f"{src}: field 'inputs' must be a non-empty list of distinct input names, got {list(inputs)!r}")
    return actuator, inputs


def _model(d: dict, src: str, inputs: tuple[str, ...]) -> tuple[tuple[str, ...], TermSet, tuple[tuple, ...], set[str]]:
    """[model] term lists and [parameter_names] per DOF (a roll list makes the ship 4-DOF): the
    DOFs, the compiled terms, the names and the signals a term may read."""
    dofs = ROLL_DOFS if isinstance(d.get("model"), dict) and "roll" in d["model"] else DOFS
    terms = per_dof(d, "model", src, str, "regressor term strings like 'u_r*|u_r|'", dofs, (src, "model"), ROLL_DOFS)
    names = per_dof(d, "parameter_names", src, str, "parameter names", dofs, (src, "parameter_names"))
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
    sets_raw = need(d, "parameters", src, dict, "a table of parameter sets, e.g. [parameters.true]")
    sets = {}
    for set_name, table in sets_raw.items():
        vals = per_dof(
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
