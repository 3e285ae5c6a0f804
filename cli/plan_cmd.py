"""``shiptrial plan`` (= ``plan-trial``): plan a trial on a sea map with the A* lattice planner."""

from __future__ import annotations

import gc
import sys
from collections.abc import Callable
from functools import partial, wraps
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from cli.plan_inputs import (
    DesignArgs,
    DesignChoice,
    LatticeArgs,
    OutputArgs,
    check_lattice_and_outputs,
    parse_counts,
    parse_point,
    plan_inputs,
)
from cli.plan_outputs import export_chart, stage, write_outputs_all
from cli.plan_summary import report

if TYPE_CHECKING:  # annotations only: the command imports the library when it runs
    from cli.drawer import Drawer
    from cli.plan_cache import CacheSlot, Planned
    from maps.chain import LatLonHdg
    from maps.geo import SeaMap
    from maps.plan import Plan
    from maps.planoptions import PlanOptions
    from maps.trialdesign import TrialDesign


def register(app: typer.Typer) -> None:
    @app.command("plan")
    def plan(
        ctx: typer.Context,
        map_path: Path | None = typer.Option(
            None, "--map", help="GeoJSON sea map file, or a bundled map's name: helsinki (default), open-sea"
        ),
        ship: str = typer.Option("full-scale", "--ship", help="built-in profile name or a .toml/.json profile file"),
        start: str | None = typer.Option(None, "--start", help="LAT,LON,HEADING_DEG (default: the map's start feature)"),
        goal: str | None = typer.Option(None, "--goal", help="LAT,LON[,HEADING_DEG] (default: the map's goal feature)"),
        counts: str | None = typer.Option(
            None, "--counts", help="NAME=N,... uses per informative primitive (default: run the design)"
        ),
        scenario: str | None = typer.Option(None, "--scenario", help="a named example instead of the design: thesis-9.4"),
        criterion: str | None = typer.Option(
            None,
            "--criterion",
            help="design criterion: D (= local-D), A, E, bayes-D or maximin-D (as shiptrial design; default D)",
        ),
        prior_spread: float | None = typer.Option(
            None,
            "--prior-spread",
            help="robust criteria: parameters drawn within +-FRACTION of the profile's (0 < FRACTION <= 1)",
        ),
        prior_file: Path | None = typer.Option(
            None, "--prior-file", help="robust criteria: JSON prior (parameter_names with draws or a covariance)"
        ),
        prior_draws: int | None = typer.Option(
            None, "--prior-draws", help="parameter draws of the robust criteria (default 200; a prior file's draws as given)"
        ),
        mean_subtraction: str | None = typer.Option(
            None, "--mean-subtraction", help="none, batchwise (7.53) or complete (7.57) (default complete)"
        ),
        trial_length_text: str | None = typer.Option(
            None,
            "--trial-length",
            help="trial length the design is rounded to: seconds, "
            "or with a unit s, min or h (1800, 30min, 0.5h; default: "
            "every library primitive once)",
        ),
        resolution: float | None = typer.Option(None, "--resolution", help="lattice spacing in metres (default ~4 ship lengths)"),
        headings: int = typer.Option(16, "--headings", help="lattice headings: 4, 8 or 16"),
        heuristic: str = typer.Option("admissible", "--heuristic", help="admissible (certified optimal) or thesis (8.9)"),
        margin: float = typer.Option(20.0, "--margin", help="safety margin around the swept hull, metres"),
        run_in: float | None = typer.Option(
            None,
            "--run-in",
            help="seconds on steady course and speed before each execute point (default: max(60 s, two ship lengths))",
        ),
        max_memory: float = typer.Option(2.0, "--max-memory", help="refuse a lattice estimated to need more GiB than this"),
        split: bool = typer.Option(False, "--split", help="split primitives at their natural break points"),
        size: str = typer.Option("35x44", "--size", help="minimum lattice size NORTHxEAST points"),
        vessel_name: str | None = typer.Option(
            None, "--vessel-name", help="vessel name for the exports (default: the profile's name)"
        ),
        out: Path = typer.Option(Path("trial-out"), "--out", help="directory for the plan, the crew exports and the figures"),
        start_time: str | None = typer.Option(
            None,
            "--start-time",
            help="UTC start of the trial for the schedule, e.g. 2026-06-01T08:00Z (default: the next full hour)",
        ),
        no_export: bool = typer.Option(False, "--no-export", help="write only plan.json, trajectory.geojson and plan.png"),
        no_cache: bool = typer.Option(
            False,
            "--no-cache",
            help="plan afresh, neither reading nor writing the plan cache "
            "($SHIPTRIAL_CACHE_DIR, default ~/.cache/shiptrial/plans); the ship's lattice moves, its simulated library, its "
            "first design (keyed by the design options) with its ratios figure and the projected map kept there are still "
            "read and written, as compiled code is (SHIPTRIAL_CACHE_DIR='' for no cache at all)",
        ),
        json_out: bool = typer.Option(False, "--json", help="print one JSON summary"),
        seed: int = typer.Option(0, "--seed", help="seed of the experiment design"),
        resume: Path | None = typer.Option(
            None,
            "--resume",
            help="re-design the rest of the trial planned in this plan.json (with --recordings, --from, --time-left)",
        ),
        recordings: list[Path] | None = typer.Option(
            None, "--recordings", help="recording (CSV) of a manoeuvre sailed, or a directory of them; repeat for each"
        ),
        start_from: str | None = typer.Option(
            None, "--from", help="resume: the ship's position and heading now, LAT,LON,HEADING_DEG"
        ),
        time_left: str | None = typer.Option(
            None, "--time-left", help="resume: manoeuvring time left, seconds or with a unit s, min or h (transits come on top)"
        ),
    ) -> None:
        """Plan a trial: design -> whole manoeuvres -> A* planning -> continuous verification -> exports for the crew."""
        from cli.resume_cmd import resume_conflict

        resume_conflict(
            resume,
            recordings,
            start_from,
            time_left,
            counts=counts,
            scenario=scenario,
            criterion=criterion,
            trial_length=trial_length_text,
            prior_spread=prior_spread,
            prior_file=prior_file,
            prior_draws=prior_draws,
            mean_subtraction=mean_subtraction,
            start=start,
            goal=goal,
        )
        lattice = LatticeArgs(
            resolution=resolution,
            headings=headings,
            heuristic=heuristic,
            margin=margin,
            split=split,
            size=size,
            run_in=run_in,
            max_memory=max_memory,
        )
        outputs = OutputArgs(out=out, seed=seed, vessel_name=vessel_name, start_time=start_time, no_export=no_export)
        if resume is not None:
            resumed = (resume, recordings or [], start_from or "", time_left or "")
            _resume(ctx, resumed, map_path, ship, lattice, outputs, json_out)
            return
        given = DesignArgs(
            criterion=criterion,
            mean_subtraction=mean_subtraction,
            trial_length=trial_length_text,
            prior_spread=prior_spread,
            prior_file=prior_file,
            prior_draws=prior_draws,
        )
        opts, design = plan_inputs(ship, start, goal, counts, scenario, given, lattice, outputs)
        files, result, cached = plan_and_write(
            ship,
            map_path,
            opts,
            design,
            counts=parse_counts(counts),
            scenario=scenario,
            start=parse_point(start, "start"),
            goal=parse_point(goal, "goal"),
            vessel_name=vessel_name,
            out=out,
            start_time=start_time,
            no_export=no_export,
            json_out=json_out,
            cache=not no_cache,
        )
        _skip_final_collection()
        report(result, files, heuristic, json_out, cached=cached)


def _resume(
    ctx: typer.Context,
    resumed: tuple[Path, list[Path], str, str],
    map_path: Path | None,
    ship: str,
    lattice: LatticeArgs,
    outputs: OutputArgs,
    json_out: bool,
) -> None:
    """``plan --resume`` (:func:`cli.resume_cmd.run_resume`; ``resumed``: the plan file, the recordings, --from,
    --time-left): the lattice options given override the plan's; those left at their defaults keep the plan's."""
    from cli.resume_cmd import run_resume

    check_lattice_and_outputs(lattice, outputs, start=None, goal=None, counts=None)
    # by name: typer's vendored click has its own ParameterSource
    given = {k for k in ctx.params if getattr(ctx.get_parameter_source(k), "name", "DEFAULT") != "DEFAULT"}
    values = dict(lattice.items(), size=lattice.size_points())  # size checked by validate_plan_options
    fields = {"run_in": "run_in_s", "max_memory": "max_memory_gib"}  # parameter -> PlanOptions field
    run_resume(
        *resumed,
        map_path=map_path,
        ship=ship if "ship" in given else None,
        json_out=json_out,
        overrides={fields.get(k, k): v for k, v in values.items() if k in given},
        out=outputs.out,
        seed=outputs.seed,
        vessel_name=outputs.vessel_name,
        start_time=outputs.start_time,
        no_export=outputs.no_export,
    )


def _heap_frozen(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Run ``fn`` with what is alive when it starts (the command's imports: some 45k objects) out of
    the collector's sight (``gc.freeze``): planning makes garbage enough for a full collection or
    two, each of which would walk every imported object again (0.045-0.13 s of CPU at the head of a
    ``plan-trial --no-cache``, measured under load; none with it). Given back after (``gc.unfreeze``),
    so that an in-process caller's collector is as it was; not done when the caller froze objects
    itself (unfreezing would give back its objects too)."""

    @wraps(fn)
    def run(*args: Any, **kwargs: Any) -> Any:
        if gc.get_freeze_count():
            return fn(*args, **kwargs)
        gc.freeze()
        try:
            return fn(*args, **kwargs)
        finally:
            gc.unfreeze()

    return run


@_heap_frozen
def plan_and_write(
    ship: str,
    map_path: Path | None,
    opts: PlanOptions,
    design: DesignChoice,
    *,
    counts: dict[str, int] | None,
    scenario: str | None,
    start: LatLonHdg | None,
    goal: LatLonHdg | None,
    vessel_name: str | None,
    out: Path,
    start_time: str | None,
    no_export: bool,
    json_out: bool,
    cache: bool = True,
) -> tuple[dict[str, Path], Plan, bool]:
    """Plan (``design``: :class:`cli.plan_inputs.DesignChoice`) and write every
    output into ``out``; returns the files (paths in ``out``), the plan and whether the design
    and plan were read from the plan cache (:mod:`maps.plancache`; ``cache=False``: neither read
    nor written). The figures are drawn by a :class:`cli.drawer.Drawer`, the one ``plan-trial``
    forked before parsing its options (:func:`cli.drawer.start_early`) or one started here: it
    imports the drawing modules and, on a cache miss, designs on the other core while this process
    reads the cache or plans; a NoFitError is the command's exit 1."""
    from cli import plan_early
    from cli.drawer import take_early
    from cli.plan_cache import cache_slot, read_cached
    from maps.trialdesign import NoFitError
    from primitives.ship import load_profile

    prof = load_profile(ship)
    prof.require_planar("shiptrial plan")
    inputs = dict(
        counts=counts, start=start, goal=goal, scenario=scenario, **design.kwargs(), vessel_name=vessel_name or "", options=opts
    )
    slot = cache_slot(prof, map_path, inputs, cache)
    planned = read_cached(slot, start_time, no_export)
    early = None
    if planned is None and counts is None and scenario is None:  # the drawer designs while this process builds the basic moves
        early = partial(plan_early.early_design, ship, **design.kwargs())
    ahead = partial(plan_early.ratios_ahead, ship) if early is not None else None
    cached, drawer = planned is not None, None
    try:  # the drawer is ended in `finally` whatever is raised from here on (a Ctrl-C in begin() included)
        drawer = take_early()  # started with the command (plan-trial): the drawing modules imported already, or importing
        drawer = _drawer(drawer, early, ahead, planned, no_export)
        if planned is None:
            planned = _plan_here(map_path, prof, inputs, drawer, slot, start_time, no_export, json_out)
        files = _write_outputs(planned, out, slot, drawer, start_time, no_export, json_out)
    except NoFitError as exc:
        print(f"error: {str(exc).splitlines()[0]}", file=sys.stderr)
        raise typer.Exit(1) from None
    finally:
        if drawer is not None:
            drawer.cancel()  # a no-op once it has drawn; ends it at once when the command failed before
    return files, planned.result, cached


def _drawer(
    early_drawer: Drawer | None, early: Callable | None, ahead: Callable | None, planned: Planned | None, no_export: bool
) -> Drawer | None:
    """The drawer of this run: the one forked with the command (``early_drawer``, cancelled when
    there is nothing to draw), else one started here; None when nothing is drawn."""
    from cli.drawer import Drawer
    from maps import plancache

    saved = planned.saved if planned is not None else None
    if early_drawer is not None and (no_export or saved is not None):
        early_drawer.cancel()
        return None
    if early_drawer is not None:  # the PNGs kept for another start time: the drawer writes the trial cards only
        early_drawer.begin(early, ahead, cards_only=planned is not None and planned.figures is not None)
        return early_drawer
    if no_export or saved is not None:
        return None
    if planned is None:  # planned here: the drawer forked after the planner's imports shares them (start_early)
        import maps.planner  # noqa: F401

        if plancache.default_dir() is not None:
            # hashed once, before the fork: the map's key here and the drawer's library and design keys both
            # need it (0.045-0.066 s of CPU each, docs/kernel-speed.md Stop 57; with the plan cache on, the
            # plan's key hashed it already)
            plancache.code_version()
    return Drawer(early, ahead=ahead)


def _plan_here(
    map_path: Path | None,
    prof: Any,
    inputs: dict[str, Any],
    drawer: Drawer | None,
    slot: CacheSlot,
    start_time: str | None,
    no_export: bool,
    quiet: bool,
) -> Planned:
    """Design and plan on the map (a cache miss), kept in the plan cache when ``slot`` has a key."""
    from cli.plan_cache import Planned, map_digest
    from maps import plancache
    from maps.export._common import resolve_start
    from maps.mapcache import load_map_kept

    sea = load_map_kept(map_path, draught_m=prof.draught_m)  # the projected map kept as the moves are
    result, td = _plan(sea, prof, inputs, drawer, quiet)
    # the export chart, route and sea room now, before the start time is set: kept with the plan in the cache
    chart = export_chart(result, sea) if result.feasible and not no_export else None
    digest = None
    # kept only when the map file still holds the bytes keyed (read again: about 1 ms): one saved while this
    # run loaded it would leave the saved file's plan under the earlier bytes' key (as maps.mapcache does)
    if slot.key is not None and map_digest(map_path) == slot.map_digest:
        digest = plancache.store(slot.dir, slot.key, {"plan": result, "design": td, "sea": sea, "chart": chart})
    return Planned(result, td, sea, chart, digest, resolve_start(result, start_time))


def _write_outputs(
    planned: Planned,
    out: Path,
    slot: CacheSlot,
    drawer: Drawer | None,
    start_time: str | None,
    no_export: bool,
    json_out: bool,
) -> dict[str, Path]:
    """Every output into ``out`` at once (:func:`primitives.io.atomic_output_dir`): restored from the
    cache when kept for this plan and start time, else written (and kept); returns the files' paths."""
    from cli.plan_cache import keep_outputs, note_kept, restore_outputs
    from maps.export._common import iso
    from primitives.io import atomic_output_dir

    result, t0 = planned.result, planned.t0
    start_utc = result.stats["start_utc"] = iso(t0)  # saved in plan.json: re-exports give the same schedule
    with atomic_output_dir(out) as tmp:
        if planned.saved is not None:
            files, kept = restore_outputs(planned.saved, tmp), True
        else:
            td, sea, chart = planned.design, planned.sea, planned.chart
            files = write_outputs_all(result, sea, tmp, td, t0, no_export, json_out, drawer, chart, planned.figures)
            kept = result.feasible and not no_export and keep_outputs(slot.dir, slot.key, planned.digest, start_utc, files, tmp)
    note_kept(slot.dir, kept, None if start_time else t0)
    return {k: out / Path(v).relative_to(tmp) for k, v in files.items()}


def _plan(sea: SeaMap, prof: Any, inputs: dict[str, Any], drawer: Drawer | None, quiet: bool) -> tuple[Plan, TrialDesign | None]:
    """Design and plan (:func:`maps.planner.plan_with_design`), the first design taken from the drawer."""
    from maps.planner import plan_with_design

    with stage("designing the manoeuvre mix and planning on the lattice (A*) ...", quiet):
        return plan_with_design(sea, profile=prof, **inputs, first_design=drawer.early if drawer is not None else None)


def _skip_final_collection() -> None:
    """Every output is written and closed: at interpreter exit, before its final garbage
    collection, move every object to the permanent generation (``gc.freeze``), since that
    collection would only walk everything the command made for the process to end (0.043 s CPU
    at the end of ``plan-trial``, 67k objects). Registered once; called in-process (a test),
    it runs when that process ends."""
    import atexit
    import gc

    atexit.unregister(gc.freeze)
    atexit.register(gc.freeze)
