"""Parsers of the physical tables of a profile: [rigid_body], [[pods]] and [pod_model] of a 4-DOF
profile, [helm] and [engine] of a rudder/propeller ship (with their dataclasses).

Called by :mod:`primitives.profile_document` and :mod:`primitives.profile_tables` (with their ProfileError)
beside the planar tables' steps; every message names the file, the field and what to give.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from primitives.errors import UserError
from primitives.pods import Pod, PodModel
from primitives.rigidbody import ADDED_MASS_KEYS, RigidBody
from primitives.unit_ranges import check_max_rudder_deg, check_rpm, check_rudder_rate
from primitives.validate import check_table_keys, finite, positive

POD_MODEL_KEYS = ("rho", "diameter", "strut_area", "c_mx1", "c_mx2", "c_my1", "c_my2", "c_rx1", "c_rx2", "c_ry")
RIGID_BODY_KEYS = ("mass", "I_x", "I_z", "x_g", "z_g") + ADDED_MASS_KEYS
POD_KEYS = ("name", "x", "y", "z")
HELM_KEYS = ("max_rudder_deg", "rudder_rate_deg_s", "starboard_sign")
ENGINE_KEYS = ("rps_limits", "rps_rate", "mcr_rpm", "approach_rpm", "astern_rpm")
# The smallest astern rpm accepted, as a fraction of the ahead maximum: a plausibility gate, not a physical limit
ASTERN_MIN_FRACTION = 0.1


@dataclass(frozen=True)
class Helm:
    """Steering gear of a rudder ship ([helm] of the profile).

    starboard_sign: sign of the model's rudder input ``delta`` that turns the ship to starboard
    (derived from the model's yaw response when the profile does not state it).
    rudder_rate_deg_s: default 2.32 deg/s, the SOLAS II-1/29 minimum (35 deg one side to 30 deg
    the other in 28 s), which is also the KVLCC2 full-scale rate of SIMMAN 2008.
    """

    max_rudder_deg: float = 35.0
    rudder_rate_deg_s: float = 2.32
    starboard_sign: float = 1.0

    def delta_rad(self, rudder_deg: np.ndarray | float) -> np.ndarray:
        """Model input delta [rad] for a helm angle in degrees (+ starboard)."""
        return self.starboard_sign * np.radians(rudder_deg)

    def rudder_deg(self, delta_rad: np.ndarray | float) -> np.ndarray:
        """Helm angle in degrees (+ starboard) of a model input delta [rad]."""
        return self.starboard_sign * np.degrees(delta_rad)


@dataclass(frozen=True)
class Engine:
    """Propulsion engine of a rudder ship ([engine] of the profile).

    rps_limits: propeller speed range [rev/s] (default the input limits of ``n``); rps_rate:
    fastest change of the shaft speed [rev/s per s] (None: steps); mcr_rpm: shaft rpm at MCR,
    for % MCR under the propeller law (power ~ rpm^3); approach_rpm: the rpm the source ran
    its trials at (compared with the model's steady rpm for the cruise speed); astern_rpm: the
    most the engine turns astern, in rpm (None: no astern power; declared, the lower end of
    ``rps_limits`` is -astern_rpm / 60 and the model's thrust must reverse with the shaft).
    """

    rps_limits: tuple[float, float] = (0.0, np.inf)
    rps_rate: float | None = None
    mcr_rpm: float | None = None
    approach_rpm: float | None = None
    astern_rpm: float | None = None


def _numbers(
    table: Any, section: str, keys: tuple[str, ...], src: str, hint: str, err: type[UserError], other: tuple[str, ...] = ()
) -> dict[str, float]:
    """Every key of ``keys`` from a table of finite numbers; ``other`` keys the caller reads, none else."""
    if not isinstance(table, dict):
        raise err(f"{src}: field '{section}' must be a table [{section}] ({hint})")
    check_table_keys(table, keys + other, src, f"[{section}]", err)
    out = {}
    for k in keys:
        if k not in table:
            raise err(f"{src}: missing field '{section}.{k}' ({hint})")
        out[k] = finite(table[k], f"{src}: field '{section}.{k}'", "SI units", err)
    return out


def parse_rigid_body(d: dict, src: str, n_dof: int, err: type[UserError]) -> RigidBody | None:
    """[rigid_body] of a 4-DOF physical model: its terms are forces, the kernel divides by M (2.14)."""
    if "rigid_body" not in d:
        if n_dof == 4:
            raise err(f"{src}: a profile with a roll DOF needs a [rigid_body] table ({', '.join(RIGID_BODY_KEYS)})")
        return None
    if n_dof != 4:
        raise err(f"{src}: field 'rigid_body' needs the roll DOF: add model.roll and parameter_names.roll")
    t = _numbers(d["rigid_body"], "rigid_body", RIGID_BODY_KEYS, src, "mass kg, inertias kg m^2, CoG m, added mass SI", err)
    for k in ("mass", "I_x", "I_z"):
        positive(t[k], f"{src}: field 'rigid_body.{k}'", "SI units", err)
    rb = RigidBody(t["mass"], t["I_x"], t["I_z"], t["x_g"], t["z_g"], {k: t[k] for k in ADDED_MASS_KEYS})
    if np.linalg.cond(rb.mass_matrix) > 1e12:
        raise err(f"{src}: field 'rigid_body': the mass matrix M = M_RB - M_A (2.14) is singular; check the added masses")
    return rb


def parse_pods(d: dict, src: str, inputs: tuple[str, ...], err: type[UserError]) -> tuple[tuple[Pod, ...], PodModel]:
    table = d.get("pods")
    if not isinstance(table, list) or not table or not all(isinstance(t, dict) for t in table):
        raise err(f'{src}: an actuator = "pods" profile needs [[pods]] tables with x, y, z in metres')
    for i, t in enumerate(table):
        check_table_keys(t, POD_KEYS, src, f"[[pods]] number {i + 1}", err)
    pods = tuple(
        Pod(str(t.get("name", f"pod{i + 1}")), *(finite(t.get(k), f"{src}: field 'pods.{i}.{k}'", "m", err) for k in "xyz"))
        for i, t in enumerate(table)
    )
    expect = tuple(x for i in range(1, len(pods) + 1) for x in (f"n{i}", f"delta{i}"))
    if inputs != expect:
        raise err(f"{src}: field 'inputs' of a pods profile must be {list(expect)} (rev/s, rad) with one [[pods]] entry each")
    pm = d.get("pod_model")
    c = _numbers(pm, "pod_model", POD_MODEL_KEYS, src, "Table 2.1 of the podded-ship MSc thesis", err, other=("yaw_moment",))
    yaw_moment = pm.get("yaw_moment", "thesis")
    if yaw_moment not in ("thesis", "full"):
        raise err(f"{src}: field 'pod_model.yaw_moment' must be 'thesis' (x F_y, eq. 2.12) or 'full' (x F_y - y F_x)")
    return pods, PodModel(*(c[k] for k in POD_MODEL_KEYS), yaw_moment=yaw_moment)


def _positive(table: dict, section: str, key: str, src: str, hint: str, err: type[UserError]) -> float | None:
    if key not in table:
        return None
    val = table[key]
    if not isinstance(val, (int, float)) or isinstance(val, bool) or not val > 0:
        raise err(f"{src}: field '{section}.{key}' must be a number > 0 ({hint}), got {val!r}")
    return float(val)


def parse_helm_engine(
    d: dict,
    src: str,
    limits: dict,
    starboard_sign: Callable[[], float],
    err: type[UserError],
    astern_thrust: Callable[[float], float] | None = None,
) -> tuple[Helm, Engine]:
    """[helm] and [engine] of a rudder/propeller profile, defaults from the input limits;
    ``starboard_sign()`` derives the helm's sign from the model when [helm] does not state it;
    ``astern_thrust(rps)``: the model's surge force at rest with the shaft at ``rps`` (checks
    that a declared astern_rpm reverses the thrust)."""
    h = d.get("helm", {})
    e = d.get("engine", {})
    for key, tab, accepted in (("helm", h, HELM_KEYS), ("engine", e, ENGINE_KEYS)):
        if not isinstance(tab, dict):
            raise err(f"{src}: field '{key}' must be a table [{key}]")
        check_table_keys(tab, accepted, src, f"[{key}]", err)
    lim_deg = float(np.degrees(min(abs(x) for x in limits["delta"]))) if "delta" in limits else 35.0
    max_deg = _positive(h, "helm", "max_rudder_deg", src, "the largest rudder angle in degrees, e.g. 35", err)
    if max_deg is not None:
        check_max_rudder_deg(max_deg, src, err)
    max_deg = max_deg or lim_deg
    if max_deg > lim_deg + 1e-6:
        raise err(f"{src}: field 'helm.max_rudder_deg' = {max_deg:g} exceeds input_limits.delta ({lim_deg:.2f} deg)")
    rate = _positive(h, "helm", "rudder_rate_deg_s", src, "the steering gear's rate in deg/s, e.g. 2.32", err)
    if rate is not None:
        check_rudder_rate(rate, src, err)
    rate = rate or 2.32
    sign = h.get("starboard_sign")
    if sign is None:
        sign = starboard_sign()
    elif sign not in (1, -1):
        raise err(f"{src}: field 'helm.starboard_sign' must be 1 or -1 (sign of delta that turns to starboard), got {sign!r}")
    rps = e.get("rps_limits", list(limits.get("n", (0.0, np.inf))))
    if not (isinstance(rps, list) and len(rps) == 2 and all(isinstance(x, (int, float)) for x in rps) and rps[0] < rps[1]):
        raise err(f"{src}: field 'engine.rps_limits' must be [min, max] propeller rev/s with min < max, got {rps!r}")
    n_lo, n_hi = limits.get("n", (-np.inf, np.inf))
    if rps[0] < n_lo or rps[1] > n_hi:
        raise err(f"{src}: field 'engine.rps_limits' {rps} exceeds input_limits.n [{n_lo:g}, {n_hi:g}]")
    if np.isinf(rps[1]):
        raise err(
            f"{src}: a rudder_propeller profile needs the propeller's rev/s range: add input_limits.n = [min, max] or engine.rps_limits"
        )
    rpms = {
        key: _positive(e, "engine", key, src, hint, err)
        for key, hint in (("mcr_rpm", "shaft rpm at MCR"), ("approach_rpm", "the rpm of the source's approach runs"))
    }
    for key, value in rpms.items():
        if value is not None:
            check_rpm(key, value, float(rps[1]), src, err)
    astern = _astern(e, src, rps, limits, astern_thrust, err)
    engine = Engine(
        (-astern / 60.0 if astern else float(rps[0]), float(rps[1])),
        _positive(e, "engine", "rps_rate", src, "the fastest shaft-speed change in rev/s per second", err),
        rpms["mcr_rpm"],
        rpms["approach_rpm"],
        astern,
    )
    return Helm(max_deg, rate, float(sign)), engine


def _astern(
    e: dict, src: str, rps: list, limits: dict, astern_thrust: Callable[[float], float] | None, err: type[UserError]
) -> float | None:
    """[engine] astern_rpm, checked: at least :data:`ASTERN_MIN_FRACTION` of the ahead rpm and at most
    the ahead rpm (a fixed-pitch propeller turns astern no faster than ahead), within input_limits.n, consistent with rps_limits, and
    the model's thrust reverses with the shaft (a thrust term even in n, ``n^2``, does not)."""
    value = _positive(e, "engine", "astern_rpm", src, "the most astern shaft rpm, a positive number, e.g. 60", err)
    if value is None:
        return None
    ahead = 60.0 * float(rps[1])
    if value > ahead + 1e-9:
        raise err(f"{src}: field 'engine.astern_rpm' = {value:g} exceeds the ahead maximum {ahead:g} rpm; give at most {ahead:g}")
    if value < ASTERN_MIN_FRACTION * ahead:
        # a shaft barely turning astern makes a crash stop that never stops (a typo or a unit slip, e.g. rev/s for rpm)
        raise err(
            f"{src}: field 'engine.astern_rpm' = {value:g} is under {ASTERN_MIN_FRACTION:.0%} of the ahead maximum "
            f"{ahead:g} rpm, too little to stop the ship: give the engine's astern rpm in rpm "
            f"(ships turn astern at about 50-80 % of ahead) or remove astern_rpm"
        )
    n_lo = limits.get("n", (-np.inf, np.inf))[0]
    if -value / 60.0 < n_lo - 1e-12:
        raise err(
            f"{src}: field 'engine.astern_rpm' = {value:g} needs input_limits.n down to {-value / 60:.4g} rev/s "
            f"(it starts at {n_lo:g}): lower input_limits.n[0] or remove astern_rpm"
        )
    if "rps_limits" in e and rps[0] not in (0, 0.0) and abs(rps[0] + value / 60.0) > 1e-9:
        raise err(
            f"{src}: field 'engine.rps_limits' starts at {rps[0]:g} rev/s, but astern_rpm = {value:g} means "
            f"{-value / 60:.4g}: give rps_limits[0] = 0 (astern_rpm sets the astern end) or drop astern_rpm"
        )
    if astern_thrust is not None and not astern_thrust(-value / 60.0) < 0.0:
        raise err(
            f"{src}: field 'engine.astern_rpm': the model's surge terms do not reverse the thrust at {-value:g} rpm "
            "(a thrust term even in n, such as n^2, pushes ahead astern too): write the thrust as n*|n| or remove astern_rpm"
        )
    return value
