"""Top level: plan a trial on a sea map (Ljungberg 2022, chapter 8, section 9.4) -> :class:`maps.plan.Plan`.

A thin composition of the steps in :mod:`maps.chain` (each callable on its own):

1. design (:mod:`maps.trialdesign`): the optimal mix of the ship's library rounded to whole
   manoeuvres; what fits nowhere on the map is dropped and the design redone;
2. lattice: window, collision grid, motion set (run-in + primitive + settling leg, basic moves);
3. search: A* over (i, j, heading, g_1..g_Q) (8.3) with soft clearance in the cost;
4. verify: transit straightened by shortcuts, continuous re-simulation against the margin;
   a failing placement is blocked and the search repeated before footprints are grown.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from expdesign.dopt import canonical_criterion
from expdesign.errors import DesignError
from expdesign.prior import ParameterPrior
from maps.chain import LatLonHdg, PlanOptions, assemble_plan, build_lattice, prepare_basic_moves, search_plan, verify_plan
from maps.geo import MapError, SeaMap, load_map
from maps.motionset import default_resolution, resolve_primitives
from maps.plan import Plan
from maps.sailable import MAX_STATES as SAILABLE_STATES
from maps.sailable import UNDECIDED, not_sailable_together
from maps.scenario import thesis_planning_scenario
from maps.sizing import Needs
from maps.smooth import unsteady_executes
from maps.trialdesign import FirstDesign, TrialDesign, TrialTooShort, design_for_map
from primitives.library import Primitive
from primitives.ship import ShipProfile, load_profile

SCENARIOS = ("thesis-9.4",)
MAX_EXTRA_M = 100.0
CONFINED_LENGTHS = 1.25  # lattice spacing in confined water, ship lengths
CONFINED_NOTE = (
    "confined water: the ship's library does not all fit, so the lattice is {res:.0f} m and every move settles onto "
    "it as a master would (steady within 0.5 deg, rate of turn under 0.05 m/s at the ends of the hull, sway under "
    "0.05 m/s, speed within 0.1 m/s, regained full ahead, on the lattice line within half the beam) rather than to "
    "the autopilot's 0.2 deg and 1 % of a length"
)
MAX_REDESIGNS = 6  # confined water: designs redone without what cannot be sailed with the rest of the mix
CONFINED_TRIED = "confined-water settling (a finer lattice, moves settled as a master would) tried and not kept"

__all__ = ["PlanOptions", "plan_trial", "plan_with_design", "default_resolution", "SCENARIOS"]


def _counts_given(
    prof: ShipProfile, counts: dict[str, int], primitives: list[Primitive] | None
) -> tuple[list[Primitive], dict[str, int]]:
    bad = {k: v for k, v in counts.items() if not isinstance(v, (int, np.integer)) or v < 0}
    if bad:
        raise MapError(f"--counts must be whole numbers >= 0, got {bad}")
    counts = {k: int(v) for k, v in counts.items() if v > 0}
    if not counts:
        raise MapError("--counts: every count is 0: nothing to plan")
    return resolve_primitives(prof, counts, primitives), counts


def plan_trial(*args: Any, **kw: Any) -> Plan:
    """Plan a trial (see :func:`plan_with_design`, which also returns the design)."""
    return plan_with_design(*args, **kw)[0]


def plan_with_design(
    sea: SeaMap | str | Path | None = None,
    *,
    profile: ShipProfile | str = "full-scale",
    counts: dict[str, int] | None = None,
    primitives: list[Primitive] | None = None,
    start: LatLonHdg | None = None,
    goal: LatLonHdg | None = None,
    scenario: str | None = None,
    criterion: str = "D",
    mean_subtraction: str = "complete",
    trial_length_s: float | None = None,
    seed: int = 0,
    vessel_name: str = "",
    options: PlanOptions | None = None,
    first_design: Callable[[], FirstDesign | None] | None = None,
    parameter_prior: ParameterPrior | None = None,
    **opts: Any,
) -> tuple[Plan, TrialDesign | None]:
    """Plan a trial that sails every informative primitive ``counts[name]`` times (8.4) with as
    little repositioning as possible (8.8), from ``start`` to ``goal`` ((lat, lon, heading_deg|None)).

    Without ``counts``: the design of the ship's library (``criterion``, ``mean_subtraction``,
    ``trial_length_s``, ``seed`` as in ``shiptrial design``; ``parameter_prior`` for the robust
    criteria bayes-D and maximin-D), or ``scenario="thesis-9.4"``.
    ``options`` (or keyword arguments of :class:`maps.chain.PlanOptions`) set the lattice.
    ``first_design``: returns :func:`maps.trialdesign.first_design` of ``profile`` and these design
    options computed elsewhere (another process), or None to compute it here; it is called once
    the basic moves are built, so the two overlap.
    Returns a Plan; ``feasible`` is False (with ``stats['reason']`` and ``stats['help']``) when
    no plan exists or the re-simulated plan violates the margin.
    """
    t_all = time.perf_counter()
    o = options or PlanOptions(**opts)
    o.check()
    criterion = canonical_criterion(criterion)
    prof = load_profile(profile) if isinstance(profile, str) else profile
    if not isinstance(sea, SeaMap):
        sea = load_map(sea, draught_m=prof.draught_m, ukc_m=o.ukc_m)
    cache: dict[str, Any] = {}
    td: TrialDesign | None = None
    t_design = time.perf_counter()
    if counts is not None:
        prims, counts = _counts_given(prof, counts, primitives)
        lat = build_lattice(sea, prof, prims, counts, start=start, goal=goal, options=o, cache=cache)
    elif scenario is not None:
        if scenario not in SCENARIOS:
            raise MapError(f"--scenario must be one of {', '.join(SCENARIOS)}, got {scenario!r}")
        prims, counts = thesis_planning_scenario(prof)
        lat = build_lattice(sea, prof, prims, counts, start=start, goal=goal, options=o, cache=cache)
    else:
        first = None
        if first_design is not None:
            prepare_basic_moves(sea, prof, o, cache, start=start, goal=goal)
            try:
                first = first_design()
            except TrialTooShort:  # design_for_map sees whether what fits the map needs less time
                first = None
        dkw = dict(criterion=criterion, mean_subtraction=mean_subtraction, trial_length_s=trial_length_s, seed=seed)
        dkw |= dict(first=first, parameter_prior=parameter_prior)

        tried: dict[str, Any] = {}
        apart: dict[str, Needs] = {}  # confined water: manoeuvres the water cannot hold with the rest of the mix

        def design(confined: bool) -> tuple[Any, TrialDesign, bool]:
            return _design_on_map(sea, prof, o, cache, start, goal, primitives, dkw, tried if confined else None, apart)

        for attempt in range(MAX_REDESIGNS + 1):
            try:
                lat, td, switched = design(True)
            except (DesignError, MapError) as exc:  # confined-water settling found no design: today's planning decides
                if not tried:
                    raise
                lat, td = _fallback(design, f"{CONFINED_TRIED}: {exc}", apart)
                if isinstance(exc, TrialTooShort) and td is not None and td.record.get("held_parameters"):
                    lat.notes += longer_trial_note(exc, td.record["held_parameters"])
                break
            if not switched:
                break
            design_s = time.perf_counter() - t_design - lat.setup_s
            plan = solve(lat, design=td.record, vessel_name=vessel_name, t_all=t_all, design_s=design_s)
            if plan.feasible:
                return plan, td
            # the mix may not be sailable together although each manoeuvre fits: redesign without what the
            # best sailable part of it leaves out (maps.sailable)
            left_out = not_sailable_together(lat) if attempt < MAX_REDESIGNS else {}
            if not left_out:
                lat, td = _fallback(design, no_plan_note(plan, left_out is None), apart)
                break
            apart |= left_out
    design_s = time.perf_counter() - t_design - lat.setup_s
    return solve(lat, design=td.record if td else None, vessel_name=vessel_name, t_all=t_all, design_s=design_s), td


def no_plan_note(plan: Plan, undecided: bool) -> str:
    """Why the confined-water attempt ended without a plan (``plan``: its last, infeasible one), for the
    fallback's note; ``undecided``: the search of the sailable mixes stopped at its budget (:data:`UNDECIDED`)."""
    why = f"{CONFINED_TRIED}: no verified plan ({plan.stats.get('reason', '')})"
    return f"{why}; {UNDECIDED.format(n=SAILABLE_STATES)}" if undecided else why


def longer_trial_note(short: TrialTooShort, held: list[dict[str, Any]]) -> list[str]:
    """What would identify the parameters a plan holds when the confined-water design needed a longer
    trial (``short``): its manoeuvres and the trial length they take. The design at that length may
    name manoeuvres the map check has not placed (its check ran on the longer design's), so whether they
    fit and can be sailed together is known only once that trial is planned.
    None (an empty list) when that design held them all too."""
    names = [h["parameter"] for h in held]
    still = [n for n in names if n in short.held]
    gain = [n for n in names if n not in short.held]
    if not short.support or not gain:
        return []
    what = f"{', '.join(gain)} of the held parameters" if still else "every held parameter"
    return [
        f"a longer trial would identify {what} in this water: the confined-water design needs {', '.join(short.support)}, "
        f"one of each takes --trial-length >= {short.need_s:.0f} s"
        + (f" ({', '.join(still)} held still)" if still else "")
        + "; whether they all fit and can be sailed together is known only once that trial is planned"
    ]


def _fallback(
    design: Callable[[bool], tuple[Any, TrialDesign, bool]], why: str, apart: dict[str, Needs] | None = None
) -> tuple[Any, TrialDesign]:
    """Today's lattice and design after the confined-water attempt failed (``why``, one line): a note
    on the plan, or appended to the refusal when today's planning refuses too, so the user sees both.
    ``apart`` (the confined lattice's verdicts) is emptied: today's lattice judges for itself."""
    if apart:
        apart.clear()
    why = " ".join(why.split())  # one line, whatever the reason held
    try:
        lat, td, _ = design(False)
    except (DesignError, MapError) as exc:
        raise type(exc)(f"{exc}; {why}") from exc
    lat.notes.append(why)
    return lat, td


def _design_on_map(
    sea: SeaMap,
    prof: ShipProfile,
    o: PlanOptions,
    cache: dict[str, Any],
    start: LatLonHdg | None,
    goal: LatLonHdg | None,
    primitives: list[Primitive] | None,
    dkw: dict[str, Any],
    confined: dict[str, Any] | None,
    apart: dict[str, Needs] | None = None,
) -> tuple[Any, TrialDesign, bool]:
    """(lattice, design, switched): the design of the ship's library redone without what fits nowhere
    (:func:`maps.trialdesign.design_for_map`). ``confined`` (a dict, or None for today's lattice only): a
    rudder ship whose library does not all fit switches to the confined-water lattice
    (:func:`confined_options`) for the rest, and ``confined["switched"]`` is set (also when the design then fails).
    ``apart``: manoeuvres the confined lattice cannot sail with the rest of an earlier mix, left out there too."""
    built: dict[str, Any] = {"o": o, "cache": cache}

    def fits_nowhere(ps: list[Primitive], cs: dict[str, int]) -> dict[str, tuple[float, float]]:
        lo, lc = built["o"], built["cache"]
        built["lat"] = build_lattice(sea, prof, ps, cs, start=start, goal=goal, options=lo, cache=lc, prefilter=True)
        bad = built["lat"].fits_nowhere()
        if built["o"].settle == "ship" and apart:
            bad |= {p.name: apart[p.name] for p in ps if p.name in apart and p.name not in bad}
        if bad and confined is not None and lo.settle == "lattice" and prof.actuator == "rudder_propeller":
            # its own cache (kept for the redesigns): today's lattice's moves, built already, stay for the fallback
            built["o"], built["cache"] = confined_options(lo, prof, sea), confined.setdefault("cache", {})
            confined["switched"] = True
            return fits_nowhere(ps, cs)
        return bad

    td = design_for_map(prof, fits_nowhere, primitives, **dkw)
    lat = built["lat"]
    lat.notes[:0] = td.notes
    switched = built["o"].settle != o.settle
    if switched:
        lat.notes.append(CONFINED_NOTE.format(res=lat.res))
    return lat, td, switched


def confined_options(o: PlanOptions, prof: ShipProfile, sea: SeaMap) -> PlanOptions:
    """The lattice for confined water: moves settle as a master would (:func:`maps.autopilot.steady_enough`)
    on a lattice of about ``CONFINED_LENGTHS`` ship lengths (unless ``o`` gives a resolution): a finer lattice
    has lattice lines and points nearer wherever a manoeuvre ends, so the settling legs are shorter."""
    res = o.resolution
    if res is None:
        step = prof.cruise_speed_mps * prof.sample_time
        res = min(default_resolution(prof, sea), max(1, round(CONFINED_LENGTHS * prof.length_m / step)) * step)
    return replace(o, settle="ship", resolution=float(res))


def solve(lat, *, design: dict | None = None, vessel_name: str = "", t_all: float | None = None, design_s: float = 0.0) -> Plan:
    """Search, verify and, on a verification failure, re-plan: block the failing placement
    (``replans`` times), then grow the footprints by the clearance deficit."""
    t_all = time.perf_counter() if t_all is None else t_all
    o = lat.options
    extra, blocked = 0.0, frozenset()
    attempts: list[dict[str, Any]] = []
    search_s = expansions = visited = 0
    real = out = None
    for attempt in range(o.replans + 2):
        out = search_plan(lat, extra, blocked)
        r = out.result
        search_s += r.time_s
        expansions += r.expansions
        visited += r.states_visited
        if not r.found:
            break
        real = verify_plan(lat, out)
        ver = real.verification
        attempts.append(
            {"inflation_m": extra, "blocked": len(blocked), "min_clearance_m": ver.min_clearance_m, "search_s": r.time_s}
        )
        if ver.ok or ver.drifted or extra >= MAX_EXTRA_M:  # blocking or growing footprints cannot mend a drift
            break
        leg = real.legs[int(ver.step_of_sample[ver.worst_sample])]
        if leg.move < 0:
            o.smooth = False  # a shortcut broke the margin (it should not): sail the lattice moves (the lattice's own options)
        elif attempt < o.replans:
            blocked = blocked | {(leg.move, leg.spatial)}
        else:
            extra = min(MAX_EXTRA_M, extra + (o.margin - ver.min_clearance_m) + 2.0)
    pb = out.problem
    stats: dict[str, Any] = {
        "expansions": expansions,
        "states_visited": visited,
        "plan_time_s": search_s,
        "heuristic": o.heuristic,
        # the options the lattice does not record, for a resumed trial (maps.resume.plan_options)
        "options": {
            "run_in_s": o.run_in_s,
            "split": o.split,
            "size": list(o.size),
            "max_memory_gib": o.max_memory_gib,
            "settle": o.settle,
        },
        "expansions_per_s": expansions / max(search_s, 1e-9),
        "setup_time_s": lat.setup_s,
        "design_time_s": design_s,
        "lattice": {
            "ni": lat.window.ni,
            "nj": lat.window.nj,
            "headings": len(lat.table),
            "resolution_m": lat.res,
            "x0": lat.window.x0,
            "y0": lat.window.y0,
            "states": lat.n_states(),
        },
        "cost": out.result.cost,
        "basic_cost": o.basic_cost,
        "h_start": out.result.h_start,
        "snap_max_m": lat.snap_max,
        "notes": lat.notes + (unsteady_executes(real.legs) if real is not None and o.settle == "ship" else []),
        "warnings": lat.warnings,
        "start": list(lat.start_ll),
        "goal": list(lat.goal_ll),
        "moves_valid": {m.name: int(sum(ok.sum() for ok, _ in per)) for m, per in zip(lat.moves, lat.placements(out.extra))},
        "attempts": attempts,
        "inflation_m": extra,
        "blocked": len(blocked),
    }
    if not out.found:
        from maps.diagnose import explain_failure

        reason, helps = explain_failure(pb, lat.moves, lat.cnames, out.result)
        if real is not None:  # an earlier plan existed but broke the margin when re-simulated
            reason = f"{real.verification.reason}; re-planned ({len(blocked)} placement(s) blocked, footprints grown by {extra:.0f} m): {reason}"
        stats.update(reason=reason, help=helps, total_time_s=time.perf_counter() - t_all)
        p = lat.profile
        empty = np.zeros((0,))
        return Plan(
            ship=p.name,
            steps=[],
            t=empty,
            track=np.zeros((0, 3)),
            lonlat=np.zeros((0, 2)),
            speed=empty,
            step_of_sample=np.zeros((0,), int),
            inputs=np.zeros((0, len(p.inputs))),
            input_names=list(p.inputs),
            projection=lat.sea.projection_info(),
            feasible=False,
            optimal=False,
            min_clearance_m=float("nan"),
            margin_m=o.margin,
            counts=dict.fromkeys(lat.cnames, 0),
            targets=dict(lat.targets),
            stats=stats,
            map_name=lat.sea.name,
            hull=(p.length_m, p.beam_m),
            design=dict(design or {}),
            vessel_name=vessel_name,
        )
    plan = assemble_plan(lat, out, real, stats, design=design, vessel_name=vessel_name)
    plan.stats["total_time_s"] = time.perf_counter() - t_all
    return plan
