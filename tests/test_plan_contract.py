"""The Plan data contract the exporters read: segments, orders, abort criteria, design, vessel name."""

from __future__ import annotations

import json

import numpy as np
import pytest

from maps.plan import Plan, PlanStep


def _step(i: int, kind: str, **kw) -> PlanStep:
    return PlanStep(
        index=i,
        primitive="p",
        kind=kind,
        description="d",
        start_time_s=float(i),
        duration_s=1.0,
        entry_x=0.0,
        entry_y=0.0,
        entry_psi=0.0,
        entry_lon=25.0,
        entry_lat=60.0,
        entry_speed_mps=3.0,
        **kw,
    )


PROJECTION = {"proj4": "+proj=tmerc +lat_0=0 +lon_0=0 +ellps=WGS84 +units=m", "lon0": 0.0, "lat0": 0.0}  # the exporters need one


def _plan(steps: list[PlanStep], **kw) -> Plan:
    n = len(steps) + 1
    return Plan(
        ship="s",
        steps=steps,
        t=np.arange(n, dtype=float),
        track=np.zeros((n, 3)),
        lonlat=np.zeros((n, 2)),
        speed=np.ones(n),
        step_of_sample=np.minimum(np.arange(n), len(steps) - 1),
        inputs=np.zeros((n, 1)),
        input_names=["a"],
        projection=PROJECTION,
        feasible=True,
        optimal=True,
        min_clearance_m=50.0,
        margin_m=20.0,
        counts={"p": 1},
        targets={"p": 1},
        **kw,
    )


def test_new_fields_round_trip():
    steps = [
        _step(0, "basic"),
        _step(1, "run-in"),
        _step(
            2,
            "informative",
            execute=True,
            orders=[{"t_s": 0.0, "text": "rudder 10 deg starboard", "rudder_deg": 10.0}],
            abort=["clearance below 50 m"],
        ),
    ]
    design = {
        "criterion": "D",
        "mean_subtraction": "complete",
        "weights": {"p": 1.0},
        "counts": {"p": 1},
        "d_efficiency": 0.97,
        "dropped": [{"primitive": "q", "needs_m": [900.0, 400.0], "efficiency_loss": 0.1}],
    }
    p = _plan(steps, design=design, vessel_name="M/S Test")
    q = Plan.from_dict(json.loads(p.to_json()))
    assert [s.segment for s in q.steps] == ["transit", "run-in", "informative"]
    assert q.steps[2].execute and not q.steps[1].execute
    assert q.steps[2].orders == steps[2].orders and q.steps[2].abort == ["clearance below 50 m"]
    assert q.design == design and q.vessel_name == "M/S Test"
    assert q.basic_moves == 1 and [s.index for s in q.segment_steps("run-in")] == [1]


def test_old_plan_json_still_loads():
    """A plan written before segments existed: the new fields default, segments follow the kind."""
    d = json.loads(_plan([_step(0, "basic"), _step(1, "informative")]).to_json())
    for st in d["steps"]:
        for k in ("segment", "orders", "abort", "execute"):
            del st[k]
    del d["design"], d["vessel_name"], d["digest"]  # nor a digest (stop 60)
    q = Plan.from_dict(d)
    assert [s.segment for s in q.steps] == ["transit", "informative"]
    assert q.design == {} and q.vessel_name == "" and q.steps[1].orders == [] and not q.steps[1].execute


def test_unknown_segment_rejected():
    with pytest.raises(ValueError, match="segment"):
        _step(0, "basic", segment="approach")


def test_held_parameters_round_trip_and_a_malformed_row_is_refused_in_one_line():
    """Issue 28's design rows: the card words them from the file, so a hand-edited row is refused
    naming the field (before, a string 'identified_by' loaded and the card export raised a TypeError)."""
    from maps.plan import PlanError

    held = [
        {"parameter": "Yur", "value": -0.64, "identified_by": {"primitive": "q", "needs_m": [900.0, 400.0], "unreachable": True}},
        {"parameter": "Nrr", "value": -1.7, "identified_by": None},
    ]
    design = {"counts": {"p": 1}, "dropped": [{"primitive": "q", "needs_m": [900.0, 400.0], "unreachable": True}]}
    d = json.loads(_plan([_step(0, "informative")], design=design | {"held_parameters": held}).to_json())
    assert Plan.from_dict(d).design["held_parameters"] == held
    d["design"]["held_parameters"][0]["identified_by"] = "q"
    with pytest.raises(PlanError, match=r"design.held_parameters\[0\].identified_by") as exc:
        Plan.from_dict(d, "p.json")
    assert len(str(exc.value).splitlines()) == 1


def _json_dumps_document(p: Plan) -> str:
    """The plan document as stop 60 wrote it: the whole document through json.dumps once more after each field's
    canonical JSON (sorted keys, no spaces, the timings left out at every depth) was hashed for the digest."""
    import hashlib

    from maps.plan import TIMINGS
    from primitives.io import to_jsonable

    def untimed(v):
        if isinstance(v, dict):
            return {k: untimed(x) for k, x in v.items() if k not in TIMINGS}
        return [untimed(x) for x in v] if isinstance(v, list) else v

    d = to_jsonable(p.to_dict())
    canon = {k: json.dumps(untimed(v), sort_keys=True, separators=(",", ":")) for k, v in d.items()}
    d["digest"] = {k: hashlib.sha256(c.encode()).hexdigest()[:16] for k, c in canon.items()}
    return json.dumps(d)


def test_to_json_is_json_dumps_of_the_document_byte_for_byte():
    """Stop 61: to_json serialises each field once for both the document and its digest; the text must stay what
    json.dumps wrote, digest included, on what a separator or key order could change: strings holding ", " and ": ",
    nested tables in unsorted order, timings at two depths, non-ASCII text, lists of lists, nulls, empty lists."""
    orders = [{"t_s": 0.0, "text": "hard a-port, then: midships", "z": [1, [2.5, None]]}]
    steps = [_step(0, "basic", orders=orders, abort=["clearance, below: 50 m", "wind"])]
    p = _plan(
        steps,
        stats={"search_s": 0.5, "zeta": {"plan_time_s": 1.0, "b": "x, y: z"}, "alpha": [], "mid": [[1.0, 2.0], [3.0]]},
        design={"weights": {"z": 1.0, "a": 2.0}, "dropped": [{"primitive": "q", "needs_m": [900.0, 400.0]}]},
        vessel_name='Å/S Tëst, "quoted": yes',
    )
    assert p.to_json() == _json_dumps_document(p)
    timed = _plan(
        steps, stats={"search_s": 9.0, "zeta": {"plan_time_s": 7.0, "b": "x, y: z"}, "alpha": [], "mid": [[1.0, 2.0], [3.0]]}
    )
    untimed = _plan(steps, stats={"zeta": {"b": "x, y: z"}, "alpha": [], "mid": [[1.0, 2.0], [3.0]]})
    assert json.loads(timed.to_json())["digest"] == json.loads(untimed.to_json())["digest"]


def test_the_digest_check_builds_the_canonical_text_the_writer_digests():
    """Stop 62: check_digest builds the canonical text alone (``_canonical``) while the writer builds both texts in
    one pass (``_pieces``): two codings of one text, and if they ever differ every plan read back is refused as
    edited. Equal, and equal to json.dumps's canonical form, on every field of a plan and on the corner cases
    (timings at any depth, strings holding ", " and ": ", mixed lists, nested lists of numbers)."""
    from maps.export._testing import synthetic_plan
    from maps.plan import TIMINGS, _canonical, _pieces
    from primitives.io import to_jsonable

    def untimed(v):
        if isinstance(v, dict):
            return {k: untimed(x) for k, x in v.items() if k not in TIMINGS}
        return [untimed(x) for x in v] if isinstance(v, list) else v

    odd = {
        "b": [1, 2.5, None, [3, [4, 5]], True],
        "plan_time_s": 9.0,
        "a": {"search_s": 1.0, "x": "p, q: r", "y": [{"total_time_s": 2, "z": [False, "s, t"]}, [0.1, {"k": 1}]]},
    }
    doc = to_jsonable(synthetic_plan("model-ship", ("straight", "turn_s")).to_dict())
    for name, v in [("odd", odd), *doc.items()]:
        canon = json.dumps(untimed(v), sort_keys=True, separators=(",", ":"))
        assert _canonical(v) == _pieces(v)[1] == canon, name
