"""Ship profiles: the data that describe one ship model (states, inputs, structure, parameters).

Built-in profiles live as TOML files in ``primitives/profiles``; users can load their own from
TOML or JSON with :func:`load_profile`. A profile is the single source of truth for a model's
structure (regressor terms per DOF) and its parameter sets. This module holds the dataclasses and
finds a profile file; :mod:`primitives.profile_document` checks a document and builds the profile.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from primitives.errors import UserError
from primitives.physical_tables import POD_MODEL_KEYS, Engine, Helm
from primitives.pods import Pod, PodModel
from primitives.rigidbody import RigidBody
from primitives.terms import TermSet

PROFILE_DIR = Path(__file__).with_name("profiles")
DOFS = ("surge", "sway", "yaw")
# A profile with a roll term list is surge-sway-yaw-roll (the podded-ship MSc thesis); roll is appended so yaw
# stays the third state of every ship.
ROLL_DOFS = DOFS + ("roll",)
ACTUATORS = ("generalized", "azimuth", "rudder_propeller", "pods")
# Signals every model may read besides its own inputs.
BASE_SIGNALS = {"u", "v", "r", "u_r", "v_r", "u_q", "v_q", "psi", "tau_x", "tau_y", "tau_n", "U"}
# Signals only a model with the roll DOF has: roll rate, roll angle, actuator roll moment.
ROLL_SIGNALS = {"p", "phi", "tau_k"}


class ProfileError(UserError):
    """A ship profile file is malformed; the message names the file and the field."""


# Prior std of a [diagnosis] structure coefficient, as a fraction of the coefficient that alone
# would explain its DOF's increments (diagnose.api.term_scales), when the profile gives none.
DEFAULT_STRUCTURE_PRIOR = 0.01


@lru_cache(maxsize=64)
def _allocation_pinv(arms: tuple[tuple[float, float], ...]) -> np.ndarray:
    """Pseudo-inverse of the allocation matrix of azimuth thrusters at ``arms`` ((x, y) each):
    unknowns per thruster fx_i = n cos a, fy_i = n sin a (3.55). Formed once per thruster layout
    (the planner allocates on every closed-loop run); read-only."""
    b_mat = np.array(
        [np.ravel([[1.0, 0.0] for _ in arms]), np.ravel([[0.0, 1.0] for _ in arms]), np.ravel([[-y, x] for x, y in arms])]
    )
    out = np.linalg.pinv(b_mat)
    out.flags.writeable = False
    return out


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
    # [prior] std: 1-sigma spread of each coefficient of the simulation set, in the model's
    # parameter order (a profile made from particulars carries its regressions' scatter here)
    prior_std: np.ndarray | None = None
    # [diagnosis] rudder_thrust_share: d ln(rudder force) / d ln(thrust) at the approach, the
    # part of a thrust loss the rudder loses with the propeller slipstream (MMG (24): the rudder
    # inflow u_R grows with the propeller loading 8 K_T / (pi J^2)); 0 when the rudder is not
    # in the slipstream or the profile does not say
    rudder_thrust_share: float = 0.0
    # what the commands given this ship must tell the user: a diagnosed model.json's findings the
    # profile cannot hold (primitives.model_json_ship), one line each
    load_warnings: tuple[str, ...] = ()
    # the vessel this profile is a model of, as a recording's '# ship:' header names it (kvlcc2-linear is a model
    # of the kvlcc2); empty: the profile's own name (primitives.profile_tables.read_vessel)
    vessel: str = ""

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
        f = _allocation_pinv(tuple((float(t.x), float(t.y)) for t in self.thrusters)) @ np.stack([tau_x, tau_y, tau_n])
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
            **({"vessel": self.vessel} if self.vessel and self.vessel != self.name else {}),
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
            d["helm"] = {
                "max_rudder_deg": h.max_rudder_deg,
                "rudder_rate_deg_s": h.rudder_rate_deg_s,
                "starboard_sign": h.starboard_sign,
            }
            d["engine"] = {"rps_limits": list(e.rps_limits)} | {
                k: getattr(e, k) for k in ("rps_rate", "mcr_rpm", "approach_rpm", "astern_rpm") if getattr(e, k) is not None
            }
        if self.prior_std is not None and self.prior_std.shape == (self.model.n_params,):
            d["prior"] = {"std": {dof: self.prior_std[self.model.dof_slice(i)].tolist() for i, dof in enumerate(self.dofs)}}
        if self.library:
            d["library"] = self.library
        if self.structure_terms:
            d["diagnosis"] = {
                "structure": dict(zip(self.dofs, map(list, self.structure_terms))),
                "structure_prior": self.structure_prior,
            }
        if self.rudder_thrust_share:
            d.setdefault("diagnosis", {"structure_prior": self.structure_prior})["rudder_thrust_share"] = self.rudder_thrust_share
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
    from primitives.profile_document import read_profile_file  # it builds ShipProfile: imported when used

    return read_profile_file(path)
