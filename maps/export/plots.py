"""Figures of a plan: the track on the map coloured by primitive and numbered by manoeuvre
(like Fig. 9.13 of seed 001) and the simulated states over time (speed, heading, inputs).

Obstacles come from an optional ``sea_map``: a ``maps.geo.SeaMap``, a GeoJSON file or mapping, a shapely geometry or
a list of them, or any object with ``__geo_interface__`` (lon/lat, WGS-84). The plan alone
draws the track only. A ``maps.geo.SeaMap`` (metric geometries) is converted with its own
projection.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.legend_handler import HandlerPatch  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402

from maps.export._common import KN_PER_MPS, M_PER_NM, ExportError, deg_min, step_slice  # noqa: E402
from maps.plan import Plan, PlanStep  # noqa: E402
from primitives.io import atomic_savefig  # noqa: E402

OBSTACLE_KINDS = ("land", "obstacle", "restricted")


def load_geojson(path: str | Path) -> Any:
    """A GeoJSON file as a mapping, or an :class:`ExportError` naming the file."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ExportError(f"{path}: cannot read the obstacle map as GeoJSON ({exc})") from None


def obstacle_geoms(sea_map: Any) -> list:
    """Shapely geometries (lon/lat) of the obstacles in ``sea_map`` (see the module docstring)."""
    from shapely.geometry import shape
    from shapely.geometry.base import BaseGeometry

    if sea_map is None:
        return []
    if isinstance(sea_map, BaseGeometry):
        return [sea_map]
    if hasattr(sea_map, "obstacles") and hasattr(sea_map, "to_lonlat"):  # maps.geo.SeaMap: metric (x north, y east)
        import shapely

        def to_ll(c: np.ndarray) -> np.ndarray:
            return np.column_stack(sea_map.to_lonlat(c[:, 0], c[:, 1]))

        return [shapely.transform(sea_map.obstacles, to_ll)]
    if isinstance(sea_map, (str, Path)):
        sea_map = load_geojson(sea_map)
    if hasattr(sea_map, "__geo_interface__") and not isinstance(sea_map, dict):
        sea_map = sea_map.__geo_interface__
    if isinstance(sea_map, dict):
        t = sea_map.get("type")
        if t == "FeatureCollection":  # sea-map kinds: draw what the hull must avoid
            return [shape(f["geometry"]) for f in sea_map.get("features", [])
                    if f.get("geometry") and (f.get("properties") or {}).get("kind", "land") in OBSTACLE_KINDS]
        if t == "Feature":
            return [shape(sea_map["geometry"])] if sea_map.get("geometry") else []
        return [shape(sea_map)]
    if isinstance(sea_map, (list, tuple)):
        return [g for item in sea_map for g in obstacle_geoms(item)]
    raise ExportError(f"obstacle map of type {type(sea_map).__name__} is not understood: pass GeoJSON or shapely geometries")


RUN_IN_COLOUR = "#1b7f3b"
TRANSIT_COLOUR = "#7a7a7a"
LAND_COLOUR = "#c8b88a"
NO_GO_COLOUR = "#8fb3c9"


def primitive_colours(plan: Plan) -> dict[str, Any]:
    """A colour per step primitive: a distinct one per informative primitive (order of first
    appearance), green for run-ins, grey for transit."""
    inf = list(dict.fromkeys(st.primitive for st in plan.steps if st.segment == "informative"))
    cmap = plt.get_cmap("tab10" if len(inf) <= 10 else "tab20")
    out: dict[str, Any] = {n: cmap(i % cmap.N) for i, n in enumerate(inf)}
    for st in plan.steps:
        if st.primitive not in out:
            out[st.primitive] = RUN_IN_COLOUR if st.segment == "run-in" else TRANSIT_COLOUR
    return out


def step_colour(plan: Plan, st: PlanStep, colours: dict[str, Any] | None = None) -> Any:
    """Colour of one step on the map and the time plots."""
    seg = st.segment
    if seg == "run-in":
        return RUN_IN_COLOUR
    if seg == "transit":
        return TRANSIT_COLOUR
    return (colours or primitive_colours(plan))[st.primitive]


def _dm_formatter(pos: str, neg: str, width: int) -> Any:
    from matplotlib.ticker import FuncFormatter

    return FuncFormatter(lambda v, _: deg_min(v, pos, neg, width).replace("'", "′"))


def _view(plan: Plan, pad_m: float | None) -> tuple[float, float, float, float, float, float]:
    """(lon0, lat0, lon1, lat1, m per degree lon, m per degree lat) of the map window."""
    lon, lat = plan.lonlat[:, 0], plan.lonlat[:, 1]
    m_per_deg_lat = 111_320.0
    m_per_deg_lon = m_per_deg_lat * math.cos(math.radians(float(np.mean(lat))))
    if pad_m is None:  # room for the sea-room band and the markers
        pad_m = max(1.5 * (0.5 * plan.hull[1] + plan.margin_m), 3.0 * plan.hull[0], 1.0)
    pad = max(pad_m, 0.08 * max((lon.max() - lon.min()) * m_per_deg_lon, (lat.max() - lat.min()) * m_per_deg_lat))
    return (lon.min() - pad / m_per_deg_lon, lat.min() - pad / m_per_deg_lat, lon.max() + pad / m_per_deg_lon,
            lat.max() + pad / m_per_deg_lat, m_per_deg_lon, m_per_deg_lat)


def _draw_geom(ax: Any, geom: Any, view: Any, **kw: Any) -> bool:
    """Fill the polygons (draw lines, points) of ``geom`` inside ``view``; True if any drawn.
    The polygons are one compound path (a chart has hundreds of islands: one patch to draw)."""
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MPath

    if geom is None or geom.is_empty or not geom.intersects(view):
        return False
    verts: list[np.ndarray] = []
    codes: list[np.ndarray] = []
    drawn = _collect_geom(ax, geom.intersection(view), verts, codes, kw)
    if verts:
        ax.add_patch(PathPatch(MPath(np.concatenate(verts), np.concatenate(codes)), **kw))
    return drawn or bool(verts)


def _collect_geom(ax: Any, g: Any, verts: list, codes: list, kw: dict) -> bool:
    """Rings of the polygons of ``g`` into ``verts``/``codes``; lines and points drawn here."""
    from matplotlib.path import Path as MPath

    drawn = False
    for p in getattr(g, "geoms", [g]):
        if p.geom_type == "Polygon" and not p.is_empty:
            for ring in [p.exterior, *p.interiors]:
                c = np.asarray(ring.coords)[:, :2]
                code = np.full(len(c), MPath.LINETO, dtype=MPath.code_type)
                code[0], code[-1] = MPath.MOVETO, MPath.CLOSEPOLY
                verts.append(c)
                codes.append(code)
        elif p.geom_type in ("LineString", "LinearRing"):
            ax.plot(*p.xy, color=kw.get("edgecolor", "k"), lw=0.8, zorder=kw.get("zorder", 1))
            drawn = True
        elif p.geom_type == "Point":
            ax.plot(p.x, p.y, "x", color=kw.get("edgecolor", "k"), zorder=kw.get("zorder", 1))
            drawn = True
        elif hasattr(p, "geoms"):
            drawn = _collect_geom(ax, p, verts, codes, kw) or drawn
    return drawn


HATCH_PT = 3.0  # spacing of hatch lines (matplotlib's "////": 24 lines an inch)


class HatchProxy(Rectangle):
    """Legend entry of hatched water drawn with :class:`HatchHandler` (lines, not a fill pattern)."""


class HatchHandler(HandlerPatch):
    """Draws a :class:`HatchProxy` legend key as a filled box crossed by diagonal lines."""

    def create_artists(self, legend: Any, orig: Any, xd: float, yd: float, width: float, height: float, fontsize: float,
                       trans: Any) -> list:
        from matplotlib.collections import LineCollection

        box = Rectangle((-xd, -yd), width, height, facecolor=orig.get_facecolor(), edgecolor=orig.get_edgecolor(), lw=0.6,
                        transform=trans)
        segs = []
        for t in np.arange(-height, width, HATCH_PT):
            a, b = max(t, 0.0), min(t + height, width)
            segs.append([(-xd + a, -yd + a - t), (-xd + b, -yd + b - t)])
        return [box, LineCollection(segs, colors=[orig.get_edgecolor()], linewidths=0.6, transform=trans)]


HATCH_LEGEND = {HatchProxy: HatchHandler()}  # legend handler_map for maps drawn with hatch_lines


def hatch_segments(geom: Any, view: Any, m_per_deg: tuple[float, float], m_per_pt: float) -> list[np.ndarray]:
    """Diagonal lines (rising to the right, ``HATCH_PT`` apart on the page, ``m_per_pt`` metres
    a point) over ``geom`` inside ``view`` as lon/lat segments: hatching as line geometry, which
    every vector format reads (SVG patterns are not)."""
    from shapely.geometry import MultiLineString

    if geom is None or geom.is_empty or not geom.intersects(view):
        return []
    g = geom.intersection(view)
    x0, y0, x1, y1 = view.bounds
    wx, wy = (x1 - x0) * m_per_deg[0], (y1 - y0) * m_per_deg[1]
    step = HATCH_PT * m_per_pt * math.sqrt(2.0)
    cs = np.arange(-wy, wx + step, step)  # lines x - y = c in metres from the view's corner
    lines = MultiLineString([[(x0 + c / m_per_deg[0], y0), (x0 + (c + wy) / m_per_deg[0], y1)] for c in cs])
    cut = lines.intersection(g)
    return [np.asarray(p.coords) for p in getattr(cut, "geoms", [cut]) if p.geom_type == "LineString" and not p.is_empty]


def _hatch(ax: Any, geom: Any, view: Any, m_per_deg: tuple[float, float], colour: str, zorder: float) -> None:
    """:func:`hatch_segments` drawn on ``ax`` (its size on the page sets the spacing)."""
    from matplotlib.collections import LineCollection

    x0, y0, x1, y1 = view.bounds
    wx, wy = (x1 - x0) * m_per_deg[0], (y1 - y0) * m_per_deg[1]
    fig_w, fig_h = ax.figure.get_size_inches()
    pos = ax.get_position()
    m_per_pt = max(wx / (pos.width * fig_w * 72.0), wy / (pos.height * fig_h * 72.0))  # the aspect shrinks one side
    segs = hatch_segments(geom, view, m_per_deg, m_per_pt)
    if segs:
        ax.add_collection(LineCollection(segs, colors=colour, linewidths=0.6, zorder=zorder))


def _draw_chart(ax: Any, plan: Plan, sea_map: Any, view: Any, hatch_lines: bool = False) -> None:
    """Depth areas (blue shades, deeper darker), land (tan) and other no-go water (hatched:
    shallow for the ship, restricted, charted obstacles; ``hatch_lines``: see :func:`draw_map`)."""
    from maps.export.chart import plan_chart

    chart = plan_chart(plan, sea_map)
    if chart is None:
        return
    if chart.depth_areas:
        depths = sorted({d for _, d in chart.depth_areas})
        # as on a chart: the shallower the water, the stronger the blue; deep water nearly white
        shades = plt.get_cmap("Blues")(np.linspace(0.32, 0.04, max(len(depths), 2)))
        any_drawn = False
        for g, d in chart.depth_areas:
            any_drawn |= _draw_geom(ax, g, view, facecolor=shades[depths.index(d)], edgecolor="#5b8db8", lw=0.4, zorder=0.5)
        if any_drawn:
            ax.fill([], [], facecolor=shades[0], edgecolor="#5b8db8", label=f"depth areas {depths[0]:g}-{depths[-1]:g} m (darker: shallower)")
    if hatch_lines:
        if _draw_geom(ax, chart.no_go, view, facecolor=NO_GO_COLOUR, edgecolor="#35607d", lw=0.6, zorder=1):
            _hatch(ax, chart.no_go, view, _m_per_deg(view), "#35607d", 1)
            ax.add_patch(HatchProxy((view.bounds[0], view.bounds[1]), 0, 0, facecolor=NO_GO_COLOUR, edgecolor="#35607d",
                                    label="shallow / restricted (no-go)"))
    elif _draw_geom(ax, chart.no_go, view, facecolor=NO_GO_COLOUR, edgecolor="#35607d", hatch="////", lw=0.6, zorder=1):
        ax.fill([], [], facecolor=NO_GO_COLOUR, edgecolor="#35607d", hatch="////", label="shallow / restricted (no-go)")
    if _draw_geom(ax, chart.land, view, facecolor=LAND_COLOUR, edgecolor="#6b5d3a", lw=0.6, zorder=1):
        ax.fill([], [], facecolor=LAND_COLOUR, edgecolor="#6b5d3a", label="land")


def _draw_track(ax: Any, plan: Plan, numbers: bool) -> None:
    lon, lat = plan.lonlat[:, 0], plan.lonlat[:, 1]
    colours = primitive_colours(plan)
    labelled: set[str] = set()
    for st in plan.steps:
        sl = step_slice(plan, st)
        seg = st.segment
        key = st.primitive if seg == "informative" else seg
        label = None if key in labelled else {"run-in": "run-in (steady course and speed)", "transit": "transit"}.get(key, key)
        labelled.add(key)
        style = {"run-in": {"ls": (0, (4, 2)), "lw": 1.8}, "transit": {"ls": "-", "lw": 1.1}}.get(seg, {"ls": "-", "lw": 2.2})
        ax.plot(lon[sl], lat[sl], color=step_colour(plan, st, colours), zorder=3, solid_capstyle="butt", label=label, **style)
    execs = [st for st in plan.steps if getattr(st, "execute", False)]
    if execs:
        ax.plot([st.entry_lon for st in execs], [st.entry_lat for st in execs], ls="none", marker="*", ms=15, mfc="#ffd400",
                mec="k", mew=0.8, zorder=4.5, label="execute point")
    if numbers:
        for st in plan.steps:
            if st.segment == "transit" and not getattr(st, "execute", False) and len(plan.steps) > 12:
                continue  # a long plan: number the run-ins and manoeuvres, the table lists the rest
            ax.annotate(
                str(st.index + 1), (st.entry_lon, st.entry_lat), xytext=(7, 7), textcoords="offset points", fontsize=7,
                fontweight="bold", ha="center", va="center", zorder=5,
                bbox={"boxstyle": "circle,pad=0.15", "fc": "white", "ec": step_colour(plan, st, colours), "lw": 1.2},
            )
    ax.plot(lon[0], lat[0], marker="^", ms=11, color="green", mec="k", zorder=4, ls="none", label="start")
    ax.plot(lon[-1], lat[-1], marker="s", ms=9, color="red", mec="k", zorder=4, ls="none", label="end")


def lon_ticks(x0: float, x1: float, width_pt: float) -> list[float]:
    """Longitude ticks of a map from ``x0`` to ``x1`` drawn ``width_pt`` points wide:
    matplotlib's MaxNLocator(4) ticks inside the view, every other one dropped until they are
    60 points apart (a label such as 024°57.600′E is some 45 points long at 7 pt): a narrow map
    (a fjord) gets fewer labels, never overlapping ones."""
    from matplotlib.ticker import MaxNLocator

    ticks = [float(v) for v in MaxNLocator(4).tick_values(x0, x1) if x0 <= v <= x1]
    step = 1
    while len(ticks[::step]) > 1 and (ticks[step] - ticks[0]) / (x1 - x0) * width_pt < 60.0:
        step += 1
    return ticks[::step]


def _m_per_deg(view: Any) -> tuple[float, float]:
    lat = 0.5 * (view.bounds[1] + view.bounds[3])
    return 111_320.0 * math.cos(math.radians(lat)), 111_320.0


def draw_map(ax: Any, plan: Plan, sea_map: Any = None, *, pad_m: float | None = None, numbers: bool = True, sea_room: bool = True,
             hatch_lines: bool = False) -> None:
    """Chart (depth areas, land, shallow/restricted water), sea room (light blue), the track
    (informative manoeuvres coloured by primitive, run-ins dashed green, transit grey), execute
    points (stars), numbered manoeuvre starts, start/end marks, a scale bar and a north arrow,
    on lon/lat axes. ``sea_map``: see the module docstring (default: the plan's own chart).
    ``hatch_lines``: hatch shallow/restricted water with drawn lines instead of a fill pattern
    (for SVG read by other programs; the legend then needs ``handler_map=HATCH_LEGEND``)."""
    from shapely.geometry import box

    x0, y0, x1, y1, m_per_deg_lon, m_per_deg_lat = _view(plan, pad_m)
    view = box(x0, y0, x1, y1)
    _draw_chart(ax, plan, sea_map, view, hatch_lines)
    if sea_room:
        from maps.export.geojson import sea_room_lonlat

        room = sea_room_lonlat(plan)
        if room is not None and _draw_geom(ax, room, view, facecolor="#cfe6fb", edgecolor="none", zorder=2):
            ax.fill([], [], facecolor="#cfe6fb", label="sea room (hull + margin)")
    _draw_track(ax, plan, numbers)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    lat0 = float(np.mean(plan.lonlat[:, 1]))
    ax.set_aspect(1.0 / math.cos(math.radians(lat0)))
    ax.set_facecolor("#eef6fd")
    ax.xaxis.set_major_formatter(_dm_formatter("E", "W", 3))
    ax.yaxis.set_major_formatter(_dm_formatter("N", "S", 2))
    ax.tick_params(labelsize=7)
    ax.xaxis.set_major_locator(plt.MaxNLocator(4))
    ax.grid(color="white", lw=0.6, zorder=0)
    _scale_bar(ax, x0, y0, x1, y1, m_per_deg_lon)
    ax.annotate("N", xy=(0.95, 0.95), xytext=(0.95, 0.85), xycoords="axes fraction", ha="center", fontsize=9, fontweight="bold",
                arrowprops={"arrowstyle": "-|>", "color": "k"}, zorder=6)


def scale_bar(x0: float, y0: float, x1: float, y1: float, m_per_deg_lon: float) -> tuple[float, float, float, str]:
    """A round length (m, or NM from 1 NM up) about a fifth of the view width, bottom right:
    (lon, lat of its left end, its length in degrees of longitude, its label)."""
    width_m = (x1 - x0) * m_per_deg_lon
    unit = M_PER_NM if width_m / 5 >= M_PER_NM else 1.0
    target = width_m / 5 / unit
    mag = 10 ** math.floor(math.log10(max(target, 1e-3)))
    bar = max(n * mag for n in (1, 2, 5) if n * mag <= max(target, mag)) * unit
    bx, by = x1 - 0.04 * (x1 - x0) - bar / m_per_deg_lon, y0 + 0.04 * (y1 - y0)
    return bx, by, bar / m_per_deg_lon, f"{bar:g} m" if unit == 1.0 else f"{bar / M_PER_NM:g} NM"


def _scale_bar(ax: Any, x0: float, y0: float, x1: float, y1: float, m_per_deg_lon: float) -> None:
    """:func:`scale_bar` drawn on ``ax``."""
    bx, by, length, label = scale_bar(x0, y0, x1, y1, m_per_deg_lon)
    ax.plot([bx, bx + length], [by, by], color="k", lw=3, zorder=6)
    ax.text(bx + 0.5 * length, by + 0.012 * (y1 - y0), label, ha="center", va="bottom", fontsize=7, zorder=6)


def state_series(plan: Plan) -> list[tuple[str, np.ndarray]]:
    """(label, values) of each panel of the states figure: speed (kn), heading (deg, NaN where
    it wraps round), then each commanded input (angles in deg)."""
    heading = np.degrees(plan.track[:, 2]) % 360.0
    heading[1:][np.abs(np.diff(heading)) > 180] = np.nan  # no line across the wrap
    series = [("speed over ground [kn]", plan.speed * KN_PER_MPS), ("heading [deg]", heading)]
    for j, nm in enumerate(plan.input_names):
        v = plan.inputs[:, j] if plan.inputs.ndim == 2 and plan.inputs.shape[1] > j else np.zeros_like(plan.t)
        if nm.startswith("alpha") or nm == "delta":
            series.append((f"{nm} [deg]", np.degrees(v)))
        else:
            series.append((f"{nm}" + (" [rpm]" if nm.startswith("n") and nm[1:].isdigit() else ""), v))
    return series


def state_limits(lo: float, hi: float) -> tuple[float, float]:
    """The y range of a states panel with data from ``lo`` to ``hi``: matplotlib's autoscaling
    (non-singular, 5 % margins), except that a series constant to 1e-9 of its size (a steady
    speed) is shown as constant, not as rounding noise around an offset."""
    from matplotlib.ticker import MaxNLocator

    if hi - lo <= 1e-9 * max(abs(lo), abs(hi), 1.0):
        lo = hi = 0.5 * (lo + hi)
    lo, hi = MaxNLocator().nonsingular(lo, hi)
    d = 0.05 * (hi - lo)
    return lo - d, hi + d


def states_size_in(plan: Plan) -> tuple[float, float]:
    """Width and height (inches) of the states figure: A4 wide, 1.5 in a panel plus 1 in."""
    return 8.27, 1.5 * (2 + len(plan.input_names)) + 1.0


def draw_states(axes: list, plan: Plan) -> None:
    """Speed (kn), heading (deg) and each commanded input over time (minutes) on ``axes``
    (len 2 + number of inputs), with the manoeuvre numbers along the top."""
    t_min = (plan.t - plan.t[0]) / 60.0
    colours = primitive_colours(plan)
    series = state_series(plan)
    from matplotlib.collections import PolyCollection

    spans, span_colours = [], []
    for st in plan.steps:
        sl = step_slice(plan, st)
        a, b = t_min[sl.start], t_min[sl.stop - 1]
        spans.append([(a, 0.0), (a, 1.0), (b, 1.0), (b, 0.0)])
        span_colours.append(step_colour(plan, st, colours))
    for ax, (label, y) in zip(axes, series):
        # each step's span as axvspan shades it (full height, 12 % colour), all in one collection: one artist, not a patch a step
        ax.add_collection(PolyCollection(spans, facecolors=span_colours, alpha=0.12, linewidths=0, transform=ax.get_xaxis_transform()),
                          autolim=False)
        ax.plot(t_min[: len(y)], y, color="k", lw=0.9)
        finite = y[np.isfinite(y)]
        if len(finite):
            ax.set_ylim(*state_limits(float(finite.min()), float(finite.max())))
        ax.set_ylabel(label, fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    top = axes[0]
    for st in plan.steps:
        sl = step_slice(plan, st)
        top.text(0.5 * (t_min[sl.start] + t_min[sl.stop - 1]), 1.02, str(st.index + 1), transform=top.get_xaxis_transform(),
                 ha="center", va="bottom", fontsize=7, fontweight="bold", color=step_colour(plan, st, colours))
    axes[-1].set_xlabel("time from start [min]", fontsize=8)


# Fixed margins in inches (what tight_layout found for the bundled ships, rounded up): a layout
# pass measures every tick label of every axes, which cost as much CPU as drawing the figure.
STATES_MARGINS_IN = {"left": 0.72, "right": 0.15, "top": 0.56, "bottom": 0.52}
STATES_HSPACE = 0.15


def fixed_margins(fig: Any, left: float, right: float, top: float, bottom: float, **kw: float) -> None:
    """``fig.subplots_adjust`` with the margins given in inches (``kw``: hspace, wspace)."""
    w, h = fig.get_size_inches()
    fig.subplots_adjust(left=left / w, right=1.0 - right / w, top=1.0 - top / h, bottom=bottom / h, **kw)


def legend_width_in(fig: Any, legend: Any) -> float:
    """Width of ``legend`` in inches (its texts laid out, nothing else of the figure)."""
    return legend.get_window_extent(fig.canvas.get_renderer()).width / fig.dpi


def states_figure(plan: Plan) -> Any:
    """A figure of :func:`draw_states`, laid out with :data:`STATES_MARGINS_IN`."""
    n = 2 + len(plan.input_names)
    fig, axes = plt.subplots(n, 1, figsize=states_size_in(plan), sharex=True)
    draw_states(list(np.atleast_1d(axes)), plan)
    fig.suptitle(f"{plan.ship}: planned speed, heading and commanded inputs (manoeuvre numbers on top)", fontsize=9)
    fixed_margins(fig, **STATES_MARGINS_IN, hspace=STATES_HSPACE)
    return fig


TRACK_MARGINS_IN = {"left": 0.85, "top": 0.35, "bottom": 0.35}


def track_figure(plan: Plan, sea_map: Any = None) -> Any:
    """The numbered track coloured by primitive on the map, legend outside, titled; the axes
    take the figure less fixed margins and the legend's width (the PNG is cropped to what is
    drawn)."""
    fig, ax = plt.subplots(figsize=(9.5, 7.5))
    draw_map(ax, plan, sea_map)
    leg = ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), framealpha=0.9)  # outside: never hides the track
    ax.set_title(f"{plan.ship} trial{' on ' + plan.map_name if plan.map_name else ''}: manoeuvres numbered in sailing order", fontsize=9)
    _fit_to_map(fig, ax, leg)
    return fig


def _fit_to_map(fig: Any, ax: Any, legend: Any) -> None:
    """Size ``fig`` to the map (its aspect fixed by the latitude) plus fixed margins and the
    legend on the right: the figure ends where the drawing does, with no layout pass over the
    tick labels and no cropping draw when saved."""
    from matplotlib.ticker import FixedLocator

    r = fig.canvas.get_renderer()
    leg = legend.get_window_extent(r)
    leg_w, leg_h = leg.width / fig.dpi, leg.height / fig.dpi
    m = TRACK_MARGINS_IN
    fixed_margins(fig, right=leg_w + 0.2, **m)
    ax.apply_aspect()  # the axes shrink to the map's aspect inside the box the margins leave
    w, h = fig.get_size_inches()
    pos = ax.get_position()
    ax_w, ax_h = pos.width * w, pos.height * h
    # the title is centred over the map: a map narrower than its title gets the room on both sides
    over = max(0.0, 0.5 * (ax.title.get_window_extent(r).width / fig.dpi - ax_w) + 0.1)
    left = max(m["left"], over)
    right = max(0.01 * ax_w + leg_w + 0.15, over)  # the legend sits 1 % of the axes width right of the map
    fig.set_size_inches(left + ax_w + right, m["top"] + max(ax_h, leg_h) + m["bottom"])
    fixed_margins(fig, right=right, left=left, top=m["top"], bottom=m["bottom"] + max(0.0, leg_h - ax_h))
    x0, x1 = ax.get_xlim()
    ax.xaxis.set_major_locator(FixedLocator(lon_ticks(x0, x1, 72.0 * ax_w)))  # labels that do not overlap


STATES_DPI = 110
TRACK_DPI = 130
_SAVE = {"states": (STATES_DPI, None), "track": (TRACK_DPI, None)}  # default dpi, bbox_inches (the track figure fits its map)


class PlanFigures:
    """The figures of one plan, each drawn once and shared by the HTML trial card's images and
    the PNG exports (the PDF card draws its own map and states page): drawing a figure with its
    layout passes costs as much as saving it. ``close()`` when done (figures hold memory until closed)."""

    def __init__(self, plan: Plan, sea_map: Any = None) -> None:
        self.plan, self.sea_map = plan, sea_map
        self._figs: dict[str, Any] = {}
        self._png: dict[tuple[str, int], bytes] = {}

    def figure(self, name: str) -> Any:
        """'states' (:func:`states_figure`) or 'track' (:func:`track_figure`), built on first use."""
        if name not in self._figs:
            self._figs[name] = states_figure(self.plan) if name == "states" else track_figure(self.plan, self.sea_map)
        return self._figs[name]

    def owns(self, fig: Any) -> bool:
        return any(fig is f for f in self._figs.values())

    def png(self, name: str, dpi: int | None = None) -> bytes:
        """The figure as PNG bytes, rendered once per dpi (the map cropped to what is drawn)."""
        key = (name, dpi or _SAVE[name][0])
        if key not in self._png:
            import io

            buf = io.BytesIO()
            self.figure(name).savefig(buf, format="png", dpi=key[1], bbox_inches=_SAVE[name][1])
            self._png[key] = buf.getvalue()
        return self._png[key]

    def adopt_png(self, name: str, data: bytes, dpi: int | None = None) -> None:
        """Use ``data`` as the PNG of figure ``name`` at ``dpi``: the bytes :meth:`png` gave for
        the same plan in another process (``shiptrial plan`` draws its figures in two)."""
        self._png[(name, dpi or _SAVE[name][0])] = data

    def save(self, name: str, path: str | Path, dpi: int | None = None) -> Path:
        """Write the figure to ``path`` (PNG from the shared render, other formats by suffix)."""
        from primitives.io import atomic_write_bytes

        if Path(path).suffix.lower() in ("", ".png"):
            return atomic_write_bytes(path, self.png(name, dpi))
        return atomic_savefig(self.figure(name), path, dpi=dpi or _SAVE[name][0], bbox_inches=_SAVE[name][1])

    def close(self) -> None:
        for f in self._figs.values():
            plt.close(f)
        self._figs.clear()

    def __enter__(self) -> PlanFigures:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def plot_states(plan: Plan, path: str | Path, dpi: int = STATES_DPI, figures: PlanFigures | None = None) -> Path:
    """The simulated states over time (speed, heading, inputs) as PNG (or PDF/SVG by suffix)."""
    if figures is not None:
        return figures.save("states", path, dpi)
    with PlanFigures(plan) as figs:
        return figs.save("states", path, dpi)


def plot_track(plan: Plan, path: str | Path, sea_map: Any = None, dpi: int = TRACK_DPI, figures: PlanFigures | None = None) -> Path:
    """The numbered track coloured by primitive on the map, as PNG (or PDF/SVG by suffix)."""
    if figures is not None:
        return figures.save("track", path, dpi)
    with PlanFigures(plan, sea_map) as figs:
        return figs.save("track", path, dpi)
