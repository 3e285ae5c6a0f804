"""``shiptrial export PLAN.json --format gpx|rtz|geojson|csv|card|all``: re-export a saved plan."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from primitives.errors import UserError

if TYPE_CHECKING:  # annotations only
    from maps.geo import SeaMap
    from maps.plan import Plan


def load_plan(path: Path):
    """A saved plan, or a one-line :class:`UserError` naming the file and the fix."""
    from maps.plan import Plan

    if path.is_dir():
        raise UserError(f"{path}: is a directory; give the plan file (plan.json written by plan-trial --out DIR)")
    try:
        return Plan.load(path)
    except FileNotFoundError as exc:
        raise UserError(str(exc)) from None
    except UnicodeDecodeError:
        raise UserError(f"{path}: not a text file; give the plan JSON written by plan-trial") from None
    except ValueError as exc:
        raise UserError(str(exc).splitlines()[0]) from None
    except (TypeError, AttributeError, IndexError) as exc:
        raise UserError(f"{path}: malformed plan ({type(exc).__name__}: {exc}); re-create it with plan-trial") from None


def resolve_sea_map(path: Path | None, map_name: str, plan: Plan | None = None) -> SeaMap | str | None:
    """The chart for the card and the route's corridors: ``--map`` (a sea map read by
    ``maps.geo.load_map``, shallow for the ship's draught when the plan's ship is a bundled
    profile), else None when the plan carries its own chart (``plan.stats['chart']``), else the
    bundled map the plan names, else None (the card then draws the track only)."""
    try:
        from maps.geo import bundled_map_path, load_map
    except ImportError:
        return str(path) if path else None
    if path is not None:
        sea = load_map(path, draught_m=_draught(plan))
        _check_track_on_map(plan, sea, path)
        return sea
    if plan is not None and isinstance(plan.stats, dict) and plan.stats.get("chart"):
        return None  # the exporters use the chart saved with the plan
    if map_name and bundled_map_path(map_name).is_file():
        return load_map(bundled_map_path(map_name))
    return None


def _check_track_on_map(plan: Plan | None, sea: SeaMap, path: Path) -> None:
    """The plan's track reaches the ``--map`` given: a plan made on another sea would be drawn on its chart (the
    card's track off the chart, the route's corridors on the wrong water). Only a track wholly off the map's extent
    is refused: the extent is the box of the map's features, and on a map without a trial area the plan's own
    track leaves it (a small island's map: the lattice window is wider than the island)."""
    if plan is None or len(plan.lonlat) == 0:
        return
    lo0, la0, lo1, la1 = sea.lonlat_extent
    lon, lat = plan.lonlat[:, 0], plan.lonlat[:, 1]
    if ((lon >= lo0) & (lon <= lo1) & (lat >= la0) & (lat <= la1)).any():
        return
    raise UserError(
        f"--map {path}: the plan's track (lat {lat.min():.4f}..{lat.max():.4f}, lon {lon.min():.4f}..{lon.max():.4f}) "
        f"is nowhere on this map (lat {la0:.4f}..{la1:.4f}, lon {lo0:.4f}..{lo1:.4f}); give the map the plan was made "
        f"on ({plan.map_name or 'its --map'}) or leave --map out"
    )


def _draught(plan) -> float:
    """The draught of the plan's ship when it is a bundled profile, else 0 (no depth limit)."""
    try:
        from primitives.ship import builtin_profiles, load_profile

        if plan is not None and plan.ship in builtin_profiles():
            return float(load_profile(plan.ship).draught_m)
    except Exception:  # the map still loads without the profile
        pass
    return 0.0


def register(app: typer.Typer) -> None:
    @app.command("export")
    def export(
        plan_file: Path = typer.Argument(..., help="plan JSON written by plan-trial"),
        fmt: str = typer.Option("all", "--format", "-f", help="gpx | rtz | geojson | csv | card | all"),
        out: Path | None = typer.Option(None, "--out", "-o", help="output file (one format) or directory (all)"),
        sea_map: Path | None = typer.Option(
            None,
            "--map",
            help="GeoJSON sea map file or a bundled map's name to draw on the card (default: the bundled map the plan names)",
        ),
        start: str | None = typer.Option(None, "--start", help="UTC start of the trial, ISO 8601 (e.g. 2026-06-01T08:00Z)"),
        no_pdf: bool = typer.Option(False, "--no-pdf", help="card: write the HTML only"),
        force: bool = typer.Option(
            False, "--force", help="replace files of the export's names that no export wrote (default: refuse, naming the file)"
        ),
        vessel: str | None = typer.Option(
            None,
            "--vessel-name",
            help="the ship's name on the route and card (default: the plan's vessel name, else the profile's display name)",
        ),
    ) -> None:
        """Export a saved plan for the ship: route (RTZ, GPX), GeoJSON, CSV schedule or trial card."""
        from cli.options import validate_export_options
        from maps.export import default_path, export_all, export_plan

        validate_export_options(plan_file=plan_file, fmt=fmt, out=out, sea_map=sea_map, vessel_name=vessel, start=start)
        fmt_l = fmt.lower()
        plan = load_plan(plan_file)
        for note in plan.read_notes:
            typer.echo(f"note: {note}")
        sea = resolve_sea_map(sea_map, plan.map_name, plan)
        if fmt_l == "all":
            out_dir = out or plan_file.parent  # an --out that is a file: refused by validate_export_options
            written = list(export_all(plan, out_dir, sea, start=start, vessel=vessel, replace=force).values())
        else:
            path = out or default_path(plan, fmt_l, plan_file.parent)
            if path.is_dir():
                path = default_path(plan, fmt_l, path)
            written = export_plan(plan, fmt_l, path, sea_map=sea, start=start, pdf=not no_pdf, vessel=vessel, replace=force)
        for p in written:
            typer.echo(f"wrote {p}")
