"""Exports of a :class:`maps.plan.Plan` for ships and crews (notes/anchors section 5).

Formats: ``geojson`` (RFC 7946 chart overlay: tagged track segments, execute points, waypoints,
corridors, sea room), ``gpx`` (GPX 1.1 route + track), ``rtz`` (RTZ 1.2, IEC 61174),
``csv`` (schedule per sample), ``card`` (trial card: HTML with embedded PNGs, plus PDF).
Every file is written atomically and a set of files all-or-nothing (:mod:`maps.export.staging`).
:func:`export_plan` writes one format, :func:`export_all` every format plus the track and states plots.
"""

from __future__ import annotations

from contextlib import nullcontext
from datetime import datetime
from pathlib import Path
from typing import Any

from maps.export._common import ExportError
from maps.plan import Plan

FORMATS: dict[str, str] = {"geojson": ".geojson", "gpx": ".gpx", "rtz": ".rtz", "csv": ".csv", "card": ".html"}

__all__ = ["FORMATS", "ExportError", "default_path", "export_all", "export_plan"]


def default_path(plan: Plan, fmt: str, out_dir: str | Path = ".") -> Path:
    """``<out_dir>/<ship>-trial.<ext>`` (the RTZ route name is the file's stem)."""
    stem = f"{plan.ship}-trial".replace(" ", "_") if plan.ship else "trial"
    return Path(out_dir) / f"{stem}{FORMATS[fmt]}"


def export_plan(
    plan: Plan,
    fmt: str,
    path: str | Path,
    *,
    sea_map: Any = None,
    start: datetime | str | None = None,
    pdf: bool = True,
    vessel: str | None = None,
    figures: Any = None,
    replace: bool = False,
) -> list[Path]:
    """Write ``plan`` in format ``fmt`` to ``path``; returns the files written (the card writes
    an HTML file and, with ``pdf``, a PDF beside it; a ``.pdf`` path writes the PDF only).

    ``sea_map``: the chart for the card's map and the route's land-free corridors (a
    ``maps.geo.SeaMap``, GeoJSON path/mapping or shapely geometries in lon/lat; default: the
    chart stored in the plan). ``start``: UTC start of the trial for ETAs (default:
    ``plan.stats['start_utc']``, else the next full hour). ``vessel``: the ship's name on the
    route and card (default: ``plan.vessel_name``, else the profile's display name).
    ``figures``: a :class:`maps.export.figures.PlanFigures` of the plan to share the card's
    figures with other exports (:func:`export_all` does). The card's files appear together or
    not at all (:func:`maps.export.staging.staged_outputs`). A file of the same name that no export
    wrote (it carries no export's mark, :func:`maps.export.ownership.is_export_file`), or that changed since
    a record listed it, is refused unless ``replace`` (:func:`maps.export.ownership.check_replaceable`). The
    file is added to a record only where one is kept (a directory export's, a plan-trial directory); none is
    started beside it.
    """
    from maps.export.ownership import check_replaceable, write_record
    from maps.export.staging import staged_outputs

    fmt = fmt.lower()
    if fmt not in FORMATS:
        raise ExportError(f"unknown export format {fmt!r}: choose one of {', '.join(FORMATS)}")
    path = Path(path)
    names = [path.name]
    if fmt == "card" and pdf and path.suffix.lower() != ".pdf":
        names.append(path.with_suffix(".pdf").name)  # write_card's PDF beside the HTML
    recorded = check_replaceable(path.parent, names, replace)
    with staged_outputs(path.parent) as tmp:
        written = _write(plan, fmt, tmp / path.name, sea_map=sea_map, start=start, pdf=pdf, vessel=vessel, figures=figures)
        write_record(tmp, recorded, written)  # only where a record is kept: a file carries its own mark
    return [path.parent / p.name for p in written]


def _write(
    plan: Plan, fmt: str, path: Path, *, sea_map: Any, start: datetime | str | None, pdf: bool, vessel: str | None, figures: Any
) -> list[Path]:
    """:func:`export_plan` of a known format, written straight to ``path`` (and beside it)."""
    if fmt == "geojson":
        from maps.export.geojson import write_geojson

        return [write_geojson(plan, path, sea_map=sea_map)]
    if fmt == "gpx":
        from maps.export.gpx import write_gpx

        return [write_gpx(plan, path, start=start, vessel=vessel, sea_map=sea_map)]
    if fmt == "rtz":
        from maps.export.rtz import write_rtz

        return [write_rtz(plan, path, start=start, sea_map=sea_map, vessel=vessel)]
    if fmt == "csv":
        from maps.export.csv import write_csv

        return [write_csv(plan, path, start=start)]
    from maps.export.card import write_card

    return write_card(plan, path, sea_map=sea_map, start=start, pdf=pdf, vessel=vessel, figures=figures)


def export_all(
    plan: Plan,
    out_dir: str | Path,
    sea_map: Any = None,
    *,
    start: datetime | str | None = None,
    plots: bool = True,
    vessel: str | None = None,
    pdf: bool = True,
    figures: Any = None,
    staged: bool = True,
    replace: bool = False,
) -> dict[str, Path]:
    """Every export of ``plan`` into ``out_dir``: keys geojson, gpx, rtz, csv, card (HTML),
    card_pdf (without ``pdf``: none), and with ``plots`` track_png (map) and states_png (speed,
    heading, inputs): the card's images are those PNGs, each figure drawn once (``figures``: a
    :class:`maps.export.figures.PlanFigures` of the plan to draw them in, else a new one).

    All or nothing: when a writer fails, none of the files is left in ``out_dir`` and files there
    of the same names are as they were (:func:`maps.export.staging.staged_outputs`). ``staged=False``:
    write straight into ``out_dir``, for a caller that already builds ``out_dir`` all-or-nothing
    (``shiptrial plan``: :func:`primitives.io.atomic_output_dir`). A file of one of the export's names
    that no export wrote is refused unless ``replace`` (:mod:`maps.export.ownership`); files of other
    names are never touched."""
    from maps.export._common import check_plan, resolve_start
    from maps.export.chart import plan_chart
    from maps.export.figures import PlanFigures
    from maps.export.ownership import check_replaceable, read_record, write_record
    from maps.export.plots import plot_states, plot_track
    from maps.export.staging import staged_outputs

    check_plan(plan)
    if staged:  # unstaged, the caller builds out_dir whole: nothing of the user's is in it
        recorded = check_replaceable(out_dir, export_names(plan, plots=plots, pdf=pdf), replace) or {}
    else:
        recorded = read_record(out_dir) or {}
    t0 = resolve_start(plan, start)  # one start time for every file
    sea_map = plan_chart(plan, sea_map)  # one chart for every file (projecting the map was done once per export)
    out: dict[str, Path] = {}
    with PlanFigures(plan, sea_map) as own, staged_outputs(out_dir) if staged else nullcontext(Path(out_dir)) as tmp:
        figs = figures or own
        for fmt in FORMATS:
            written = _write(
                plan, fmt, default_path(plan, fmt, tmp), sea_map=sea_map, start=t0, vessel=vessel, pdf=pdf, figures=figs
            )
            out[fmt] = written[0]
            if fmt == "card" and len(written) > 1:
                out["card_pdf"] = written[1]
        if plots:
            stem = default_path(plan, "csv", tmp).with_suffix("")
            out["track_png"] = plot_track(plan, f"{stem}-track.png", sea_map, figures=figs)
            out["states_png"] = plot_states(plan, f"{stem}-states.png", figures=figs)
        write_record(tmp, recorded, out.values())  # published with the files: never one without the other
    return {k: Path(out_dir) / p.name for k, p in out.items()}


def export_names(plan: Plan, *, plots: bool = True, pdf: bool = True) -> list[str]:
    """The names of the files :func:`export_all` writes (checked before any work)."""
    names = [default_path(plan, fmt).name for fmt in FORMATS]
    stem = default_path(plan, "csv").stem
    return names + ([f"{stem}.pdf"] if pdf else []) + ([f"{stem}-track.png", f"{stem}-states.png"] if plots else [])
