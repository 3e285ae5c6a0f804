"""Parsers of the physical tables of a 4-DOF profile: [rigid_body], [[pods]] and [pod_model].

Kept out of :mod:`primitives.ship` (which calls them with its ProfileError) so that the planar
profile loader stays short; every message names the file, the field and what to give.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from primitives.errors import UserError
from primitives.pods import Pod, PodModel
from primitives.rigidbody import ADDED_MASS_KEYS, RigidBody
from primitives.validate import finite, positive

POD_MODEL_KEYS = ("rho", "diameter", "strut_area", "c_mx1", "c_mx2", "c_my1", "c_my2", "c_rx1", "c_rx2", "c_ry")
RIGID_BODY_KEYS = ("mass", "I_x", "I_z", "x_g", "z_g") + ADDED_MASS_KEYS


def _numbers(table: Any, section: str, keys: tuple[str, ...], src: str, hint: str, err: type[UserError]) -> dict[str, float]:
    """Every key of ``keys`` from a table of finite numbers, none other."""
    if not isinstance(table, dict):
        raise err(f"{src}: field '{section}' must be a table [{section}] ({hint})")
    extra = sorted(set(table) - set(keys) - {"yaw_moment"})
    if extra:
        raise err(f"{src}: unknown field '{section}.{extra[0]}'; known: {', '.join(keys)}")
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
        raise err(f"{src}: an actuator = \"pods\" profile needs [[pods]] tables with x, y, z in metres")
    pods = tuple(
        Pod(str(t.get("name", f"pod{i + 1}")), *(finite(t.get(k), f"{src}: field 'pods.{i}.{k}'", "m", err) for k in "xyz"))
        for i, t in enumerate(table)
    )
    expect = tuple(x for i in range(1, len(pods) + 1) for x in (f"n{i}", f"delta{i}"))
    if inputs != expect:
        raise err(f"{src}: field 'inputs' of a pods profile must be {list(expect)} (rev/s, rad) with one [[pods]] entry each")
    pm = d.get("pod_model")
    c = _numbers(pm, "pod_model", POD_MODEL_KEYS, src, "Table 2.1 of seed 000", err)
    yaw_moment = pm.get("yaw_moment", "thesis")
    if yaw_moment not in ("thesis", "full"):
        raise err(f"{src}: field 'pod_model.yaw_moment' must be 'thesis' (x F_y, eq. 2.12) or 'full' (x F_y - y F_x)")
    return pods, PodModel(*(c[k] for k in POD_MODEL_KEYS), yaw_moment=yaw_moment)
