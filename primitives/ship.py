"""Ship profiles: the data that describe one ship model (states, inputs, structure, parameters).

Built-in profiles live as TOML files in ``primitives/profiles``; users can load their own from
TOML or JSON with :func:`load_profile`. A profile is the single source of truth for a model's
structure (regressor terms per DOF) and its parameter sets.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from primitives.errors import UserError
from primitives.physical_tables import POD_MODEL_KEYS, Engine, Helm, parse_helm_engine, parse_pods, parse_rigid_body
from primitives.pods import Pod, PodModel
from primitives.rigidbody import RigidBody
from primitives.terms import TermError, TermSet, signals_used
from primitives.validate import MAX_PRIMITIVE_SAMPLES, finite, manoeuvre_samples, positive, unknown_key

PROFILE_DIR = Path(__file__).with_name("profiles")
DOFS = ("surge", "sway", "yaw")
# A profile with a roll term list is surge-sway-yaw-roll (seed 000); roll is appended so yaw
# stays the third state of every ship.
ROLL_DOFS = DOFS + ("roll",)
STATES = ("u", "v", "r")
ACTUATORS = ("generalized", "azimuth", "rudder_propeller", "pods")
# Signals every model may read besides its own inputs.
BASE_SIGNALS = {"u", "v", "r", "u_r", "v_r", "u_q", "v_q", "psi", "tau_x", "tau_y", "tau_n", "U"}
# Signals only a model with the roll DOF has: roll rate, roll angle, actuator roll moment.
ROLL_SIGNALS = {"p", "phi", "tau_k"}


class ProfileError(UserError):
    """A ship profile file is malformed; the message names the file and the field."""


# Every top-level key a profile may hold: one list, so an engineer adding a table adds one line.
PROFILE_KEYS = frozenset({
    "name", "description", "source", "sample_time", "length_m", "beam_m", "draught_m", "cruise_speed_mps",
    "actuator", "inputs", "input_limits", "model", "parameter_names", "parameters", "simulation_set",
    "instrument_set", "predictor", "predictor_names", "thrusters", "disturbances",
    "helm",  # optional helm table (rudder-ship manoeuvres)
    "engine",  # optional engine table (rudder-ship manoeuvres)
    "library",  # which built-in manoeuvre dictionary the ship uses (primitives.library)
    "augmentations",  # effects a diagnosed model.json lists beside its terms (diagnose.report.model_dict)
    "diagnosed_model",  # what a diagnosed model.json was scored on (diagnose.model_file)
    "rigid_body",  # mass, inertias, CoG and added mass of a 4-DOF physical model (primitives.rigidbody)
    "pods", "pod_model",  # podded propulsion (primitives.pods), actuator = "pods"
    "diagnosis",  # baseline structure a --fit-on refit may add (ShipProfile.structure_terms)
})
# Physical sizes a profile must give, all finite and > 0 (unit in the message).
# Prior std of a [diagnosis] structure coefficient, as a fraction of the coefficient that alone
# would explain its DOF's increments (diagnose.api.term_scales), when the profile gives none.
DEFAULT_STRUCTURE_PRIOR = 0.01
POSITIVE_FIELDS = (("sample_time", "s"), ("length_m", "m"), ("beam_m", "m"), ("draught_m", "m"), ("cruise_speed_mps", "m/s"))


def _check_keys(d: dict, src: str) -> None:
    """Refuse unknown top-level keys, suggesting the nearest known one (a misspelt key must not
    silently fall back to a default)."""
    bad = unknown_key(d, sorted(PROFILE_KEYS))
    if bad:
        raise ProfileError(f"{src}: unknown field {bad[0]!r}{bad[1]}")


def _check_sizes(d: dict, src: str) -> dict[str, float]:
    sizes = {k: positive(_need(d, k, src, (int, float), f"a number in {unit}, > 0"), f"{src}: field '{k}'", unit, ProfileError)
             for k, unit in POSITIVE_FIELDS}
    # a manoeuvre spans ~20 ship lengths: too slow a ship or too short a sample time makes it endless
    n = manoeuvre_samples(20 * sizes["length_m"], sizes["cruise_speed_mps"], sizes["sample_time"])
    if n > MAX_PRIMITIVE_SAMPLES:
        raise ProfileError(
            f"{src}: 20 ship lengths ({20 * sizes['length_m']:g} m) at cruise_speed_mps {sizes['cruise_speed_mps']:g} m/s "
            f"take {n:.3g} samples of {sizes['sample_time']:g} s (limit {MAX_PRIMITIVE_SAMPLES:,}): check the units of "
            "length_m, cruise_speed_mps and sample_time"
        )
    return sizes


@dataclass(frozen=True)
class Thruster:
    name: str
    x: float
    y: float


LIBRARIES = ("thesis-model-ship", "thesis-full-scale")


@dataclass(frozen=True)
class ShipProfile:
    """One ship model: structure (3.60)-style terms, parameter sets and physical facts."""

    name: str
    description: str
    sample_time: float
    length_m: float
    beam_m: float
    draught_m: float
    cruise_speed_mps: float
    actuator: str
    inputs: tuple[str, ...]
    input_limits: dict[str, tuple[float, float]]
    model_terms: tuple[tuple[str, ...], ...]
    parameter_names: tuple[tuple[str, ...], ...]
    parameter_sets: dict[str, np.ndarray]
    simulation_set: str = "true"
    instrument_set: str = "nominal"
    predictor_terms: tuple[tuple[str, ...], ...] | None = None
    predictor_names: tuple[tuple[str, ...], ...] | None = None
    thrusters: tuple[Thruster, ...] = ()
    disturbances: dict[str, Any] = field(default_factory=dict)
    source: str = ""
    helm: Helm = field(default_factory=Helm)
    engine: Engine = field(default_factory=Engine)
    library: str = ""
    rigid_body: RigidBody | None = None
    pods: tuple[Pod, ...] = ()
    pod_model: PodModel | None = None
    # [diagnosis] structure: terms per DOF a diagnosis adds to the model when it refits the
    # baseline on calm-water runs (--fit-on), and the prior that holds them towards zero
    structure_terms: tuple[tuple[str, ...], ...] | None = None
    structure_prior: float = DEFAULT_STRUCTURE_PRIOR

    # -- structure -------------------------------------------------------------------------
    # cached: compiled once per profile (a frozen dataclass still has an instance __dict__)
    @cached_property
    def model(self) -> TermSet:
        return TermSet(self.model_terms)

    @cached_property
    def predictor(self) -> TermSet:
        """Terms of the linear-in-parameters predictor used for estimation and design."""
        return TermSet(self.predictor_terms or self.model_terms)

    @property
    def n_dof(self) -> int:
        """3 (surge, sway, yaw) or 4 (surge, sway, yaw, roll)."""
        return len(self.model_terms)

    @property
    def dofs(self) -> tuple[str, ...]:
        return ROLL_DOFS[: self.n_dof]

    @property
    def planar(self) -> bool:
        """A 3-DOF ship without pods: what the manoeuvre library, design, planner and diagnosis support."""
        return self.n_dof == 3 and self.actuator != "pods"

    def require_planar(self, what: str) -> None:
        """Refuse a 4-DOF (roll) or podded profile where only 3-DOF ships are supported."""
        if not self.planar:
            raise ProfileError(
                f"ship {self.name!r} is a {self.n_dof}-DOF {self.actuator} profile; {what} supports 3-DOF ships only "
                "(for this ship: `shiptrial yawid` / `yawid-sim`, or primitives.simulate.simulate)"
            )

    @property
    def param_names(self) -> list[str]:
        return [n for dof in self.parameter_names for n in dof]

    @property
    def predictor_param_names(self) -> list[str]:
        names = self.predictor_names or self.parameter_names
        return [n for dof in names for n in dof]

    @property
    def has_wind_terms(self) -> bool:
        return bool({"u_q", "v_q"} & signals_used(self.model_terms))

    def params(self, which: str | np.ndarray | None = None) -> np.ndarray:
        """A parameter vector: a named set, an explicit vector, or the simulation set."""
        if which is None:
            which = self.simulation_set
        if isinstance(which, str):
            try:
                return self.parameter_sets[which].copy()
            except KeyError:
                raise ProfileError(
                    f"profile {self.name!r} has no parameter set {which!r}; choose one of {sorted(self.parameter_sets)}"
                ) from None
        theta = np.asarray(which, dtype=float)
        if theta.shape[-1] != self.model.n_params:
            raise ProfileError(f"profile {self.name!r} needs {self.model.n_params} parameters, got {theta.shape[-1]}")
        return theta

    @property
    def steering_input(self) -> str:
        """The input that plays the rudder in standard trials."""
        return {"generalized": "tau_n", "azimuth": "alpha2", "rudder_propeller": "delta", "pods": "delta1"}[self.actuator]

    # -- actuators ---------------------------------------------------------------------------
    def generalized_forces(self, inputs: np.ndarray) -> dict[str, np.ndarray]:
        """Input-dependent signals of the model, from an input array (..., n_inputs).

        For azimuth thrusters this is (3.55): tau_x = sum n cos a, tau_y = sum n sin a,
        tau_n = sum n (dx sin a - dy cos a).
        """
        inputs = np.asarray(inputs, dtype=float)
        sig = {name: inputs[..., i] for i, name in enumerate(self.inputs)}
        if self.actuator == "azimuth":
            tx = ty = tn = 0.0
            for i, th in enumerate(self.thrusters, start=1):
                n, a = sig[f"n{i}"], sig[f"alpha{i}"]
                tx = tx + n * np.cos(a)
                ty = ty + n * np.sin(a)
                tn = tn + n * (th.x * np.sin(a) - th.y * np.cos(a))
            sig.update(tau_x=tx, tau_y=ty, tau_n=tn)
        return sig

    def allocate(self, tau_x: np.ndarray, tau_y: np.ndarray, tau_n: np.ndarray) -> np.ndarray:
        """Inputs (N, n_inputs) that produce the given generalized forces.

        Azimuth thrusters: least-norm solution for the thrust components (n cos a, n sin a)
        of each thruster, then n >= 0 and a in (-pi, pi].
        """
        tau_x, tau_y, tau_n = np.broadcast_arrays(*(np.atleast_1d(np.asarray(t, float)) for t in (tau_x, tau_y, tau_n)))
        if self.actuator == "generalized":
            return np.stack([tau_x, tau_y, tau_n], axis=-1)
        if self.actuator != "azimuth":
            raise ProfileError(f"profile {self.name!r}: forces cannot be allocated to {self.actuator} inputs")
        # Unknowns per thruster: fx_i = n cos a, fy_i = n sin a.
        rows = []
        rows.append(np.ravel([[1.0, 0.0] for _ in self.thrusters]))
        rows.append(np.ravel([[0.0, 1.0] for _ in self.thrusters]))
        rows.append(np.ravel([[-t.y, t.x] for t in self.thrusters]))
        b_mat = np.array(rows)
        f = np.linalg.pinv(b_mat) @ np.stack([tau_x, tau_y, tau_n])
        cols = []
        for i in range(len(self.thrusters)):
            fx, fy = f[2 * i], f[2 * i + 1]
            cols += [np.hypot(fx, fy), np.arctan2(fy, fx)]
        return np.stack(cols, axis=-1)

    def clip_inputs(self, inputs: np.ndarray) -> np.ndarray:
        out = np.array(inputs, dtype=float)
        for i, name in enumerate(self.inputs):
            lo, hi = self.input_limits.get(name, (-np.inf, np.inf))
            out[..., i] = np.clip(out[..., i], lo, hi)
        return out

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "name": self.name,
            "description": self.description,
            "source": self.source,
            "sample_time": self.sample_time,
            "length_m": self.length_m,
            "beam_m": self.beam_m,
            "draught_m": self.draught_m,
            "cruise_speed_mps": self.cruise_speed_mps,
            "actuator": self.actuator,
            "inputs": list(self.inputs),
            "simulation_set": self.simulation_set,
            "instrument_set": self.instrument_set,
            "input_limits": {k: list(v) for k, v in self.input_limits.items()},
            "model": dict(zip(self.dofs, map(list, self.model_terms))),
            "parameter_names": dict(zip(self.dofs, map(list, self.parameter_names))),
            "parameters": {
                k: {dof: v[self.model.dof_slice(i)].tolist() for i, dof in enumerate(self.dofs)}
                for k, v in self.parameter_sets.items()
            },
            "disturbances": self.disturbances,
        }
        if self.predictor_terms:
            d["predictor"] = dict(zip(DOFS, map(list, self.predictor_terms)))
        if self.predictor_names:
            d["predictor_names"] = dict(zip(DOFS, map(list, self.predictor_names)))
        if self.thrusters:
            d["thrusters"] = [{"name": t.name, "x": t.x, "y": t.y} for t in self.thrusters]
        if self.actuator == "rudder_propeller":
            h, e = self.helm, self.engine
            d["helm"] = {"max_rudder_deg": h.max_rudder_deg, "rudder_rate_deg_s": h.rudder_rate_deg_s,
                         "starboard_sign": h.starboard_sign}
            d["engine"] = {"rps_limits": list(e.rps_limits)} | {
                k: getattr(e, k) for k in ("rps_rate", "mcr_rpm", "approach_rpm") if getattr(e, k) is not None}
        if self.library:
            d["library"] = self.library
        if self.structure_terms:
            d["diagnosis"] = {"structure": dict(zip(self.dofs, map(list, self.structure_terms))),
                              "structure_prior": self.structure_prior}
        if self.rigid_body is not None:
            rb = self.rigid_body
            d["rigid_body"] = {"mass": rb.mass, "I_x": rb.i_x, "I_z": rb.i_z, "x_g": rb.x_g, "z_g": rb.z_g} | dict(rb.added)
        if self.pods:
            d["pods"] = [{"name": q.name, "x": q.x, "y": q.y, "z": q.z} for q in self.pods]
            d["pod_model"] = {k: getattr(self.pod_model, k) for k in POD_MODEL_KEYS} | {"yaw_moment": self.pod_model.yaw_moment}
        return d


# -- loading -------------------------------------------------------------------------------------


def builtin_profiles() -> list[str]:
    return sorted(p.stem for p in PROFILE_DIR.glob("*.toml"))


def planar_profiles() -> list[str]:
    """The built-in 3-DOF profiles: those the manoeuvre library, design and planner support."""
    return [name for name in builtin_profiles() if load_profile(name).planar]


def _need(d: dict, key: str, src: str, kind: type | tuple[type, ...], hint: str) -> Any:
    if key not in d:
        raise ProfileError(f"{src}: missing field '{key}' ({hint})")
    val = d[key]
    if not isinstance(val, kind) or isinstance(val, bool):
        raise ProfileError(f"{src}: field '{key}' must be {hint}, got {val!r}")
    return val


def _per_dof(d: dict, key: str, src: str, item: type, hint: str, dofs: tuple[str, ...] = DOFS) -> tuple[tuple, ...]:
    table = _need(d, key, src, dict, f"a table with {', '.join(dofs)} lists")
    out = []
    for dof in dofs:
        vals = _need(table, dof, f"{src} [{key}]", list, hint)
        for v in vals:
            if not isinstance(v, item) or isinstance(v, bool):
                raise ProfileError(f"{src}: field '{key}.{dof}' must hold only {hint}, got {v!r}")
        out.append(tuple(float(v) if item is not str else v for v in vals))
    return tuple(out)


def _input_limits(d: dict, src: str) -> dict[str, tuple[float, float]]:
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
        limits[k] = (lo, hi)
    return limits


def _thrusters(d: dict, src: str) -> tuple[Thruster, ...]:
    table = d.get("thrusters", [])
    if not isinstance(table, list) or not all(isinstance(t, dict) and "x" in t for t in table):
        raise ProfileError(f"{src}: field 'thrusters' must be a list of [[thrusters]] tables with x (and y) in metres")
    return tuple(
        Thruster(str(t.get("name", f"thruster{i + 1}")), finite(t["x"], f"{src}: field 'thrusters.{i}.x'", "m", ProfileError),
                 finite(t.get("y", 0.0), f"{src}: field 'thrusters.{i}.y'", "m", ProfileError))
        for i, t in enumerate(table)
    )


# Disturbance levels a profile may state (Disturbances.from_profile reads them): key -> length (0 = scalar).
DISTURBANCE_KEYS = {"current_mean_ne": 2, "current_sample_std": 0, "measurement_std": 3, "heading_std": 0}


def _disturbances(d: dict, src: str) -> dict[str, Any]:
    table = d.get("disturbances", {})
    if not isinstance(table, dict):
        raise ProfileError(f"{src}: field 'disturbances' must be a table")
    for k, v in table.items():
        if k not in DISTURBANCE_KEYS:
            raise ProfileError(f"{src}: unknown field 'disturbances.{k}'; known: {', '.join(DISTURBANCE_KEYS)}")
        n = DISTURBANCE_KEYS[k]
        vals = v if n else [v]
        if not isinstance(vals, list) or len(vals) != max(n, 1):
            raise ProfileError(f"{src}: field 'disturbances.{k}' must be {f'a list of {n} numbers' if n else 'a number'}")
        for x in vals:
            y = finite(x, f"{src}: field 'disturbances.{k}'", "SI units", ProfileError)
            if k != "current_mean_ne" and y < 0:
                raise ProfileError(f"{src}: field 'disturbances.{k}' is a standard deviation: must be >= 0, got {x!r}")
    return dict(table)


DIAGNOSIS_KEYS = ("structure", "structure_prior")


def _diagnosis(d: dict, src: str, dofs: tuple[str, ...], known: set[str]) -> tuple[tuple[tuple[str, ...], ...] | None, float]:
    """The optional [diagnosis] table: ``structure`` (term lists per DOF that a --fit-on refit
    adds to the model) and ``structure_prior`` (> 0: the prior std of their coefficients, as a
    fraction of the coefficient that alone would explain the increments' spread)."""
    table = d.get("diagnosis")
    if table is None:
        return None, DEFAULT_STRUCTURE_PRIOR
    if not isinstance(table, dict):
        raise ProfileError(f"{src}: field 'diagnosis' must be a table with 'structure' (and 'structure_prior')")
    bad = unknown_key(table, list(DIAGNOSIS_KEYS))
    if bad:
        raise ProfileError(f"{src}: unknown field 'diagnosis.{bad[0]}'{bad[1]}")
    prior = positive(table.get("structure_prior", DEFAULT_STRUCTURE_PRIOR), f"{src}: field 'diagnosis.structure_prior'", "", ProfileError)
    terms = _per_dof(table, "structure", f"{src} [diagnosis]", str, "regressor term strings like 'v_r^3*U^-1'", dofs)
    try:
        unknown = signals_used(terms) - known
        TermSet(terms)
    except TermError as exc:
        raise ProfileError(f"{src}: field 'diagnosis.structure': {exc}") from None
    if unknown:
        raise ProfileError(f"{src}: field 'diagnosis.structure' uses unknown signals {sorted(unknown)}; known: {sorted(known)}")
    return terms, prior


def profile_from_dict(d: dict[str, Any], src: str = "<profile>") -> ShipProfile:
    """Validate a decoded TOML/JSON document and build a profile."""
    num = (int, float)
    _check_keys(d, src)
    name = _need(d, "name", src, str, "the profile name, e.g. 'my-ship'")
    sizes = _check_sizes(d, src)
    ts = sizes["sample_time"]
    actuator = d.get("actuator", "generalized")
    if actuator not in ACTUATORS:
        raise ProfileError(f"{src}: field 'actuator' must be one of {ACTUATORS}, got {actuator!r}")
    inputs = tuple(_need(d, "inputs", src, list, "a list of input names"))
    if not inputs or not all(isinstance(x, str) and x for x in inputs) or len(set(inputs)) != len(inputs):
        raise ProfileError(f"{src}: field 'inputs' must be a non-empty list of distinct input names, got {list(inputs)!r}")
    dofs = ROLL_DOFS if isinstance(d.get("model"), dict) and "roll" in d["model"] else DOFS
    terms = _per_dof(d, "model", src, str, "regressor term strings like 'u_r*|u_r|'", dofs)
    names = _per_dof(d, "parameter_names", src, str, "parameter names", dofs)
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
    sets_raw = _need(d, "parameters", src, dict, "a table of parameter sets, e.g. [parameters.true]")
    sets = {}
    for set_name, table in sets_raw.items():
        vals = _per_dof({"p": table}, "p", f"{src} [parameters.{set_name}]", num, "numbers", dofs)
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
    limits = _input_limits(d, src)
    thrusters = _thrusters(d, src)
    if actuator == "azimuth":
        expect = tuple(x for i in range(1, len(thrusters) + 1) for x in (f"n{i}", f"alpha{i}"))
        if not thrusters or inputs != expect:
            raise ProfileError(
                f"{src}: field 'inputs' of an azimuth profile must be {list(expect) or ['n1', 'alpha1']} with one [[thrusters]] entry each"
            )
    structure, structure_prior = _diagnosis(d, src, dofs, known)
    rigid_body = parse_rigid_body(d, src, len(dofs), ProfileError)
    pods, pod_model = parse_pods(d, src, inputs, ProfileError) if actuator == "pods" else ((), None)
    pred = pred_names = None
    if "predictor" in d:
        pred = _per_dof(d, "predictor", src, str, "regressor term strings")
        pred_names = _per_dof(d, "predictor_names", src, str, "parameter names")
        try:
            TermSet(pred)
        except TermError as exc:
            raise ProfileError(f"{src}: field 'predictor': {exc}") from None
    library = d.get("library", "")
    if library and library not in LIBRARIES:
        raise ProfileError(f"{src}: field 'library' must be one of {LIBRARIES} (or absent), got {library!r}")
    helm, engine = Helm(), Engine()
    if actuator == "rudder_propeller":
        if inputs != ("delta", "n"):
            raise ProfileError(f"{src}: field 'inputs' of a rudder_propeller profile must be ['delta', 'n'] (rudder rad, propeller rev/s)")
        helm, engine = parse_helm_engine(
            d, src, limits, lambda: _starboard_sign(model, sets[sim_set], sizes["cruise_speed_mps"]), ProfileError
        )
    return ShipProfile(
        name=name,
        description=str(d.get("description", "")),
        sample_time=ts,
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
        disturbances=_disturbances(d, src),
        source=str(d.get("source", "")),
        helm=helm,
        engine=engine,
        library=library,
        rigid_body=rigid_body,
        pods=pods,
        pod_model=pod_model,
        structure_terms=structure,
        structure_prior=structure_prior,
    )


def _starboard_sign(model: TermSet, theta: np.ndarray, cruise: float) -> float:
    """+1 if a positive delta gives a starboard (positive) yaw acceleration at cruise speed, else -1."""
    rates = []
    for delta in (0.0, 0.1):
        sig = {k: 0.0 for k in BASE_SIGNALS} | {"u": cruise, "u_r": cruise, "u_q": cruise, "U": cruise, "delta": delta, "n": 0.0}
        rates.append(float(model.increments(sig, theta)[2]))
    return 1.0 if rates[1] >= rates[0] else -1.0


def load_profile(name_or_path: str | Path) -> ShipProfile:
    """A built-in profile by name (``model-ship``, ``full-scale``, ...) or a TOML/JSON file."""
    path = Path(name_or_path)
    if not path.suffix:
        cand = PROFILE_DIR / f"{name_or_path}.toml"
        if not cand.exists():
            raise ProfileError(
                f"unknown ship {str(name_or_path)!r}: use one of {builtin_profiles()} or a .toml/.json profile file"
            )
        path = cand
    if not path.exists():
        raise ProfileError(f"{path}: no such profile file")
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
