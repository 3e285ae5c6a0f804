"""Planner outputs: plan.json, the continuous track as GeoJSON and a picture of the track in its planning window."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from maps.geo import SeaMap
from maps.plan import Plan


def _plan_box(plan: Plan, sea: SeaMap, ax: Any) -> tuple[float, float, float, float]:
    """The picture's window (x0, y0, x1, y1: north, east in metres): the track with 800 m round
    it and the planning window, which is drawn dotted on ``ax``."""
    lat = plan.stats.get("lattice", {})
    if plan.track.size:
        x, y = plan.track[:, 0], plan.track[:, 1]
        pad = 800.0
        box = (x.min() - pad, y.min() - pad, x.max() + pad, y.max() + pad)
    else:
        box = sea.extent
    if lat:
        r = lat["resolution_m"]
        wx = (lat["x0"] - r / 2, lat["x0"] + (lat["ni"] - 0.5) * r)
        wy = (lat["y0"] - r / 2, lat["y0"] + (lat["nj"] - 0.5) * r)
        box = (min(box[0], wx[0]), min(box[1], wy[0]), max(box[2], wx[1]), max(box[3], wy[1]))
        ax.plot([wy[0], wy[1], wy[1], wy[0], wy[0]], [wx[0], wx[0], wx[1], wx[1], wx[0]], "k:", lw=0.8, label="planning window")
    return box


def _plan_track(plan: Plan, ax: Any) -> None:
    """The track (informative steps coloured by primitive, run-ins dashed green, transit grey),
    execute points, start and goal, labelled for the legend."""
    # the card's colours (maps.export.mapplot), which skip the ones that read as a run-in or a
    # transit: tab10's green here drew the third manoeuvre like the run-ins' dashed green
    from maps.export.mapplot import primitive_colours, step_colour

    colours = primitive_colours(plan)
    seen: set[str] = set()
    for s in plan.steps:
        sel = plan.step_of_sample == s.index
        seg = s.segment
        key = s.primitive if seg == "informative" else seg
        col = step_colour(plan, s, colours)
        ax.plot(
            plan.track[sel, 1],
            plan.track[sel, 0],
            color=col,
            lw=1.6 if seg == "informative" else 1.0,
            ls="--" if seg == "run-in" else "-",
            label=None if key in seen else key,
        )
        seen.add(key)
    ex = [s for s in plan.steps if getattr(s, "execute", False)]
    if ex:
        ax.plot(
            [s.entry_y for s in ex],
            [s.entry_x for s in ex],
            "*",
            color="#ffd400",
            mec="k",
            ms=11,
            ls="none",
            label="execute point",
        )
    ax.plot(plan.track[0, 1], plan.track[0, 0], "go", ms=7, label="start")
    ax.plot(plan.track[-1, 1], plan.track[-1, 0], "rs", ms=7, label="goal")


def plot_plan(plan: Plan, sea: SeaMap, path: str | Path) -> Path:
    """Track on the map (east right, north up, metres): informative steps coloured by primitive,
    run-ins dashed green, transit grey, execute points starred."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import shapely
    from matplotlib.collections import PolyCollection

    from maps.export.plots import fixed_margins, legend_width_in
    from primitives.io import atomic_write_bytes, figure_png

    fig, ax = plt.subplots(figsize=(9, 8))
    box = _plan_box(plan, sea, ax)
    clip = shapely.clip_by_rect(sea.obstacles, *box)
    # one collection for every obstacle (a map has hundreds of islands): one draw call, not a patch each
    rings = [
        np.asarray(g.exterior.coords)[:, ::-1]
        for g in getattr(clip, "geoms", [clip])
        if not g.is_empty and g.geom_type == "Polygon"
    ]
    ax.add_collection(PolyCollection(rings, facecolors="#d8c8a0", edgecolors="#8a7a50", linewidths=0.5, zorder=1))
    if plan.track.size:
        _plan_track(plan, ax)
    ax.set_xlim(box[1], box[3])
    ax.set_ylim(box[0], box[2])
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    state = "feasible" if plan.feasible else "NOT feasible"
    ax.set_title(
        f"{sea.name}: {plan.ship}, {state}, {plan.duration_s / 60:.0f} min, {plan.basic_moves} basic moves, "
        f"clearance {plan.min_clearance_m:.0f} m",
        fontsize=9,
    )
    leg = ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)  # never over the track
    # fixed margins (inches) beside the legend's own width: tight_layout's pass over every tick label cost as much as the drawing
    fixed_margins(fig, left=0.95, right=legend_width_in(fig, leg) + 0.2, top=0.35, bottom=0.6)
    out = atomic_write_bytes(path, figure_png(fig, 110))
    plt.close(fig)
    return out


def write_outputs(
    plan: Plan, sea: SeaMap, out_dir: str | Path, plot: bool = True, chart: Any = None, trajectory_bytes: bytes | None = None
) -> dict[str, Path]:
    """plan.json, trajectory.geojson and (``plot``) plan.png (the track in its planning window,
    :func:`plot_plan`) in ``out_dir`` (atomic writes).

    plan.json carries the chart around the track (``plan.stats['chart']``: land, shallow and
    other no-go water, depth areas) so that ``shiptrial export`` draws the same map and keeps
    the route's corridors off the same land without the map file. trajectory.geojson is the
    track alone, one LineString per segment tagged ``run-in``, ``informative`` (with the
    primitive) or ``transit`` (RFC 7946, when there is a track); the crew's chart overlay with
    execute points, waypoints and corridors is ``<ship>-trial.geojson`` (maps.export).
    ``chart``: the chart of ``sea`` (:func:`maps.export.chart.plan_chart`) when the caller has
    it already (it costs a second reading of the map file otherwise). ``trajectory_bytes``: trajectory.geojson's
    bytes when known already (kept for this plan at another start time: the file has no start time in it),
    written as they are.
    """
    from maps.export.chart import embed_chart
    from maps.export.geojson import write_geojson
    from primitives.io import atomic_write_bytes, atomic_write_text

    out = Path(out_dir)
    if len(plan.track) >= 2:
        embed_chart(plan, sea if chart is None else chart)
    files = {"plan_json": atomic_write_text(out / "plan.json", plan.to_json())}
    if len(plan.track) >= 2:  # a LineString needs two positions; a failed search has no track
        path = out / "trajectory.geojson"
        files["trajectory_geojson"] = (
            atomic_write_bytes(path, trajectory_bytes)
            if trajectory_bytes is not None
            else write_geojson(plan, path, overlay=False)
        )
    if plot:
        files["plot"] = plot_plan(plan, sea, out / "plan.png")
    return files
