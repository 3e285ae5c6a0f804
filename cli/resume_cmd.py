"""``plan-trial --resume PLAN.json --recordings RUN.csv ... --from LAT,LON,HDG --time-left S``:
re-design and re-plan the rest of a trial from the recordings sailed so far (:mod:`maps.resume`)."""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from datetime import timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Any

from primitives.errors import UserError

if TYPE_CHECKING:  # annotations only: the command imports the library when it runs
    from maps.resume import Position


def resume_conflict(
    resume: Path | None, recordings: list[Path] | None, start_from: str | None, time_left: str | None, **other: object
) -> None:
    """The resume options go together, and without the options that choose a first design."""
    given = {"--recordings": recordings, "--from": start_from, "--time-left": time_left}
    if resume is None:
        extra = [k for k, v in given.items() if v is not None]
        if extra:
            raise UserError(f"{extra[0]}: resumes a trial; give the plan sailed so far with --resume PLAN.json")
        return
    missing = [k for k, v in given.items() if v is None]
    if missing:
        raise UserError(
            f"--resume: also give {' and '.join(missing)} (the recordings sailed, the ship's position and heading, the time left)"
        )
    clash = [f"--{k.replace('_', '-')}" for k, v in other.items() if v is not None]
    if clash and clash[0] in ("--start", "--goal"):
        raise UserError(f"{clash[0]}: a resumed trial starts at --from and keeps the plan's goal: drop {clash[0]}")
    if clash:
        raise UserError(
            f"{clash[0]}: chooses a first design; a resumed trial's design comes from --resume and the recordings: drop {clash[0]}"
        )


def _recording_files(paths: list[Path]) -> list[Path]:
    """The files given, a directory standing for the .csv files in it."""
    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            found = sorted(p.glob("*.csv"))
            if not found:
                raise UserError(f"--recordings {p}: the directory holds no .csv recording")
            out += found
        else:
            out.append(p)
    return out


def _position(text: str) -> Position:
    from cli.plan_inputs import parse_point
    from maps.resume import Position

    pt = parse_point(text, "from")
    if pt is None or pt[2] is None or not all(math.isfinite(v) for v in pt) or not (-90 <= pt[0] <= 90 and -180 <= pt[1] <= 360):
        raise UserError(f"--from: expected LAT,LON,HEADING_DEG (the ship's position now and its heading), got {text!r}")
    return Position(*pt)


def check_out_spares_inputs(out: Path, resume: Path, recordings: list[Path]) -> None:
    """``--out`` is replaced whole (:func:`primitives.io.atomic_output_dir`): refuse one that is
    the resumed plan's directory or holds the plan or a recording, which the swap would delete
    (``--out`` defaults to ``trial-out``, where the first plan was written)."""
    dest = Path(out).resolve()
    for opt, p in [("--resume", Path(resume).resolve().parent), *(("--recordings", Path(r).resolve()) for r in recordings)]:
        if p == dest or dest in p.parents:
            raise UserError(
                f"--out {out}: would replace {opt} {p} (the output directory is replaced whole); give --out a new directory"
            )


def run_resume(
    resume: Path,
    recordings: list[Path],
    start_from: str,
    time_left_text: str,
    *,
    map_path: Path | str | None,
    ship: str | None,
    out: Path,
    start_time: str | None,
    no_export: bool,
    json_out: bool,
    seed: int,
    overrides: dict[str, Any] | None = None,
    vessel_name: str | None = None,
) -> None:
    """Read and check everything first (one line and exit 2 on a bad input, nothing written),
    then re-design, re-plan and write the exports as ``plan-trial`` does. The lattice options
    are the plan's (:func:`maps.resume.plan_options`) but for those given (``overrides``,
    :class:`maps.chain.PlanOptions` fields)."""
    from cli.options import duration_s
    from cli.plan_cmd import _skip_final_collection
    from cli.plan_outputs import stage, write_outputs_all
    from cli.plan_summary import report
    from diagnose.recording import load_recording
    from maps.export._common import iso, resolve_start
    from maps.geo import bundled_map_names, load_map
    from maps.plan import Plan
    from maps.resume import match_recordings, plan_library, plan_options, resume_plan
    from primitives.io import atomic_output_dir, check_replaceable_dir
    from primitives.ship import load_profile

    check_out_spares_inputs(out, resume, recordings)
    check_replaceable_dir(out)
    time_left = duration_s(time_left_text, "--time-left")
    if time_left is None or not time_left > 0:
        raise UserError(f"--time-left {time_left_text!r}: no time left for a manoeuvre; give the seconds left (> 0)")
    pos = _position(start_from)
    plan = Plan.load(resume)
    for note in plan.read_notes:  # on stderr: --json's stdout stays one document
        print(f"note: {note}", file=sys.stderr)
    try:
        prof = load_profile(ship or plan.ship)
    except UserError as exc:
        if ship is not None:
            raise
        raise UserError(
            f"--resume {resume}: the plan is for ship {plan.ship!r}, not a built-in profile: give its profile file with "
            f"--ship PROFILE.toml ({str(exc).splitlines()[0]})"
        ) from None
    prof.require_planar("shiptrial plan --resume")
    if prof.name != plan.ship:
        raise UserError(f"--ship {ship}: the plan {resume} is for {plan.ship}; give that ship's profile")
    recs = []
    for f in _recording_files(recordings):
        pieces = load_recording(f, inputs=prof.inputs)
        if len(pieces) != 1:
            raise UserError(f"{f}: the recording is split by a long gap; give one gap-free recording per manoeuvre")
        recs.append(pieces[0])
    library = plan_library(plan, prof)  # its short forms simulated once
    runs = match_recordings(plan, recs, prof, library)
    opts = replace(plan_options(plan), **(overrides or {}))
    opts.check()
    if map_path is None:
        if plan.map_name not in bundled_map_names():
            raise UserError(f"--map: the plan was made on {plan.map_name!r}, not a bundled map: give its map file with --map")
        map_path = plan.map_name
    sea = load_map(map_path, draught_m=prof.draught_m)
    with stage("re-identifying, re-designing the rest and planning it (A*) ...", json_out):
        result, _ = resume_plan(
            plan, runs, pos, time_left, sea, prof, options=opts, seed=seed, vessel_name=vessel_name, library=library
        )
    if start_time is None and plan.stats.get("start_utc"):  # the rest starts when the last recording ended, not next hour
        start_time = iso(resolve_start(plan, None) + timedelta(seconds=max(float(r.t[-1]) for r in recs)))
    t0 = resolve_start(result, start_time)
    result.stats["start_utc"] = iso(t0)
    with atomic_output_dir(out) as tmp:
        files = write_outputs_all(result, sea, tmp, None, t0, no_export, json_out)
    files = {k: out / Path(v).relative_to(tmp) for k, v in files.items()}
    _skip_final_collection()
    report(result, files, result.stats.get("heuristic", "admissible"), json_out)
