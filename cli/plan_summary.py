"""What `plan` and `plan-trial` print: the summary as rich tables or one JSON object, and the exit
status when no feasible plan was found."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from primitives.io import dumps

if TYPE_CHECKING:  # annotations only
    from maps.plan import Plan


def print_summary(result: Plan, summary: dict[str, Any], files: dict[str, Path]) -> None:
    """The plan as rich tables on stdout: notes, totals, design, the steps in sailing order, the files written."""
    from rich.console import Console
    from rich.table import Table

    from expdesign.robust_report import PROVENANCE
    from maps.searoom import dropped_text, held_text

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
    t.add_row(
        "repositioning",
        f"{len(result.segment_steps('transit'))} transit leg(s) "
        f"({st.get('basic_moves', 0)} lattice moves, {st.get('moves_straightened', 0)} straightened)",
    )
    if result.design:
        d = result.design
        t.add_row(
            "design",
            f"{d['criterion']}-optimal, {d['mean_subtraction']} mean subtraction; rounded D-efficiency "
            f"{d['d_efficiency']:.3f}" + dropped_text(d.get("dropped", [])),
        )
        if d.get("held_parameters"):
            t.add_row("held at the profile's values", held_text(d["held_parameters"]))
        if d.get("robust"):
            r = d["robust"]
            t.add_row(
                f"D-efficiency over draws ({r['evaluated_on'].split(':')[0]})",
                "; ".join(
                    f"{k}: median {s['median']:.3f}, 10th percentile {s['p10']:.3f}, worst {s['min']:.3f}"
                    for k, s in r["d_efficiency"].items()
                )
                + f". {PROVENANCE}",
            )
    t.add_row("duration", f"{result.duration_s / 60:.1f} min")
    t.add_row("track length", f"{result.length_m / 1000:.2f} km")
    clear = f"{result.min_clearance_m:.1f} m" if math.isfinite(result.min_clearance_m) else "no land or obstacle within the map"
    t.add_row("smallest clearance", f"{clear} (margin {result.margin_m:g} m)")
    t.add_row(
        "search",
        f"{st.get('expansions')} expansions, {st.get('states_visited')} states, {st.get('plan_time_s', 0):.3f} s"
        + (" (in the run that filled the plan cache)" if summary.get("from_cache") else "")
        + ", "
        f"{'certified optimal' if result.optimal else 'not certified optimal'}",
    )
    con.print(t)
    if result.feasible:
        from rich.markup import escape

        from maps.export.wording import manoeuvre_name, phase

        # fits 80 columns: the name wraps at its spaces, the design code folds rather than being cut
        # (its last letter says starboard or port), the position wraps between latitude and longitude
        steps = Table(title="steps in sailing order")
        steps.add_column("#", justify="right")
        steps.add_column("start", justify="right", no_wrap=True)
        steps.add_column("phase", no_wrap=True)
        steps.add_column(escape("manoeuvre [design code]"), overflow="fold", ratio=1)
        steps.add_column("hdg", no_wrap=True)
        steps.add_column("entry position", no_wrap=True)
        for s_ in result.steps:
            ph = phase(result, s_)
            code = f" [{s_.primitive}]" if ph in ("EXECUTE", "manoeuvre") else ""
            steps.add_row(
                str(s_.index + 1),
                f"{s_.start_time_s / 60:.1f} min",
                ph,
                escape(manoeuvre_name(result, s_) + code),
                f"{s_.entry_heading_deg:03.0f}°",
                f"{abs(s_.entry_lat):.5f}{'N' if s_.entry_lat >= 0 else 'S'} "
                f"{abs(s_.entry_lon):.5f}{'E' if s_.entry_lon >= 0 else 'W'}",
            )
        con.print(steps)
    for key, path in files.items():
        con.print(f"wrote {key:18s} {path}", markup=False)


def report(result: Plan, files: dict[str, Path], heuristic: str, json_out: bool, cached: bool = False) -> None:
    """Print the summary (table or one JSON object); exit 1 when no feasible plan was found.
    ``cached``: the design and plan were read from the plan cache (said in a note and in the JSON
    object's ``from_cache``; the plan's timing fields are those of the run that computed it)."""
    st = result.stats
    summary = {
        "feasible": result.feasible,
        "optimal": result.optimal,
        "counts": result.counts,
        "targets": result.targets,
        "basic_moves": result.basic_moves,
        "duration_s": result.duration_s,
        "length_m": result.length_m,
        "min_clearance_m": result.min_clearance_m,
        "expansions": st.get("expansions"),
        "states_visited": st.get("states_visited"),
        "plan_time_s": st.get("plan_time_s"),
        "setup_time_s": st.get("setup_time_s"),
        "heuristic": heuristic,
        "lattice": st.get("lattice"),
        "drift_m": st.get("drift_m"),
        "reason": st.get("reason"),
        "help": st.get("help"),
        "notes": st.get("notes", []),
        "warnings": st.get("warnings", []),
        "design": result.design or None,
        "trajectory_geojson": str(files["trajectory_geojson"]) if "trajectory_geojson" in files else None,
        "plan_json": str(files["plan_json"]),
        "plot": str(files["plot"]),
        "files": {k: str(v) for k, v in files.items()},
        "from_cache": cached,
    }
    for w in st.get("warnings", []):
        print(f"warning: {w}", file=sys.stderr)
    if json_out:
        print(dumps(summary))
    else:
        if cached:
            print(
                "note: design and plan read from the plan cache (same inputs and code as a run before; --no-cache plans afresh)"
            )
        print_summary(result, summary, files)
    if not result.feasible:
        print(f"no feasible plan: {st.get('reason')}", file=sys.stderr)
        for h in st.get("help") or []:
            print(f"  would help: {h}", file=sys.stderr)
        raise typer.Exit(1)
