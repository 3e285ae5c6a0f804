"""plan-trial's and resume's outputs: the export chart every crew file shares, every file written into
a temporary directory (the figures drawn by the drawer process meanwhile), and the spinner shown
for a long step."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # annotations only: the command imports the library when it runs
    from cli.drawer import Drawer
    from maps.geo import SeaMap
    from maps.plan import Plan
    from maps.trialdesign import TrialDesign


@contextmanager
def stage(text: str, quiet: bool) -> Iterator[None]:
    """A spinner on stderr for a long step (only on a terminal, never in --json output)."""
    if quiet or not sys.stderr.isatty():
        yield
        return
    from rich.console import Console

    with Console(stderr=True).status(text):
        yield


def export_chart(result: Plan, sea: SeaMap) -> Any:
    """The one chart every export of ``result`` uses, with the route and sea room they share built
    and kept on the plan (sent to the drawer with it)."""
    from maps.export._common import check_plan
    from maps.export.geojson import sea_room_lonlat
    from maps.export.route import build_route
    from maps.mapcache import kept_chart

    check_plan(result)
    chart = kept_chart(sea)  # plan_chart(result, sea), kept with the projected map
    build_route(result, chart)
    sea_room_lonlat(result)
    return chart


def write_outputs_all(
    result: Plan,
    sea: SeaMap,
    tmp: Path,
    td: TrialDesign | None,
    t0: datetime,
    no_export: bool,
    quiet: bool,
    drawer: Drawer | None = None,
    chart: Any = None,
    figures: dict[str, bytes] | None = None,
) -> dict[str, Path]:
    """Every output into the (temporary) directory ``tmp``. The figures (PDF and HTML trial card,
    their PNGs, the plan picture, the design ratios) are drawn by ``drawer`` (a
    :class:`cli.drawer.Drawer` started with the command) while this process writes the plan and
    the text exports. ``chart``: :func:`export_chart` of the plan, when computed already. ``figures``: PNG
    and GeoJSON bytes by file name kept for this plan at another start time (:func:`cli.plan_cache.saved_sets`):
    written instead of drawn or exported (the PNGs by the drawer, the GeoJSON files here)."""
    from maps.export import default_path
    from maps.output import write_outputs

    exports = result.feasible and not no_export
    if not exports:
        if drawer is not None:
            drawer.cancel()
        files = write_outputs(result, sea, tmp, plot=True)
        if td is not None:
            from cli.drawer import _design_ratios

            files["design_ratios_png"] = _design_ratios(td.design, tmp)
        return files
    if chart is None:
        chart = export_chart(result, sea)
    if drawer is None:
        from cli.drawer import Drawer

        drawer = Drawer()
    given = figures or {}
    geo = {name: data for name, data in given.items() if name.endswith(".geojson")}  # written here, not sent
    png = {name: data for name, data in given.items() if not name.endswith(".geojson")}
    drawer.send(
        {
            "plan": result,
            "sea": sea,
            "chart": chart,
            "design": td.design if td is not None else None,
            "t0": t0,
            "dir": tmp,
            "png": png if figures is not None else None,
        }
    )  # pickled now: the figures are drawn with the chart given, not the one plan.json stores
    try:
        files, crew = _text_exports(result, sea, tmp, chart, t0, geo, quiet)
    except BaseException:
        drawer.wait(quiet=True)  # no child outlives the command; the first error is the one to report
        raise
    if not quiet:  # the summary's printer, imported while this process would only wait for the drawer
        import rich.console  # noqa: F401
        import rich.table  # noqa: F401
    drawer.wait()
    card = default_path(result, "card", tmp)
    stem = default_path(result, "csv", tmp).with_suffix("")
    return {
        **files,
        "plot": tmp / "plan.png",
        **({"design_ratios_png": tmp / "design-ratios.png"} if td is not None else {}),
        **crew,
        "card": card,
        "card_pdf": card.with_suffix(".pdf"),
        "track_png": Path(f"{stem}-track.png"),
        "states_png": Path(f"{stem}-states.png"),
    }


def _text_exports(
    result: Plan, sea: SeaMap, tmp: Path, chart: Any, t0: datetime, geo: dict[str, bytes], quiet: bool
) -> tuple[dict[str, Path], dict[str, Path]]:
    """plan.json and trajectory.geojson (:func:`maps.output.write_outputs`), then the crew exports, into ``tmp``;
    ``geo``: GeoJSON bytes kept by file name. The track's features, the start of both GeoJSON files, are built once
    (not kept on the plan): trajectory.geojson's bytes are made here (the file reads no chart) and written as kept
    ones are, and the crew's overlay is given the features."""
    from maps.export.geojson import geojson_bytes, plan_geojson, segment_features
    from maps.output import write_outputs

    segments, traj = None, geo.get("trajectory.geojson")
    if traj is None:
        segments = segment_features(result)
        traj = geojson_bytes(plan_geojson(result, overlay=False, segments=segments))
    files = write_outputs(result, sea, tmp, plot=False, chart=chart, trajectory_bytes=traj)
    with stage("writing the crew exports (GeoJSON, GPX, RTZ, CSV, trial card) ...", quiet):
        crew = {fmt: _crew_file(result, fmt, tmp, chart, t0, geo, segments) for fmt in ("geojson", "gpx", "rtz", "csv")}
    return files, crew


def _crew_file(
    result: Plan, fmt: str, tmp: Path, chart: Any, t0: datetime, kept: dict[str, bytes], segments: list[dict[str, Any]] | None
) -> Path:
    """The crew export ``fmt`` of ``result`` written into ``tmp``: its bytes from ``kept`` (by file name) when
    given, else exported (``segments``: the GeoJSON's track features, when built already)."""
    from maps.export import _write, default_path
    from primitives.io import atomic_write_bytes

    path = default_path(result, fmt, tmp)
    if path.name in kept:
        return atomic_write_bytes(path, kept[path.name])
    if fmt == "geojson" and segments is not None:  # as _write exports it, with the track's features built already
        from maps.export.geojson import write_geojson

        return write_geojson(result, path, sea_map=chart, segments=segments)
    return _write(result, fmt, path, sea_map=chart, start=t0, vessel=None, pdf=False, figures=None)[0]
