"""Resume a trial: the plan sailed so far, its recordings, a new plan for the rest.

The loop a notebook drives step by step (each a pure function over dataclasses; reading files
is the CLI's, :mod:`cli.resume_cmd`):

1. :func:`match_recordings`: each recording to the plan's informative step it belongs to (the
   recording's ``# ship:`` and ``# manoeuvre:`` header lines, optionally ``# step: N`` as numbered
   on the trial card, its time stamps on the plan's clock); a mismatch is a :class:`ResumeError`;
2. :func:`expdesign.adaptive.redesign`: re-identify, count the information sailed (7.58),
   design the rest for the time left;
3. :func:`resume_plan`: the rest planned from the ship's present position with the planner
   (:func:`maps.planner.plan_with_design` with the re-designed counts), the sailed part carried in
   ``plan.stats['resume']`` for the exports (the plan JSON, the GeoJSON's ``sailed`` line, the card).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from diagnose.recording import Recording
from expdesign.adaptive import Redesign, SailedRun, redesign
from expdesign.dopt import ROBUST
from maps.chain import PlanOptions, build_lattice
from maps.geo import SeaMap
from maps.lattice import SETTLE_PHASES
from maps.plan import Plan, PlanStep
from maps.planner import plan_with_design
from maps.searoom import held_text
from maps.sizing import Needs, water_text
from maps.trialdesign import ship_library
from primitives.errors import UserError
from primitives.library import Primitive
from primitives.profile_tables import names_ship
from primitives.ship import ShipProfile
from primitives.sized import named_short_forms

# A crew runs late or early by more with every hour, not by a quarter of an hour from one
# manoeuvre to the next: a recording without '# step:' starts within this many seconds of its
# step's planned start shifted by the previous recording's lateness (the trial's start for the first).
TIME_TOLERANCE_S = 900.0
MIN_COVER = 0.8  # a recording covers at least this share of its manoeuvre's duration
MAX_COVER = 1.5  # and no more than this: beyond, it holds the next transit or manoeuvre, not modelled as this step


class ResumeError(UserError):
    """A recording, position or time that does not fit the plan being resumed (exit 2)."""


@dataclass
class Position:
    """The ship's present position and heading (degrees from north, clockwise)."""

    lat: float
    lon: float
    heading_deg: float


def plan_library(plan: Plan, profile: ShipProfile) -> list[Primitive]:
    """The manoeuvres the plan's design chose from and can still choose from: its ``design``
    record's ``weights``, ``counts`` and ``not_used`` (the library it ran on, the dropped ones not in them),
    each from the ship's library or its short forms (:mod:`primitives.sized`, a plan for confined
    water). A plan whose record lists neither (counts given, no design): the ship's library without what it dropped."""
    design = plan.design or {}
    dropped = {d["primitive"] for d in design.get("dropped") or []}
    listed = [*(design.get("weights") or {}), *(design.get("counts") or {}), *(design.get("not_used") or [])]
    names = [n for n in dict.fromkeys(listed) if n not in dropped]
    lib = ship_library(profile)
    if not (design.get("weights") or design.get("not_used")):  # no design ran (counts given): the whole library
        return [p for p in lib if p.name not in dropped]
    by = {p.name: p for p in lib}
    short = named_short_forms(profile, [n for n in names if n not in by])
    by |= {p.name: p for p in short}
    missing = [n for n in names if n not in by]
    if missing:
        raise ResumeError(
            f"the plan's design lists {', '.join(missing)}, no manoeuvre of {profile.name}'s library or its short forms: "
            "resume a plan made for this ship's profile (its design field 'weights'/'not_used')"
        )
    return [by[n] for n in names]


def _header(rec: Recording, key: str) -> str:
    v = rec.meta.get(key)
    if not v:
        raise ResumeError(
            f"{rec.source}: header line '# {key}: ...' is missing; a resumed trial matches each recording to its plan "
            f"step by '# ship:', '# manoeuvre:' (the design code on the trial card) and its time on the plan's clock"
        )
    return v


def _numbered_step(plan: Plan, rec: Recording, manoeuvre: str) -> PlanStep:
    """The informative step a recording's ``# step: N`` names (card numbering; the run-in's
    number names its manoeuvre too)."""
    try:
        n = int(rec.meta["step"])
    except ValueError:
        n = -1
    if not 1 <= n <= len(plan.steps):
        raise ResumeError(
            f"{rec.source}: header '# step: {rec.meta['step']}' must be a step number 1..{len(plan.steps)} of the plan"
        )
    named = plan.steps[n - 1]
    if named.segment == "run-in" and n < len(plan.steps):
        named = plan.steps[n]
    if named.segment != "informative" or named.primitive != manoeuvre:
        raise ResumeError(
            f"{rec.source}: header '# manoeuvre: {manoeuvre}' but step {n} of the plan sails "
            f"{plan.steps[n - 1].primitive}: fix the header or give the recording of that step"
        )
    return named


def _next_step_of(plan: Plan, rec: Recording, manoeuvre: str, taken: dict[int, SailedRun]) -> PlanStep:
    """Without ``# step:``: the first step of that manoeuvre with no recording yet (the
    recordings taken in time order: a ship sails its steps in the plan's order)."""
    informative = [s for s in plan.steps if s.segment == "informative"]
    cand = [s for s in informative if s.primitive == manoeuvre]
    if not cand:
        raise ResumeError(
            f"{rec.source}: header '# manoeuvre: {manoeuvre}' names no manoeuvre of the plan "
            f"(its design codes: {', '.join(sorted({s.primitive for s in informative}))})"
        )
    free = [s for s in cand if s.index not in taken]
    if not free:
        prev = taken[cand[-1].index]
        raise ResumeError(
            f"{rec.source}: step {cand[-1].index + 1} ({manoeuvre}) has a recording already ({prev.source}), and the "
            f"plan sails {manoeuvre} {len(cand)} time(s): add '# step: N' (the card's number) to say which step it is"
        )
    return free[0]


def _check_times(plan: Plan, matched: list[tuple[Recording, PlanStep]]) -> None:
    """In the plan's order the recordings start later and later without overlapping; one
    without ``# step:`` is also no more than :data:`TIME_TOLERANCE_S` off its planned start
    shifted by the lateness of the recording before it (a common schedule offset, not a fixed window)."""
    late, prev = 0.0, None
    for rec, step in sorted(matched, key=lambda m: m[1].index):
        t0 = float(rec.t[0])
        if prev is not None and t0 < float(prev[0].t[-1]):
            raise ResumeError(
                f"{rec.source}: starts at t = {t0:.0f} s, before {prev[0].source} (step {prev[1].index + 1}, which the "
                f"plan sails before step {step.index + 1}) ends at {float(prev[0].t[-1]):.0f} s: column 't' must be "
                "seconds from the trial's start, on the plan's clock"
            )
        if "step" not in rec.meta and abs(t0 - step.start_time_s - late) > TIME_TOLERANCE_S:
            raise ResumeError(
                f"{rec.source}: starts at t = {t0:.0f} s but step {step.index + 1} ({step.primitive}) was planned at "
                f"{step.start_time_s:.0f} s, {late:+.0f} s late as the recording before it (more than "
                f"{TIME_TOLERANCE_S:.0f} s apart): column 't' must be seconds from the trial's start, on the plan's "
                "clock; add '# step: N' when the schedule slipped"
            )
        late, prev = t0 - step.start_time_s, (rec, step)


def match_recordings(
    plan: Plan, recordings: list[Recording], profile: ShipProfile, library: list[Primitive] | None = None
) -> list[SailedRun]:
    """Each recording as the :class:`SailedRun` of its plan step, in sailing order: the step its
    ``# step: N`` names, else (in time order) the next step of its manoeuvre without a recording.
    Refused in one line: another ship, a manoeuvre the plan does not sail (there), recordings out
    of the plan's order or overlapping, a start without ``# step:`` off its step's time by more
    than :data:`TIME_TOLERANCE_S` beyond the schedule's slip so far, a recording shorter than
    :data:`MIN_COVER` or longer than :data:`MAX_COVER` of its step, two recordings of one step.
    ``library``: :func:`plan_library` of the plan, made already."""
    runs: dict[int, SailedRun] = {}
    matched: list[tuple[Recording, PlanStep]] = []
    lib = library if library is not None else plan_library(plan, profile)
    durations = {p.name: p.duration_s for p in [*ship_library(profile), *lib]}  # short forms too
    numbered = sorted(recordings, key=lambda r: ("step" not in r.meta, float(r.t[0])))  # named steps first
    for rec in numbered:
        ship = _header(rec, "ship")
        if not names_ship(ship, plan.ship, profile.vessel):  # diagnose's and mass's rule: case and punctuation aside
            raise ResumeError(
                f"{rec.source}: header '# ship: {ship}' but the plan is for {plan.ship}: give that ship's recordings"
            )
        man = _header(rec, "manoeuvre")
        step = _numbered_step(plan, rec, man) if "step" in rec.meta else _next_step_of(plan, rec, man, runs)
        need = durations.get(man, step.duration_s)
        if rec.duration_s < MIN_COVER * need:
            raise ResumeError(
                f"{rec.source}: lasts {rec.duration_s:.0f} s but the manoeuvre of step {step.index + 1} ({man}) lasts "
                f"{need:.0f} s: give the recording of the whole manoeuvre"
            )
        if rec.duration_s > MAX_COVER * need:
            raise ResumeError(
                f"{rec.source}: lasts {rec.duration_s:.0f} s but the manoeuvre of step {step.index + 1} ({man}) lasts "
                f"{need:.0f} s: trim the recording to the manoeuvre (it holds what was sailed after it)"
            )
        if step.index in runs:
            raise ResumeError(f"{rec.source}: step {step.index + 1} ({man}) has a recording already ({runs[step.index].source})")
        if abs(rec.sample_time - profile.sample_time) > 1e-6 * profile.sample_time:
            raise ResumeError(
                f"{rec.source}: sampled every {rec.sample_time:g} s; {profile.name} is identified at {profile.sample_time:g} s"
            )
        u = rec.inputs_for(profile.inputs)
        runs[step.index] = SailedRun(step.index, man, u[:-1], rec.y, rec.psi, rec.source)
        matched.append((rec, step))
    _check_times(plan, matched)
    return [runs[k] for k in sorted(runs)]


def check_position(sea: SeaMap, pos: Position, margin_m: float) -> None:
    """The ship's present position is on the map and in navigable water (``SeaMap.locate``)."""
    if not all(math.isfinite(v) for v in (pos.lat, pos.lon, pos.heading_deg)):
        raise ResumeError(f"--from: latitude, longitude and heading must be finite numbers, got {pos}")
    sea.locate(pos.lat, pos.lon, "--from", margin_m)


def sailed_part(plan: Plan, runs: list[SailedRun], sample_time: float) -> dict[str, Any]:
    """What the resumed plan shows of the trial sailed: the steps up to the last one recorded,
    the planned track of them (lon, lat), their recordings and the time they took."""
    last = max(r.step for r in runs)
    rec = {r.step: r.source for r in runs}
    keep = plan.step_of_sample <= last
    return {
        "steps": [
            {
                "step": s.index + 1,
                "primitive": s.primitive,
                "segment": s.segment,
                "start_time_s": s.start_time_s,
                "duration_s": s.duration_s,
                **({"recording": rec[s.index]} if s.index in rec else {}),
            }
            for s in plan.steps[: last + 1]
        ],
        "lonlat": plan.lonlat[keep].tolist(),
        "sailed_s": float(plan.steps[last].start_time_s + plan.steps[last].duration_s),
        "recorded_s": float(sum(r.n_samples for r in runs) * sample_time),
    }


def earlier_runs(plan: Plan) -> list[SailedRun]:
    """The runs a resumed ``plan`` counted already (``stats['resume']['runs']``: the recordings
    of every plan before it), for the next resume to count them too: re-planning step by step
    (7.58) keeps all the information sailed, not only the latest part's."""
    out = []
    for d in (plan.stats.get("resume") or {}).get("runs") or []:
        inputs = np.asarray(d["inputs"], float)
        y, psi = np.asarray(d["y"], float), np.asarray(d["psi"], float)
        out.append(SailedRun(int(d["step"]), str(d["primitive"]), inputs, y, psi, str(d.get("source", ""))))
    return out


def _run_record(r: SailedRun) -> dict[str, Any]:
    return {
        "step": r.step,
        "primitive": r.primitive,
        "source": r.source,
        "inputs": r.inputs.tolist(),
        "y": r.y.tolist(),
        "psi": r.psi.tolist(),
    }


def plan_options(plan: Plan) -> PlanOptions:
    """The lattice and search options the plan was made with (as far as it records them: a plan
    made before ``stats['options']`` keeps the defaults of those)."""
    lat = plan.stats.get("lattice") or {}
    rec = plan.stats.get("options") or {}
    kw: dict[str, Any] = {"margin": plan.margin_m}
    if lat.get("resolution_m"):
        kw["resolution"] = float(lat["resolution_m"])
    if lat.get("headings") in (4, 8, 16):
        kw["headings"] = int(lat["headings"])
    if plan.stats.get("heuristic") in ("admissible", "thesis"):
        kw["heuristic"] = plan.stats["heuristic"]
    if "run_in_s" in rec:
        kw["run_in_s"] = None if rec["run_in_s"] is None else float(rec["run_in_s"])
    if "split" in rec:
        kw["split"] = bool(rec["split"])
    if rec.get("size"):
        kw["size"] = tuple(int(v) for v in rec["size"])
    if rec.get("max_memory_gib"):
        kw["max_memory_gib"] = float(rec["max_memory_gib"])
    if rec.get("settle") in SETTLE_PHASES:
        kw["settle"] = rec["settle"]
    return PlanOptions(**kw)


def _resume_notes(design: dict[str, Any], held_rows: list[dict[str, Any]]) -> list[str]:
    """What the resumed plan's notes say it kept of the plan resumed: the parameters held, and a
    criterion other than D replaced by D (a robust one: at the re-identified parameters)."""
    notes = []
    if held_rows:
        notes.append(
            f"the rest holds {len(held_rows)} parameter(s) at the profile's values, as the plan resumed did: {held_text(held_rows)}"
        )
    crit = design.get("criterion", "D")
    if crit in ROBUST:
        notes.append(
            f"the plan resumed was designed {crit} over its prior; the rest is re-designed D-optimal at the re-identified "
            "parameters, the recordings sailed standing in for the prior"
        )
    elif crit != "D":
        notes.append(f"the plan resumed was designed {crit}-optimal; the rest is re-designed D-optimal (7.58)")
    return notes


def _fit_from_here(
    rd: Redesign,
    library: list[Primitive],
    runs: list[SailedRun],
    time_left_s: float,
    sea: SeaMap,
    profile: ShipProfile,
    o: PlanOptions,
    start: tuple[float, float, float],
    goal: tuple[Any, ...] | None,
    ms: str,
    seed: int,
    held: list[str],
) -> tuple[Redesign, list[Primitive], dict[str, tuple[float, float]]]:
    """The re-design redone without what its mix needs but fits nowhere reachable from the ship's
    position (a manoeuvre the first design did not choose was never checked against the map, as
    :func:`maps.trialdesign.design_for_map` checks only the support), the re-identification kept."""
    cache: dict[str, Any] = {}
    nowhere: dict[str, tuple[float, float]] = {}
    while True:
        support = [p for p in library if rd.counts.get(p.name)]
        lat = build_lattice(sea, profile, support, rd.counts, start=start, goal=goal, options=o, cache=cache, prefilter=True)
        bad = lat.fits_nowhere()
        if not bad:
            return rd, library, nowhere
        nowhere |= bad
        library = [p for p in library if p.name not in bad]
        if not library:
            raise ResumeError(
                f"--from: none of the plan's manoeuvres has a placement in the water reachable from there: "
                f"{'; '.join(water_text(n, v) for n, v in nowhere.items())}; the rest cannot be sailed from that position "
                "(sail to more open water first, or end the trial)"
            )
        rd = redesign(profile, library, runs, time_left_s, mean_subtraction=ms, seed=seed, reid=rd.reid, held=held)


def resume_plan(
    plan: Plan,
    runs: list[SailedRun],
    position: Position,
    time_left_s: float,
    sea: SeaMap,
    profile: ShipProfile,
    *,
    options: PlanOptions | None = None,
    mean_subtraction: str | None = None,
    seed: int = 0,
    vessel_name: str | None = None,
    library: list[Primitive] | None = None,
) -> tuple[Plan, Redesign]:
    """Re-identify from ``runs``, re-design the rest for ``time_left_s`` seconds of manoeuvres
    counting what was sailed (7.58), plan it from ``position`` to the plan's goal; the new plan
    carries the sailed part (:func:`sailed_part`) and the re-identification in ``stats['resume']``.
    The rest is designed over the plan's own library (:func:`plan_library`, made already when
    ``library`` is given: its short forms in confined water) with the parameters it held held."""
    o = options or plan_options(plan)
    check_position(sea, position, o.margin)
    ms = mean_subtraction or (plan.design or {}).get("mean_subtraction") or "complete"
    design = plan.design or {}
    # what the first plan dropped for fitting nowhere on this map fits nowhere now either; what it
    # held, the water cannot identify now either
    dropped = {d["primitive"] for d in design.get("dropped") or []}
    library = library if library is not None else plan_library(plan, profile)
    held_rows = list(design.get("held_parameters") or [])
    before = earlier_runs(plan)
    held = [h["parameter"] for h in held_rows]
    rd = redesign(profile, library, before + runs, time_left_s, mean_subtraction=ms, seed=seed, held=held)
    goal = plan.stats.get("goal")
    start, goal = (position.lat, position.lon, position.heading_deg), tuple(goal) if goal else None
    rd, library, nowhere = _fit_from_here(rd, library, before + runs, time_left_s, sea, profile, o, start, goal, ms, seed, held)
    rd.notes += _resume_notes(design, held_rows)
    if nowhere:
        rd.notes.append(
            f"the rest also leaves out {', '.join(nowhere)}, which the first design did not choose and which fits nowhere "
            f"reachable from the ship's position: {'; '.join(water_text(n, v) for n, v in nowhere.items())}"
        )
    if held_rows:
        rd.record["held_parameters"] = held_rows
    if design.get("criterion", "D") != "D":
        rd.record["first_criterion"] = design["criterion"]
    first_dropped = list(design["dropped"]) if dropped else []
    if dropped:
        why = "fits nowhere on the map" + (
            ", or not with the rest of the mix" if any(d.get("apart") for d in first_dropped) else ""
        )
        rd.notes.append(f"the rest leaves out {', '.join(sorted(dropped))}, as the first plan did ({why})")
    # a next resume leaves these out too
    rd.record["dropped"] = first_dropped + [
        {"primitive": n, "needs_m": [float(v[0]), float(v[1])]} | (v.record() if isinstance(v, Needs) else {})
        for n, v in nowhere.items()
    ]
    new, _ = plan_with_design(
        sea,
        profile=profile,
        counts=rd.counts,
        primitives=library,  # the short forms among them
        start=start,
        goal=goal,
        options=o,
        vessel_name=vessel_name or plan.vessel_name,
    )
    new.design = rd.record
    new.stats["notes"] = list(rd.notes) + list(new.stats.get("notes", []))
    new.stats["warnings"] = list(new.stats.get("warnings", [])) + rd.reid.disagrees
    sailed = sailed_part(plan, runs, profile.sample_time)
    sailed["lonlat"] = ((plan.stats.get("resume") or {}).get("sailed") or {}).get("lonlat", []) + sailed["lonlat"]
    new.stats["resume"] = {
        "position": [position.lat, position.lon, position.heading_deg],
        "time_left_s": float(time_left_s),
        "sailed": sailed,
        # every run counted, this plan's and the plans' before it (step numbers on each one's own card)
        "runs": [_run_record(r) for r in before + runs],
        "earlier_runs": len(before),
        # log det of M_sailed alone (None: singular, the runs sailed cannot identify every parameter) and of the whole trial
        "logdet_sailed": rd.logdet_sailed if math.isfinite(rd.logdet_sailed) else None,
        "logdet_total": rd.logdet_total if math.isfinite(rd.logdet_total) else None,
        "disagrees": rd.reid.disagrees,
        "previous_start_utc": plan.stats.get("start_utc"),
    }
    return new, rd


def simulated_recordings(
    plan: Plan, profile: ShipProfile, steps: list[PlanStep], theta: np.ndarray, noise_std: tuple[float, float, float], seed: int
) -> list[Recording]:
    """Recordings of the informative ``steps`` as a ship with model parameters ``theta`` (the
    profile's structure) would sail them, white noise of ``noise_std`` on u, v, r, with the
    header lines :func:`match_recordings` reads: for examples, tests and benchmarks (write them
    with :func:`diagnose.recording.write_csv`)."""
    from primitives.simulate import simulate

    lib = {p.name: p for p in plan_library(plan, profile)}
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(28, 7)))
    out = []
    for s in steps:
        p = lib[s.primitive]
        res = simulate(profile, p.inputs, np.asarray(theta, float), nu0=p.nu0, eta0=(s.entry_x, s.entry_y, s.entry_psi))
        n = p.n_samples
        y = res.nu[0] + rng.standard_normal((n + 1, 3)) * np.asarray(noise_std, float)
        u = np.vstack([p.inputs, p.inputs[-1:]])
        out.append(
            Recording(
                source=f"step{s.index + 1:02d}-{s.primitive}.csv",
                t=s.start_time_s + profile.sample_time * np.arange(n + 1),
                y=y,
                psi=res.eta[0, :, 2],
                pos=res.eta[0, :, :2],
                channels={name: u[:, i] for i, name in enumerate(profile.inputs)},
                meta={
                    "ship": plan.ship,
                    "manoeuvre": s.primitive,
                    "step": str(s.index + 1),
                    "sample_time": f"{profile.sample_time:g}",
                },
            )
        )
    return out
