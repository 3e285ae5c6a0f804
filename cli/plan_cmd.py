"""``shiptrial plan`` (= ``plan-trial``): plan a trial on a sea map with the A* lattice planner."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from cli.errors import UserError
from cli.io import dumps


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


def design_counts(profile, seed: int = 0) -> tuple[dict[str, int], list, str]:
    """Counts from the D-optimal design over the section 9.4 primitives (rounded units converted
    to whole primitives); the thesis scenario's counts when the design is not available."""
    from maps.scenario import thesis_planning_scenario

    prims, scen = thesis_planning_scenario(profile)
    try:
        from expdesign.api import run_design
    except ImportError:
        return scen, prims, "experiment design not available: using the thesis scenario counts (3 uses each)"
    total = 3 * sum(p.duration_s for p in prims)
    d = run_design(profile, prims, trial_length_s=total, seed=seed)
    counts = {}
    for p in prims:
        units = d.rounded.get(p.name, 0)
        unit_s = d.unit_s.get(p.name, p.duration_s) if hasattr(d, "unit_s") else p.duration_s
        counts[p.name] = int(round(units * unit_s / p.duration_s))
    counts = {k: v for k, v in counts.items() if v > 0}
    if not counts:
        return scen, prims, "the design selected nothing: using the thesis scenario counts"
    return counts, prims, f"counts from the D-optimal design over {', '.join(p.name for p in prims)} ({total:.0f} s of trial)"


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
        out: Path | None = typer.Option(None, "--out", help="write plan.json, trajectory.geojson and plan.png here"),
        json_out: bool = typer.Option(False, "--json", help="print a JSON summary"),
        seed: int = typer.Option(0, "--seed", help="seed of the experiment design"),
    ) -> None:
        """Plan a trial: every informative primitive used as often as the design asks, fewest repositioning moves."""
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
        prof = load_profile(ship)
        sea = load_map(map_path, draught_m=prof.draught_m)
        prims = None
        note = ""
        if cnt is None:
            cnt, prims, note = design_counts(prof, seed)
        result = plan_trial(sea, profile=prof, counts=cnt, primitives=prims, start=start_pt,
                            goal=goal_pt, resolution=resolution, headings=headings,
                            heuristic=heuristic, margin=margin, split=split, size=(ni, nj))
        if note:
            result.stats.setdefault("notes", []).insert(0, note)
        files = write_outputs(result, sea, out) if out is not None else {}
        st = result.stats
        summary = {
            "feasible": result.feasible, "optimal": result.optimal, "counts": result.counts, "targets": result.targets,
            "basic_moves": result.basic_moves, "duration_s": result.duration_s, "length_m": result.length_m,
            "min_clearance_m": result.min_clearance_m, "expansions": st.get("expansions"),
            "states_visited": st.get("states_visited"), "plan_time_s": st.get("plan_time_s"),
            "setup_time_s": st.get("setup_time_s"), "heuristic": heuristic, "lattice": st.get("lattice"),
            "drift_m": st.get("drift_m"), "reason": st.get("reason"), "help": st.get("help"),
            "notes": st.get("notes", []), "warnings": st.get("warnings", []),
            "trajectory_geojson": str(files["trajectory_geojson"]) if "trajectory_geojson" in files else None,
            "plan_json": str(files["plan_json"]) if "plan_json" in files else None,
            "plot": str(files["plot"]) if "plot" in files else None,
        }
        for w in st.get("warnings", []):
            print(f"warning: {w}", file=sys.stderr)
        if json_out:
            print(dumps(summary))
        else:
            for n in st.get("notes", []):
                print(f"note: {n}")
            if result.feasible:
                used = ", ".join(f"{k} x{v}" for k, v in result.counts.items())
                print(f"plan: {len(result.steps)} steps ({used}; {result.basic_moves} basic moves), "
                      f"{result.duration_s / 60:.1f} min, {result.length_m / 1000:.2f} km, clearance {result.min_clearance_m:.1f} m, "
                      f"{'optimal' if result.optimal else 'not certified optimal'}")
                print(f"search: {st['expansions']} expansions, {st['states_visited']} states, {st['plan_time_s']:.3f} s "
                      f"(setup {st['setup_time_s']:.2f} s)")
                for s in result.steps:
                    print(f"  {s.index + 1:2d}. t={s.start_time_s:6.0f} s  {s.primitive:22s} heading {s.entry_heading_deg:5.1f}  "
                          f"at {s.entry_lat:.5f} N {s.entry_lon:.5f} E")
            for p in files.values():
                print(f"wrote {p}")
        if not result.feasible:
            print(f"no feasible plan: {st.get('reason')}", file=sys.stderr)
            for h in st.get("help") or []:
                print(f"  would help: {h}", file=sys.stderr)
            raise typer.Exit(1)
