"""``shiptrial plan`` (= ``plan-trial``): plan a trial on a sea map with the A* lattice planner."""

from __future__ import annotations

import sys
from contextlib import contextmanager
from pathlib import Path

import typer

from primitives.errors import UserError
from primitives.io import dumps


def parse_point(text: str | None, what: str) -> tuple[float, float, float | None] | None:
    """``LAT,LON[,HEADING_DEG]`` -> (lat, lon, heading or None)."""
    if text is None:
        return None
    try:
        vals = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        vals = []
    if len(vals) not in (2, 3):
        raise UserError(f"--{what}: expected LAT,LON[,HEADING_DEG] in degrees (e.g. 60.16,24.96,180), got {text!r}")
    return vals[0], vals[1], (vals[2] if len(vals) == 3 else None)


def parse_counts(text: str | None) -> dict[str, int] | None:
    """``NAME=N,NAME=N`` -> dict."""
    if text is None:
        return None
    out: dict[str, int] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        name, sep, val = part.partition("=")
        try:
            n = int(val)
        except ValueError:
            n = -1
        if not sep or not name or n < 0:
            raise UserError(f"--counts: expected NAME=N with N a whole number >= 0, got {part!r}")
        out[name.strip()] = n
    if not out:
        raise UserError("--counts: give at least one NAME=N")
    return out


def design_counts(profile, seed: int = 0) -> tuple[dict[str, int], list, str, object | None]:
    """Counts from the D-optimal design over the section 9.4 primitives (rounded units converted
    to whole primitives); the thesis scenario's counts when the design is not available."""
    from maps.scenario import thesis_planning_scenario

    prims, scen = thesis_planning_scenario(profile)
    try:
        from expdesign.api import run_design
    except ImportError:
        return scen, prims, "experiment design not available: using the thesis scenario counts (3 uses each)", None
    total = 3 * sum(p.duration_s for p in prims)
    d = run_design(profile, prims, trial_length_s=total, seed=seed)
    counts = {}
    for p in prims:
        units = d.rounded.get(p.name, 0)
        unit_s = d.unit_s.get(p.name, p.duration_s) if hasattr(d, "unit_s") else p.duration_s
        counts[p.name] = int(round(units * unit_s / p.duration_s))
    counts = {k: v for k, v in counts.items() if v > 0}
    if not counts:
        return scen, prims, "the design selected nothing: using the thesis scenario counts", d
    return counts, prims, f"counts from the D-optimal design over {', '.join(p.name for p in prims)} ({total:.0f} s of trial)", d


@contextmanager
def stage(text: str, quiet: bool):
    """A spinner on stderr for a long step (only on a terminal, never in --json output)."""
    if quiet or not sys.stderr.isatty():
        yield
        return
    from rich.console import Console

    with Console(stderr=True).status(text):
        yield


def print_summary(result, summary: dict, files: dict[str, Path]) -> None:
    from rich.console import Console
    from rich.table import Table

    con = Console()
    st = result.stats
    for n in st.get("notes", []):
        con.print(f"note: {n}", markup=False)
    t = Table(title=f"trial plan for {result.ship}" + (" (optimal)" if result.optimal else ""), show_header=False)
    t.add_column("item")
    t.add_column("value")
    used = ", ".join(f"{k} x{v}" for k, v in result.counts.items())
    t.add_row("feasible", "yes" if result.feasible else "NO")
    t.add_row("informative manoeuvres", used or "-")
    t.add_row("basic repositioning moves", str(result.basic_moves))
    t.add_row("duration", f"{result.duration_s / 60:.1f} min")
    t.add_row("track length", f"{result.length_m / 1000:.2f} km")
    t.add_row("smallest clearance", f"{result.min_clearance_m:.1f} m (margin {result.margin_m:g} m)")
    t.add_row("search", f"{st.get('expansions')} expansions, {st.get('states_visited')} states, {st.get('plan_time_s', 0):.3f} s, "
                        f"{'certified optimal' if result.optimal else 'not certified optimal'}")
    con.print(t)
    if result.feasible:
        steps = Table(title="manoeuvres in sailing order")
        for col in ("#", "start", "manoeuvre", "heading", "entry position"):
            steps.add_column(col)
        for s_ in result.steps:
            steps.add_row(str(s_.index + 1), f"{s_.start_time_s / 60:5.1f} min", s_.primitive, f"{s_.entry_heading_deg:05.1f}",
                          f"{s_.entry_lat:.5f} N {s_.entry_lon:.5f} E")
        con.print(steps)
    for key, path in files.items():
        con.print(f"wrote {key:18s} {path}", markup=False)


def register(app: typer.Typer) -> None:
    @app.command("plan")
    def plan(
        map_path: Path | None = typer.Option(None, "--map", help="GeoJSON sea map (default: the bundled Helsinki example)"),
        ship: str = typer.Option("full-scale", "--ship", help="built-in profile name or a .toml/.json profile file"),
        start: str | None = typer.Option(None, "--start", help="LAT,LON,HEADING_DEG (default: the map's start feature)"),
        goal: str | None = typer.Option(None, "--goal", help="LAT,LON[,HEADING_DEG] (default: the map's goal feature)"),
        counts: str | None = typer.Option(None, "--counts", help="NAME=N,... uses per informative primitive (default: run the design)"),
        resolution: float | None = typer.Option(None, "--resolution", help="lattice spacing in metres (default ~4 ship lengths)"),
        headings: int = typer.Option(4, "--headings", help="lattice headings: 4, 8 or 16"),
        heuristic: str = typer.Option("admissible", "--heuristic", help="admissible (certified optimal) or thesis (8.9)"),
        margin: float = typer.Option(20.0, "--margin", help="safety margin around the swept hull, metres"),
        split: bool = typer.Option(False, "--split", help="split primitives at their natural break points"),
        size: str = typer.Option("35x44", "--size", help="minimum lattice size NORTHxEAST points"),
        out: Path = typer.Option(Path("trial-out"), "--out", help="directory for the plan, the crew exports and the figures"),
        start_time: str | None = typer.Option(None, "--start-time", help="UTC start of the trial for the schedule, e.g. 2026-06-01T08:00Z "
                                                                         "(default: the next full hour)"),
        no_export: bool = typer.Option(False, "--no-export", help="write only plan.json, trajectory.geojson and plan.png"),
        json_out: bool = typer.Option(False, "--json", help="print one JSON summary"),
        seed: int = typer.Option(0, "--seed", help="seed of the experiment design"),
    ) -> None:
        """Plan a trial: design -> rounding -> A* planning -> continuous verification -> exports for the crew."""
        from cli.options import validate_plan_options

        validate_plan_options(resolution=resolution, margin=margin, headings=headings, start=start, goal=goal,
                              counts=counts, size=size, out=out, seed=seed)
        from maps.geo import load_map
        from maps.output import write_outputs
        from maps.planner import plan_trial
        from primitives.ship import load_profile

        if heuristic not in ("admissible", "thesis"):
            raise UserError(f"--heuristic must be 'admissible' or 'thesis', got {heuristic!r}")
        try:
            ni, nj = (int(v) for v in size.lower().split("x"))
        except ValueError:
            raise UserError(f"--size: expected NORTHxEAST whole numbers, e.g. 35x44, got {size!r}") from None
        start_pt, goal_pt = parse_point(start, "start"), parse_point(goal, "goal")
        cnt = parse_counts(counts)
        from maps.export._common import iso, resolve_start

        if start_time is not None:
            resolve_start(None, start_time)  # reject a malformed time before the long work
        prof = load_profile(ship)
        sea = load_map(map_path, draught_m=prof.draught_m)
        prims, note, design = None, "", None
        if cnt is None:
            with stage("designing the manoeuvre mix (D-optimal, rounded) ...", json_out):
                cnt, prims, note, design = design_counts(prof, seed)
        with stage("planning on the lattice (A*) and verifying the continuous track ...", json_out):
            result = plan_trial(sea, profile=prof, counts=cnt, primitives=prims, start=start_pt,
                                goal=goal_pt, resolution=resolution, headings=headings,
                                heuristic=heuristic, margin=margin, split=split, size=(ni, nj))
        if note:
            result.stats.setdefault("notes", []).insert(0, note)
        t0 = resolve_start(result, start_time)
        result.stats["start_utc"] = iso(t0)  # saved in plan.json: re-exports give the same schedule
        files = write_outputs(result, sea, out)
        if design is not None:
            from expdesign.report import plot_ratios

            plot_ratios(design, out / "design-ratios.png")
            files["design_ratios_png"] = out / "design-ratios.png"
        if result.feasible and not no_export:
            from maps.export import export_all

            with stage("writing the crew exports (GeoJSON, GPX, RTZ, CSV, trial card) ...", json_out):
                files.update(export_all(result, out, sea_map=sea, start=t0))
        st = result.stats
        summary = {
            "feasible": result.feasible, "optimal": result.optimal, "counts": result.counts, "targets": result.targets,
            "basic_moves": result.basic_moves, "duration_s": result.duration_s, "length_m": result.length_m,
            "min_clearance_m": result.min_clearance_m, "expansions": st.get("expansions"),
            "states_visited": st.get("states_visited"), "plan_time_s": st.get("plan_time_s"),
            "setup_time_s": st.get("setup_time_s"), "heuristic": heuristic, "lattice": st.get("lattice"),
            "drift_m": st.get("drift_m"), "reason": st.get("reason"), "help": st.get("help"),
            "notes": st.get("notes", []), "warnings": st.get("warnings", []),
            "design": None if design is None else {"weights": design.weights, "rounded": design.rounded, "logdet": design.logdet},
            "trajectory_geojson": str(files["trajectory_geojson"]) if "trajectory_geojson" in files else None,
            "plan_json": str(files["plan_json"]),
            "plot": str(files["plot"]),
            "files": {k: str(v) for k, v in files.items()},
        }
        for w in st.get("warnings", []):
            print(f"warning: {w}", file=sys.stderr)
        if json_out:
            print(dumps(summary))
        else:
            print_summary(result, summary, files)
        if not result.feasible:
            print(f"no feasible plan: {st.get('reason')}", file=sys.stderr)
            for h in st.get("help") or []:
                print(f"  would help: {h}", file=sys.stderr)
            raise typer.Exit(1)
