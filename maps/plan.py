"""The Plan: what the planner returns and every exporter reads.

Positions are in the map's local metric frame in the ship convention (Fossen 2021, ch. 2: x north, y east, psi from north):
x north, y east, in metres from the projection origin; heading psi in radians from north,
clockwise. ``lonlat`` columns carry the same points in WGS-84 for the exporters.
A plan saved as JSON (``Plan.to_json`` / ``Plan.from_json``) is self-contained: exporters
need nothing else (no map, no profile file).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from primitives.errors import UserError

PLAN_FORMAT = "shiptrial-plan/1"
SEGMENTS = ("run-in", "informative", "transit")


class PlanError(UserError):
    """A saved plan that cannot be read; the message names the file and the field."""


DIGEST_KEY = "digest"  # {field: the first 16 hex digits of the SHA-256 of its canonical JSON}, written by to_json


# the planner's timings (in stats): not the plan's content, and different on every run of the same plan
TIMINGS = frozenset({"plan_time_s", "expansions_per_s", "setup_time_s", "design_time_s", "total_time_s", "search_s"})


_NO_TEXT = frozenset({int, float, bool, type(None)})  # JSON values whose text holds no ", " nor ": "


def _no_text(v: list) -> bool:
    """Whether ``v`` holds only numbers, booleans, nulls and lists of them (a plan's samples): its JSON text then has
    no string or object that a separator could stand in, only the lists' ", " between items."""
    kinds = set(map(type, v))
    return kinds <= _NO_TEXT or (kinds <= _NO_TEXT | {list} and all(_no_text(x) for x in v if type(x) is list))


def _pieces(v: Any) -> tuple[str, str]:
    """A JSON value's text twice from one serialisation of each part: as ``json.dumps(v)`` writes it (the document)
    and canonical, as ``json.dumps(v, sort_keys=True, separators=(",", ":"))`` with the timings' keys left out at every
    depth (the digest's). A list of plain numbers (the bulk of a plan) is serialised once and its ", " made ","."""
    if isinstance(v, dict):
        parts = {k: (json.dumps(k), *_pieces(x)) for k, x in v.items()}
        doc = ", ".join(f"{key}: {text}" for key, text, _ in parts.values())
        canon = ",".join(f"{parts[k][0]}:{parts[k][2]}" for k in sorted(parts) if k not in TIMINGS)
        return "{" + doc + "}", "{" + canon + "}"
    if isinstance(v, list) and not _no_text(v):
        items = [_pieces(x) for x in v]
        return "[" + ", ".join(t for t, _ in items) + "]", "[" + ",".join(c for _, c in items) + "]"
    text = json.dumps(v)
    return text, text.replace(", ", ",") if isinstance(v, list) else text


def _canonical(v: Any) -> str:
    """``_pieces(v)[1]`` alone: the canonical text, without building the document's text (reading a plan checks
    its digest and writes nothing, so that text was thrown away)."""
    if isinstance(v, dict):
        return "{" + ",".join(f"{json.dumps(k)}:{_canonical(v[k])}" for k in sorted(v) if k not in TIMINGS) + "}"
    if isinstance(v, list) and not _no_text(v):
        return "[" + ",".join(_canonical(x) for x in v) + "]"
    text = json.dumps(v)
    return text.replace(", ", ",") if isinstance(v, list) else text


def _digest(canonical: str) -> str:
    return hashlib.sha256(canonical.encode()).hexdigest()[:16]


def content_digest(d: dict[str, Any]) -> dict[str, str]:
    """Each field of a plan document (but the digest) as the first 16 hex digits of the SHA-256 of its canonical JSON
    (sorted keys, no spaces; the timings left out, so that plans equal but for them have equal digests): a field
    edited by hand after plan-trial wrote the plan no longer matches its own."""
    return {k: _digest(_canonical(v)) for k, v in d.items() if k != DIGEST_KEY}


def check_digest(d: dict[str, Any], src: str) -> str | None:
    """Refuse a plan whose fields differ from its digest (labels edited by hand: a 'feasible' false made true puts
    an infeasible plan on the crew's card as feasible; another 'ship' gives export another ship's draught). A plan
    written before plans carried a digest (stop 60) is read, and the note returned says its content is unchecked."""
    stored = d.get(DIGEST_KEY)
    if stored is None:
        return f"{src}: the plan carries no digest (written before stop 60, or deleted): its fields are not checked against edits"
    if not isinstance(stored, dict) or not all(isinstance(v, str) for v in stored.values()):
        raise PlanError(f"{src}: field {DIGEST_KEY!r} is malformed; re-create the plan with plan-trial")
    now = content_digest(d)
    edited = sorted(k for k in set(now) | set(stored) if now.get(k) != stored.get(k))
    if edited:
        raise PlanError(
            f"{src}: field(s) {', '.join(map(repr, edited))} changed after plan-trial wrote the plan (its digest "
            f"differs); re-create the plan with plan-trial (export --vessel-name, --start and --map change the exports "
            f"without editing the plan), or delete the field {DIGEST_KEY!r} to use it as edited (unchecked)"
        )
    return None


@dataclass
class PlanStep:
    """One manoeuvre of the plan, in sailing order."""

    index: int
    primitive: str
    kind: str  # "informative" | "basic" (a repositioning lattice move) | "run-in"
    description: str
    start_time_s: float
    duration_s: float
    entry_x: float
    entry_y: float
    entry_psi: float
    entry_lon: float
    entry_lat: float
    entry_speed_mps: float
    commands: list[str] = field(default_factory=list)
    space_m: tuple[float, float] = (0.0, 0.0)  # along-track, cross-track extent of its footprint
    # "run-in" (steady approach before an execute point), "informative" or "transit"
    # (repositioning); "" in a plan written before segments existed: derived from ``kind``.
    segment: str = ""
    orders: list[dict[str, Any]] = field(default_factory=list)  # {"t_s", "text", **values} from Primitive.orders
    abort: list[str] = field(default_factory=list)  # abort criteria for the crew
    execute: bool = False  # True on an informative step that starts at an execute point

    def __post_init__(self) -> None:
        if not self.segment:
            self.segment = {"informative": "informative", "run-in": "run-in"}.get(self.kind, "transit")
        if self.segment not in SEGMENTS:
            raise ValueError(f"plan step {self.index}: field 'segment' must be one of {SEGMENTS}, got {self.segment!r}")

    @property
    def entry_heading_deg(self) -> float:
        return float(np.degrees(self.entry_psi) % 360.0)


@dataclass
class Plan:
    """A planned trial: steps, the continuous re-simulated track and the planner's figures.

    track: (K, 3) x north, y east, psi; lonlat: (K, 2) lon, lat; t: (K,) seconds;
    speed: (K,) m/s over ground; step_of_sample: (K,) index of the step each sample belongs to;
    inputs: (K, m) commanded inputs (profile's input names in ``input_names``).
    """

    ship: str
    steps: list[PlanStep]
    t: np.ndarray
    track: np.ndarray
    lonlat: np.ndarray
    speed: np.ndarray
    step_of_sample: np.ndarray
    inputs: np.ndarray
    input_names: list[str]
    projection: dict[str, Any]  # {"proj4": ..., "lon0": ..., "lat0": ...}
    feasible: bool
    optimal: bool
    min_clearance_m: float
    margin_m: float
    counts: dict[str, int]
    targets: dict[str, int]
    stats: dict[str, Any] = field(default_factory=dict)  # expansions, states, plan_time_s, heuristic...
    map_name: str = ""
    hull: tuple[float, float] = (0.0, 0.0)  # length, beam
    max_wind_mps: float = 10.0
    # the experiment design behind the counts: {"criterion", "mean_subtraction", "weights": {name: w},
    # "counts": {name: n}, "d_efficiency", "dropped": [{"primitive", "needs_m": [along, cross],
    # "efficiency_loss"}]}; {} when the counts were given by hand
    design: dict[str, Any] = field(default_factory=dict)
    vessel_name: str = ""
    read_notes: list[str] = field(default_factory=list)  # said when read back (not saved): an unchecked content

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    @property
    def length_m(self) -> float:
        return float(np.sum(np.hypot(*np.diff(self.track[:, :2], axis=0).T))) if len(self.track) > 1 else 0.0

    @property
    def basic_moves(self) -> int:
        return sum(1 for s in self.steps if s.segment == "transit")

    def segment_steps(self, segment: str) -> list[PlanStep]:
        """The steps of one segment kind ("run-in", "informative" or "transit"), in sailing order."""
        return [s for s in self.steps if s.segment == segment]

    def to_dict(self) -> dict[str, Any]:
        d = {
            "format": PLAN_FORMAT,
            "ship": self.ship,
            "map_name": self.map_name,
            "feasible": self.feasible,
            "optimal": self.optimal,
            "min_clearance_m": self.min_clearance_m,
            "margin_m": self.margin_m,
            "counts": self.counts,
            "targets": self.targets,
            "stats": self.stats,
            "projection": self.projection,
            "hull": list(self.hull),
            "max_wind_mps": self.max_wind_mps,
            "design": self.design,
            "vessel_name": self.vessel_name,
            "input_names": self.input_names,
            "steps": [asdict(s) for s in self.steps],
            "samples": {
                "t": self.t.tolist(),
                "x": self.track[:, 0].tolist(),
                "y": self.track[:, 1].tolist(),
                "psi": self.track[:, 2].tolist(),
                "lon": self.lonlat[:, 0].tolist(),
                "lat": self.lonlat[:, 1].tolist(),
                "speed": self.speed.tolist(),
                "step": self.step_of_sample.tolist(),
                "inputs": self.inputs.tolist(),
            },
        }
        return d

    def to_json(self) -> str:
        """The plan document with its ``digest`` (:func:`content_digest`): export and resume refuse a plan whose
        fields were edited after plan-trial wrote it."""
        from primitives.io import to_jsonable

        fields = {k: (json.dumps(k), *_pieces(v)) for k, v in to_jsonable(self.to_dict()).items()}
        digest = {k: _digest(canon) for k, (_, _, canon) in fields.items()}
        doc = [f"{key}: {text}" for key, text, _ in fields.values()] + [f"{json.dumps(DIGEST_KEY)}: {json.dumps(digest)}"]
        return "{" + ", ".join(doc) + "}"  # json.dumps of the document with its digest last, byte for byte

    @classmethod
    def from_dict(cls, d: dict[str, Any], src: str = "<plan>") -> Plan:
        """A plan from its JSON document, checked against the declared schema
        (:mod:`maps.plan_schema`) first: any malformed field is a :class:`PlanError` naming it."""
        from maps.plan_schema import check_plan_document

        if not isinstance(d, dict):
            raise PlanError(f"{src}: malformed plan (a JSON {type(d).__name__}, not an object); re-create it with plan-trial")
        if d.get("format") != PLAN_FORMAT:
            raise PlanError(f"{src}: field 'format' must be {PLAN_FORMAT!r}: not a plan written by shiptrial")
        check_plan_document(d, src, PlanError)
        unchecked = check_digest(d, src)
        try:
            plan = cls._from_dict(d)
        except KeyError as exc:
            raise PlanError(f"{src}: plan field {exc} is missing: re-create the plan with plan-trial") from None
        except (TypeError, ValueError, AttributeError, IndexError, OverflowError) as exc:
            raise PlanError(
                f"{src}: malformed plan ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
                "re-create it with plan-trial"
            ) from None
        for name, arr in (("t", plan.t), ("x, y, psi", plan.track), ("lon, lat", plan.lonlat)):
            if not np.all(np.isfinite(arr)):
                raise PlanError(
                    f"{src}: samples '{name}' hold values that are not finite numbers; re-create the plan with plan-trial"
                )
        plan.read_notes = [unchecked] if unchecked else []
        return plan

    @classmethod
    def _from_dict(cls, d: dict[str, Any]) -> Plan:
        s = d["samples"]
        steps = [PlanStep(**{**st, "space_m": tuple(st.get("space_m", (0.0, 0.0)))}) for st in d["steps"]]  # new fields default
        return cls(
            ship=d["ship"],
            steps=steps,
            t=np.asarray(s["t"], float),
            track=np.column_stack([s["x"], s["y"], s["psi"]]).astype(float),
            lonlat=np.column_stack([s["lon"], s["lat"]]).astype(float),
            speed=np.asarray(s["speed"], float),
            step_of_sample=np.asarray(s["step"], int),
            inputs=np.asarray(s["inputs"], float).reshape(len(s["t"]), len(d["input_names"])),
            input_names=list(d["input_names"]),
            projection=d["projection"],
            feasible=bool(d["feasible"]),
            optimal=bool(d["optimal"]),
            min_clearance_m=float(d["min_clearance_m"]) if d["min_clearance_m"] is not None else float("nan"),
            margin_m=float(d["margin_m"]),
            counts=dict(d["counts"]),
            targets=dict(d["targets"]),
            stats=dict(d.get("stats", {})),
            map_name=d.get("map_name", ""),
            hull=tuple(d.get("hull", (0.0, 0.0))),
            max_wind_mps=float(d.get("max_wind_mps", 10.0)),
            design=dict(d.get("design") or {}),
            vessel_name=str(d.get("vessel_name", "")),
        )

    @classmethod
    def load(cls, path: str | Path) -> Plan:
        path = Path(path)
        try:
            d = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise FileNotFoundError(f"{path}: no such plan file (write one with plan-trial --out DIR)") from None
        except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
            raise PlanError(
                f"{path}: not valid JSON text ({type(exc).__name__}); give the plan.json written by plan-trial"
            ) from None
        except IsADirectoryError:
            raise PlanError(f"{path}: is a directory; give the plan.json written by plan-trial") from None
        return cls.from_dict(d, str(path))
