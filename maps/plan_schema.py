"""The declared schema of a saved plan (plan.json, format ``shiptrial-plan/1``) and its check.

A plan file is read by ``shiptrial export`` long after it was written, perhaps edited by hand or
by another tool; every exporter (GeoJSON, GPX, RTZ, CSV, card) trusts the fields it reads. The
schema (JSON Schema 2020-12, checked by the ``jsonschema`` library) states each field's type and
physical range, so a malformed plan is refused in one line naming the field before any exporter
runs; :func:`check_plan_document` adds what a schema cannot say (equal sample counts, step indices
within the steps, a projection pyproj knows, chart geometries shapely can read).
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any

import numpy as np

from primitives.errors import UserError

# text a bridge document or an XML route can hold: no NUL or other C0 control characters but tab/newline
TEXT = {"type": "string", "maxLength": 4000, "pattern": "^[^\\x00-\\x08\\x0b\\x0c\\x0e-\\x1f\\x7f]*$"}
NAME = {**TEXT, "maxLength": 200}


def _num(lo: float, hi: float) -> dict[str, Any]:
    return {"type": "number", "minimum": lo, "maximum": hi}


LON, LAT = _num(-180.0, 180.0), _num(-90.0, 90.0)
METRES = _num(-1e8, 1e8)  # local metric frame: well beyond any sea trial
ANGLE = _num(-1e4, 1e4)  # radians, unwrapped headings allowed
SECONDS = _num(0.0, 1e8)
SPEED = _num(-100.0, 100.0)  # m/s: beyond any ship
COUNT = {"type": "integer", "minimum": 0, "maximum": 100000}
GEOMETRY = {"type": ["object", "null"], "required": ["type"], "properties": {"type": NAME}}

STEP = {
    "type": "object",
    "required": [
        "index",
        "primitive",
        "kind",
        "description",
        "start_time_s",
        "duration_s",
        "entry_x",
        "entry_y",
        "entry_psi",
        "entry_lon",
        "entry_lat",
        "entry_speed_mps",
    ],
    "additionalProperties": False,
    "properties": {
        "index": COUNT,
        "primitive": NAME,
        "kind": {"enum": ["informative", "basic", "run-in"]},
        "description": TEXT,
        "start_time_s": SECONDS,
        "duration_s": SECONDS,
        "entry_x": METRES,
        "entry_y": METRES,
        "entry_psi": ANGLE,
        "entry_lon": LON,
        "entry_lat": LAT,
        "entry_speed_mps": SPEED,
        "commands": {"type": "array", "items": TEXT},
        "space_m": {"type": "array", "minItems": 2, "maxItems": 2, "items": _num(0.0, 1e7)},
        "segment": {"enum": ["", "run-in", "informative", "transit"]},
        "orders": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["t_s", "text"],
                "properties": {"t_s": _num(-1e7, 1e8), "text": TEXT},
                "additionalProperties": {"anyOf": [_num(-1e12, 1e12), TEXT, {"type": ["boolean", "null"]}]},
            },
        },
        "abort": {"type": "array", "items": TEXT},
        "execute": {"type": "boolean"},
    },
}

CHART = {
    "type": "object",
    "properties": {
        "name": NAME,
        "land": GEOMETRY,
        "no_go": GEOMETRY,
        "depth_areas": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["geometry"],
                "properties": {"geometry": GEOMETRY, "min_depth_m": _num(-1e4, 1e5)},
            },
        },
        "extent": {
            "anyOf": [{"type": "null"}, {"type": "array", "minItems": 4, "maxItems": 4, "prefixItems": [LON, LAT, LON, LAT]}]
        },
    },
}


# the sample series: arrays here, their numbers checked vectorised (:func:`_check_samples`): a plan
# holds tens of thousands of samples, item by item a schema walk would cost about a second
SERIES = {"type": "array"}  # empty in an infeasible plan
SERIES_RANGES = {"t": SECONDS, "x": METRES, "y": METRES, "psi": ANGLE, "lon": LON, "lat": LAT, "speed": SPEED}


PLAN_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "shiptrial plan (shiptrial-plan/1)",
    "type": "object",
    "required": [
        "format",
        "ship",
        "feasible",
        "optimal",
        "min_clearance_m",
        "margin_m",
        "counts",
        "targets",
        "projection",
        "input_names",
        "steps",
        "samples",
    ],
    "properties": {
        "format": {"const": "shiptrial-plan/1"},
        "ship": NAME,
        "map_name": NAME,
        "vessel_name": NAME,
        "feasible": {"type": "boolean"},
        "optimal": {"type": "boolean"},
        "min_clearance_m": {"anyOf": [{"type": "null"}, _num(0.0, 1e8)]},
        "margin_m": _num(0.0, 1e5),
        "counts": {"type": "object", "additionalProperties": COUNT, "propertyNames": NAME},
        "targets": {"type": "object", "additionalProperties": COUNT, "propertyNames": NAME},
        "stats": {
            "type": "object",
            "properties": {
                "chart": CHART,
                "start_utc": {"anyOf": [{"type": "null"}, NAME]},
                "turning_radius_m": {"anyOf": [{"type": "null"}, _num(0.0, 1e6)]},
            },
        },
        "projection": {
            "type": "object",
            "required": ["proj4"],
            "properties": {"proj4": {**NAME, "minLength": 1}, "lon0": LON, "lat0": LAT},
        },
        "hull": {"type": "array", "minItems": 2, "maxItems": 2, "items": _num(0.0, 2000.0)},
        "max_wind_mps": _num(0.0, 100.0),
        "design": {
            "type": ["object", "null"],
            "properties": {
                "criterion": {"anyOf": [{"type": "null"}, NAME]},
                # a resumed plan: the criterion of the plan it resumed, when not D (the rest is re-designed D)
                "first_criterion": NAME,
                "mean_subtraction": {"anyOf": [{"type": ["null", "boolean"]}, NAME]},
                "weights": {"type": "object", "additionalProperties": _num(0.0, 1.0)},
                "counts": {"type": "object", "additionalProperties": COUNT},
                "d_efficiency": {"anyOf": [{"type": "null"}, _num(0.0, 10.0)]},
                "not_used": {"type": "array", "items": NAME},
                "dropped": {
                    "type": "array",
                    "items": {
                        "type": "object",
                        "properties": {
                            "primitive": NAME,
                            "needs_m": {"type": "array", "minItems": 2, "maxItems": 2, "items": _num(0.0, 1e8)},
                            "efficiency_loss": {"anyOf": [{"type": "null"}, _num(-10.0, 10.0)]},
                            "unreachable": {"type": "boolean"},
                            "apart": {"type": "boolean"},
                        },
                    },
                },
                # issue 28: parameters the manoeuvres that fit cannot identify (maps.searoom.held_records)
                "held_parameters": {
                    "type": "array",
                    "items": {
                        "type": "object",
                        "required": ["parameter"],
                        "properties": {
                            "parameter": NAME,
                            "value": {"anyOf": [{"type": "null"}, _num(-1e12, 1e12)]},
                            "identified_by": {
                                "anyOf": [
                                    {"type": "null"},
                                    {
                                        "type": "object",
                                        "required": ["primitive", "needs_m"],
                                        "properties": {
                                            "primitive": NAME,
                                            "needs_m": {"type": "array", "minItems": 2, "maxItems": 2, "items": _num(0.0, 1e8)},
                                            "unreachable": {"type": "boolean"},
                                            "apart": {"type": "boolean"},
                                        },
                                    },
                                ]
                            },
                        },
                    },
                },
            },
        },
        "input_names": {"type": "array", "minItems": 1, "maxItems": 16, "uniqueItems": True, "items": NAME},
        "steps": {"type": "array", "items": STEP},  # none in an infeasible plan
        "samples": {
            "type": "object",
            "required": ["t", "x", "y", "psi", "lon", "lat", "speed", "step", "inputs"],
            "properties": {k: SERIES for k in (*SERIES_RANGES, "step", "inputs")},
        },
    },
}


@cache
def _validator():
    from jsonschema import Draft202012Validator, validators

    # a JSON number must be finite (Python's json reads NaN and Infinity) and not a bool
    def finite(_checker, x) -> bool:
        return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)

    checker = Draft202012Validator.TYPE_CHECKER.redefine("number", finite)
    cls = validators.extend(Draft202012Validator, type_checker=checker)
    cls.check_schema(PLAN_SCHEMA)
    return cls(PLAN_SCHEMA)


def _where(path) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(the document)"


def _say(err) -> str:
    """One line for a schema violation: the field's path and what it must be, the value cut short."""
    if err.validator == "required":
        missing = err.message.split("'")[1] if err.message.count("'") >= 2 else "?"
        return f"field '{_where([*err.absolute_path, missing])}' is missing"
    v = err.instance
    shown = repr(v) if not isinstance(v, dict | list) else type(v).__name__
    shown = shown.encode("unicode_escape").decode("ascii")[:60]
    must = {
        "type": f"must be {err.validator_value}"
        if not isinstance(err.validator_value, list)
        else f"must be one of {err.validator_value}",
        "minimum": f"must be >= {err.validator_value}",
        "maximum": f"must be <= {err.validator_value}",
        "pattern": "must be text without control characters (NUL and the like)",
        "enum": f"must be one of {err.validator_value}",
        "const": f"must be {err.validator_value!r}",
    }.get(err.validator, err.message.splitlines()[0][:120])
    if err.validator == "type" and err.validator_value == "number":
        must = "must be a finite number"
    return f"field '{_where(err.absolute_path)}' {must}, got {shown}"


def check_plan_document(d: Any, src: str, err: type[UserError]) -> None:
    """Refuse (``err``, one line naming ``src`` and the field) a plan document the exporters cannot read."""
    from jsonschema.exceptions import best_match

    e = best_match(_validator().iter_errors(d))
    if e is not None:
        raise err(f"{src}: {_say(e)}; re-create the plan with plan-trial (or correct that field)")
    from primitives.profile_document import check_file_stem

    check_file_stem(d["ship"], f"{src}: field 'ship'", err)  # export names its files after it: never a path
    _check_samples(d["samples"], len(d["input_names"]), len(d["steps"]), src, err)
    _check_projection(d["projection"]["proj4"], src, err)
    chart = (d.get("stats") or {}).get("chart")
    if isinstance(chart, dict):
        _check_chart(chart, src, err)


def _numbers(values: list, name: str, src: str, err: type[UserError], integer: bool = False) -> np.ndarray:
    kinds = (int,) if integer else (int, float)
    if not all(type(x) in kinds for x in values):  # bool, str, None, lists: not a number here
        raise err(f"{src}: field 'samples.{name}' must hold only {'whole' if integer else 'finite'} numbers")
    return np.asarray(values, float)


def _check_samples(s: dict, n_inputs: int, n_steps: int, src: str, err: type[UserError]) -> None:
    """Equal lengths, numbers within their field's range, t not decreasing, steps that exist."""
    n = len(s["t"])
    for k in (*SERIES_RANGES, "step", "inputs"):
        if len(s[k]) != n:
            raise err(
                f"{src}: field 'samples.{k}' holds {len(s[k])} values and samples.t {n}: every sample series must be as long"
            )
    for k, rng in SERIES_RANGES.items():
        a = _numbers(s[k], k, src, err)
        if not (np.all(np.isfinite(a)) and np.all(a >= rng["minimum"]) and np.all(a <= rng["maximum"])):
            raise err(f"{src}: field 'samples.{k}' must hold finite numbers in {rng['minimum']:g} .. {rng['maximum']:g}")
    if np.any(np.diff(np.asarray(s["t"], float)) < 0):
        raise err(f"{src}: field 'samples.t' must not decrease")
    step = _numbers(s["step"], "step", src, err, integer=True)
    if len(step) and (step.min() < 0 or step.max() >= n_steps):
        raise err(f"{src}: field 'samples.step' must hold step indices 0 .. {n_steps - 1} (the plan has {n_steps} steps)")
    rows = s["inputs"]
    if not all(isinstance(r, list) and len(r) == n_inputs for r in rows):
        raise err(f"{src}: field 'samples.inputs' must hold one list per sample of one value per input_names entry ({n_inputs})")
    u = _numbers([x for r in rows for x in r], "inputs", src, err)
    if not np.all(np.isfinite(u)) or np.any(np.abs(u) > 1e12):
        raise err(f"{src}: field 'samples.inputs' must hold finite numbers")


def _check_projection(proj4: str, src: str, err: type[UserError]) -> None:
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    try:
        crs = CRS.from_user_input(proj4)
    except CRSError:
        raise err(
            f"{src}: field 'projection.proj4' = {proj4[:60]!r} is no coordinate system pyproj knows "
            "(unknown EPSG code or PROJ string); re-create the plan with plan-trial"
        ) from None
    if not crs.is_projected or crs.axis_info[0].unit_name not in ("metre", "meter"):
        raise err(
            f"{src}: field 'projection.proj4' = {proj4[:60]!r} must be a projected coordinate system in metres "
            "(the plan's local frame); re-create the plan with plan-trial"
        )


def _check_chart(chart: dict, src: str, err: type[UserError]) -> None:
    """The chart's geometries as shapely reads them (GeoJSON types, coordinates, rings), and valid:
    shiptrial writes valid ones, and GEOS's overlays of the exporters fail on a self-touching ring."""
    import shapely
    from shapely.geometry import shape

    geoms = [("land", chart.get("land")), ("no_go", chart.get("no_go"))]
    geoms += [(f"depth_areas[{i}].geometry", a.get("geometry")) for i, a in enumerate(chart.get("depth_areas") or [])]
    for name, g in geoms:
        if not g:
            continue
        try:
            geom = shape(g)
            ok = bool(shapely.is_valid_input(geom)) and (geom.is_empty or all(map(math.isfinite, geom.bounds)))
        except Exception:  # shapely raises many types for malformed GeoJSON (KeyError, TypeError, GEOSException...)
            ok = False
        if not ok:
            raise err(
                f"{src}: field 'stats.chart.{name}' is not a GeoJSON geometry shapely can read; re-create the plan "
                "with plan-trial (or export with --map)"
            )
        if not geom.is_valid:
            raise err(
                f"{src}: field 'stats.chart.{name}' is an invalid geometry ({shapely.is_valid_reason(geom)[:80]}); "
                "re-create the plan with plan-trial (or export with --map)"
            )
