"""Property-based tests of every loader: any input file raises the user-error class or loads.

Loaders: sea maps (maps.geo.load_map), recordings (CSV and MARIN .dat), ship profiles (TOML
and JSON), saved plans (maps.plan.Plan.load), sweep configs (expdesign.sweep.load_sweep) and
``shiptrial export`` of a mutated plan.json (a GeoJSON, GPX, RTZ or CSV export: the plan's chart,
projection, steps and samples reach the exporters, which must refuse in one line or write).
Inputs are valid documents with fields dropped, replaced by any JSON value or an extreme
number, plus raw random bytes. The default run uses a small fixed example budget; the
``slow`` variant runs 5,000 examples per loader (the issue's bar) but export, whose 5,000 examples
(about 0.04 s each) run in ``python benchmarks/fuzz_export.py`` instead of the CI budget.
"""

from __future__ import annotations

import copy
import json
import math
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from primitives.errors import UserError

FAST, SLOW = 40, 5000
TMP = Path(tempfile.mkdtemp(prefix="shiptrial-fuzz-"))
PROFILE_DIR = Path(__file__).resolve().parents[1] / "primitives" / "profiles"

EXTREME = st.sampled_from([0, -1, 1e-300, 1e308, -1e308, math.nan, math.inf, -math.inf, 2**70, True, "", "x", None])
JSONVAL = st.recursive(
    st.none() | st.booleans() | st.integers(-(10**6), 10**6) | st.floats(allow_nan=True) | st.text(max_size=8),
    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=6), kids, max_size=4),
    max_leaves=12,
)
ANY = EXTREME | JSONVAL


def _cfg(n: int):
    return settings(
        max_examples=n,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    )


def _paths(doc) -> list[tuple]:
    """Every path (tuple of keys/indices) into a nested dict/list document."""
    out = [()]
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += [(k, *p) for p in _paths(v)]
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:6]):
            out += [(i, *p) for p in _paths(v)]
    return out


@st.composite
def mutated(draw, base: dict, n_max: int = 3):
    """``base`` with up to ``n_max`` nodes replaced by any value, deleted, or a key added."""
    doc = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, n_max))):
        paths = _paths(doc)
        path = draw(st.sampled_from(paths))
        if not path:
            continue
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        action = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
        if action == "delete":
            del parent[path[-1]]
        elif action == "add" and isinstance(parent, dict):
            parent[draw(st.text(min_size=1, max_size=10))] = draw(ANY)
        else:
            parent[path[-1]] = draw(ANY)
    return doc


def _write(name: str, data: str | bytes) -> Path:
    p = TMP / name
    p.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8", "surrogatepass"))
    return p


def _loads_or_user_error(fn, *args, **kw):
    try:
        return fn(*args, **kw)
    except UserError:
        return None


def _json(doc) -> str:
    return json.dumps(doc, allow_nan=True)


def _toml(doc: dict) -> str:
    """A tiny TOML writer for fuzzed documents (values TOML cannot hold are written as strings)."""

    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, int):
            return str(v)
        if isinstance(v, float):
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(str(k))} = {val(x)}" for k, x in v.items()) + "}"
        return '"null"'

    return "\n".join(f"{json.dumps(str(k))} = {val(v)}" for k, v in doc.items()) + "\n"


# -- the loaders' base documents --------------------------------------------------------------------

MAP = {
    "type": "FeatureCollection",
    "name": "fuzz",
    "features": [
        {
            "type": "Feature",
            "properties": {"kind": "land"},
            "geometry": {"type": "Polygon", "coordinates": [[[24.9, 60.1], [24.95, 60.1], [24.95, 60.12], [24.9, 60.1]]]},
        },
        {
            "type": "Feature",
            "properties": {"kind": "depth_area", "min_depth_m": 3.0},
            "geometry": {"type": "Polygon", "coordinates": [[[24.96, 60.1], [24.97, 60.1], [24.97, 60.11], [24.96, 60.1]]]},
        },
        {
            "type": "Feature",
            "properties": {"kind": "obstacle", "radius_m": 20},
            "geometry": {"type": "Point", "coordinates": [24.98, 60.13]},
        },
        {
            "type": "Feature",
            "properties": {"kind": "start", "heading_deg": 90},
            "geometry": {"type": "Point", "coordinates": [24.99, 60.14]},
        },
    ],
}

PROFILE = tomllib.loads((PROFILE_DIR / "model-ship.toml").read_text())

PLAN = {
    "format": "shiptrial-plan/1",
    "ship": "model-ship",
    "map_name": "helsinki",
    "feasible": True,
    "optimal": True,
    "min_clearance_m": 50.0,
    "margin_m": 20.0,
    "counts": {"tau1": 1},
    "targets": {"tau1": 1},
    "stats": {},
    "projection": {"proj4": "+proj=tmerc +lat_0=60.1 +lon_0=24.9 +ellps=WGS84 +units=m", "lon0": 24.9, "lat0": 60.1},
    "hull": [1.0, 0.3],
    "max_wind_mps": 10.0,
    "input_names": ["tau_x", "tau_y", "tau_n"],
    "steps": [
        {
            "index": 0,
            "primitive": "tau1",
            "kind": "informative",
            "description": "d",
            "start_time_s": 0.0,
            "duration_s": 0.25,
            "entry_x": 0.0,
            "entry_y": 0.0,
            "entry_psi": 0.0,
            "entry_lon": 24.9,
            "entry_lat": 60.1,
            "entry_speed_mps": 1.0,
            "commands": ["go"],
            "space_m": [1.0, 0.5],
        }
    ],
    "samples": {
        "t": [0.0, 0.125, 0.25],
        "x": [0.0, 0.1, 0.2],
        "y": [0.0, 0.0, 0.0],
        "psi": [0.0, 0.0, 0.0],
        "lon": [24.9, 24.9, 24.9],
        "lat": [60.1, 60.100001, 60.100002],
        "speed": [1.0, 1.0, 1.0],
        "step": [0, 0, 0],
        "inputs": [[0.0, 0.0, 0.0]] * 3,
    },
}

SWEEP = {
    "sweep": {
        "ships": ["model-ship"],
        "criteria": ["D"],
        "mean_subtraction": ["complete"],
        "library": "standard",
        "speeds": [1.0],
        "seed": 1,
    }
}

_t = np.arange(60) * 0.5
REC_COLS = {
    "t": _t,
    "x": np.cumsum(np.full(60, 0.5)),
    "y": 0.01 * _t**2,
    "psi": 0.02 * _t,
    "u": np.ones(60),
    "v": np.zeros(60),
    "r": np.full(60, 0.02),
    "tau_x": np.full(60, 100.0),
}


# -- strategies per loader --------------------------------------------------------------------------

CSV_CELL = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64).map(repr),
    st.sampled_from(["", "nan", "x", "1e400", "-0"]),
    st.integers(-(10**12), 10**12).map(str),
)


@st.composite
def _corruptions(draw, n_rows: int, n_cols: int, cell) -> list[tuple[int, int, object]]:
    """Up to 6 (row, column, value) cells to overwrite: cheap to draw, so 5,000 examples stay fast."""
    if n_rows == 0:
        return []
    return draw(st.lists(st.tuples(st.integers(0, n_rows - 1), st.integers(0, n_cols - 1), cell), max_size=6))


@st.composite
def csv_text(draw) -> str:
    names = draw(
        st.lists(st.sampled_from(list(REC_COLS) + ["lat", "lon", "segment", "n", "junk"]), min_size=1, max_size=9, unique=True)
    )
    n = draw(st.integers(0, 60))
    header = [
        f"# {draw(st.sampled_from(['sample_time', 'scale', 'scale_factor', 'ship']))}: "
        f"{draw(st.sampled_from(['0.5', '0', '-1', 'nan', 'model', 'full', 'abc', '1e-9', '45.7']))}"
        for _ in range(draw(st.integers(0, 3)))
    ]
    table = [[repr(float(REC_COLS[c][i])) if c in REC_COLS else "1.0" for c in names] for i in range(n)]
    for i, j, v in draw(_corruptions(n, len(names), CSV_CELL)):
        table[i][j] = v
    return "\n".join([*header, ",".join(names), *(",".join(r) for r in table)]) + "\n"


@st.composite
def dat_text(draw) -> str:
    n = draw(st.integers(0, 120))
    step = draw(st.sampled_from([0.135, 0.135, 1.0, 0.0, -1.0, 1e9]))
    table = [
        [i * step, 8.0 * i * step, 0.1 * i * step, 0.2, 0.5 * i * step, 8.0, 0.02, 0.0, 0.5, 10.0 * (-1) ** (i // 20), 91.5]
        for i in range(n)
    ]
    for i, j, v in draw(_corruptions(n, 11, st.floats(allow_nan=True, allow_infinity=True))):
        table[i][j] = v
    rows = ["\t".join(f"{v:.2E}" if math.isfinite(v) else str(v) for v in r) for r in table]
    return "MARIN\nZig-zag\n" + "\n".join(rows) + "\n"


RAW = st.binary(max_size=300)


# -- the property, one function per loader -------------------------------------------------------------


def _map_case(doc_or_bytes):
    from maps.geo import load_map

    data = doc_or_bytes if isinstance(doc_or_bytes, bytes) else _json(doc_or_bytes)
    _loads_or_user_error(load_map, _write("m.geojson", data), draught_m=2.0)


def _profile_case(doc_or_bytes, fmt):
    from primitives.ship import load_profile

    if isinstance(doc_or_bytes, bytes):
        data = doc_or_bytes
    else:
        data = _json(doc_or_bytes) if fmt == "json" else _toml(doc_or_bytes)
    _loads_or_user_error(load_profile, _write(f"p.{fmt}", data))


def _plan_case(doc_or_bytes):
    from maps.plan import Plan

    data = doc_or_bytes if isinstance(doc_or_bytes, bytes) else _json(doc_or_bytes)
    _loads_or_user_error(Plan.load, _write("plan.json", data))


def _sweep_case(doc_or_bytes):
    from expdesign.sweep import load_sweep

    data = doc_or_bytes if isinstance(doc_or_bytes, bytes) else _toml(doc_or_bytes)
    _loads_or_user_error(load_sweep, _write("s.toml", data))


def _export_base() -> dict:
    """A saved plan with an embedded chart (land west of the track), as ``shiptrial plan`` writes it."""
    from maps.export._testing import synthetic_plan

    d = json.loads(synthetic_plan("model-ship").to_json())
    del d["digest"]  # read as a plan without a digest (a note), so that the fuzz's edits reach the exporters
    d["stats"]["chart"] = {
        "name": "fuzz",
        "land": {"type": "Polygon", "coordinates": [[[24.93, 60.11], [24.94, 60.11], [24.94, 60.13], [24.93, 60.11]]]},
        "no_go": None,
        "depth_areas": [],
        "extent": [24.9, 60.1, 25.0, 60.14],
    }
    d["stats"]["turning_radius_m"] = 3.0
    return d


EXPORT_PLAN = _export_base()
EXPORT_FORMATS = ("geojson", "gpx", "rtz", "csv")


def _export_case(doc_and_fmt):
    """``shiptrial export`` exits 0 (written) or 2 (one line ``error:``); any other exception escapes
    ``cli.app._run`` and fails the property."""
    from cli.app import _run

    doc, fmt = doc_and_fmt
    data = doc if isinstance(doc, bytes) else _json(doc)
    rc = _run(["export", str(_write("export-plan.json", data)), "--format", fmt, "--out", str(TMP / f"exported.{fmt}")])
    assert rc in (0, 2), rc


def _csv_case(text_or_bytes):
    from diagnose.recording import load_recording

    _loads_or_user_error(load_recording, _write("r.csv", text_or_bytes))


def _dat_case(text_or_bytes):
    from diagnose.recording import load_recording

    _loads_or_user_error(load_recording, _write("r.dat", text_or_bytes))


CASES = {
    "map": (lambda: st.one_of(mutated(MAP, 4), RAW), _map_case),
    "profile_toml": (lambda: st.one_of(mutated(PROFILE, 3), RAW), lambda d: _profile_case(d, "toml")),
    "profile_json": (lambda: st.one_of(mutated(PROFILE, 3), RAW), lambda d: _profile_case(d, "json")),
    "plan": (lambda: st.one_of(mutated(PLAN, 3), RAW), _plan_case),
    "sweep": (lambda: st.one_of(mutated(SWEEP, 3), RAW), _sweep_case),
    "recording_csv": (lambda: st.one_of(csv_text(), RAW), _csv_case),
    "recording_dat": (lambda: st.one_of(dat_text(), RAW), _dat_case),
    "export": (lambda: st.tuples(st.one_of(mutated(EXPORT_PLAN, 3), RAW), st.sampled_from(EXPORT_FORMATS)), _export_case),
}
SLOW_CASES = [c for c in CASES if c != "export"]  # export's 5,000: benchmarks/fuzz_export.py


def _check(name: str, budget: int) -> None:
    strategy, case = CASES[name]

    @_cfg(budget)
    @given(strategy())
    def prop(x):
        case(x)

    prop()


@pytest.mark.parametrize("loader", list(CASES))
def test_loader_raises_user_error_or_loads(loader):
    _check(loader, FAST)


@pytest.mark.slow
@pytest.mark.parametrize("loader", SLOW_CASES)
def test_loader_raises_user_error_or_loads_5000(loader):
    _check(loader, SLOW)


def test_base_documents_load():
    """The fuzzers start from documents that load: mutations explore the loaders, not their first check."""
    from expdesign.sweep import load_sweep
    from maps.geo import load_map
    from maps.plan import Plan
    from primitives.ship import load_profile

    load_map(_write("base.geojson", _json(MAP)))
    load_profile(_write("base.toml", _toml(PROFILE)))
    load_profile(_write("base.json", _json(PROFILE)))
    Plan.load(_write("base-plan.json", _json(PLAN)))
    assert len(load_sweep(_write("base.toml", _toml(SWEEP)))) == 1
    cols = ",".join(REC_COLS)
    rows = "\n".join(",".join(repr(float(REC_COLS[c][i])) for c in REC_COLS) for i in range(60))
    from diagnose.recording import load_recording

    assert load_recording(_write("base.csv", f"# sample_time: 0.5\n{cols}\n{rows}\n"))[0].n_samples == 60
