"""The plan on the map: the chart (depth areas, land, shallow/restricted water), sea room, the
track coloured by primitive and numbered by manoeuvre (like Fig. 9.13 of seed 001), drawn on
matplotlib axes by :func:`draw_map`; its style (colours, depth shades, hatch spacing) and view
(:func:`map_view`) are shared with the PDF card's own drawing of the map
(:mod:`maps.export.pdfmap`), so the PNG and PDF maps cannot drift apart.

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
import numpy as np  # noqa: E402

from maps.export._common import M_PER_NM, ExportError, deg_min, step_slice  # noqa: E402
from maps.export.labels import END_MARKER_PT, NORTH_FS, north_place  # noqa: E402
from maps.export.wording import manoeuvre_name  # noqa: E402
from maps.plan import Plan, PlanStep  # noqa: E402

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
            return [
                shape(f["geometry"])
                for f in sea_map.get("features", [])
                if f.get("geometry") and (f.get("properties") or {}).get("kind", "land") in OBSTACLE_KINDS
            ]
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
NO_GO_EDGE = "#35607d"  # also the hatch lines
LAND_EDGE = "#6b5d3a"
DEPTH_EDGE = "#5b8db8"
SEA_ROOM_COLOUR = "#cfe6fb"
WATER_COLOUR = "#eef6fd"  # the map's background
EXECUTE_COLOUR = "#ffd400"  # the execute points' stars
NO_GO_LABEL = "shallow / restricted (no-go)"


def depth_shades(n: int) -> np.ndarray:
    """RGBA of ``n`` depth areas, shallowest first: as on a chart, the shallower the water, the
    stronger the blue; deep water nearly white (matplotlib's Blues from 0.32 down to 0.04)."""
    return matplotlib.colormaps["Blues"](np.linspace(0.32, 0.04, max(n, 2)))


def depth_label(depths: list[float]) -> str:
    """The legend label of the depth areas (``depths`` sorted)."""
    return f"depth areas {depths[0]:g}-{depths[-1]:g} m (darker: shallower)"


def depth_layers(chart: Any) -> tuple[list[tuple[Any, np.ndarray]], np.ndarray, str]:
    """The chart's depth areas with their shade (RGBA), the legend's shade (the shallowest) and
    label, as both the PNG and the PDF map draw them (no layers without depth areas)."""
    depths = sorted({d for _, d in chart.depth_areas})
    shades = depth_shades(len(depths))
    if not depths:
        return [], shades[0], ""
    return [(g, shades[depths.index(d)]) for g, d in chart.depth_areas], shades[0], depth_label(depths)


# A manoeuvre's colour must not read as a run-in (dashed green), a transit (grey) or the chart
# underneath: tab10's green (#2ca02c, 40 from RUN_IN_COLOUR) made the third manoeuvre of a plan
# look like its own run-in on the card, and tab10's grey the eighth like a transit. Minimum
# Euclidean distance in 8-bit RGB; 50 keeps tab10's brown (62 from the transit grey), but behind
# every colour at least CLEAR_COLOUR_DISTANCE away: on the states page the steps are 12 %-alpha
# bands, where brown's is CIELAB dE 2.6 from the transit's (the green one the rule removes: 3.2),
# so the Quick start's fifth manoeuvre read as a transit. Only a plan of 8 manoeuvres gets brown.
RESERVED_COLOURS = (RUN_IN_COLOUR, TRANSIT_COLOUR, SEA_ROOM_COLOUR, WATER_COLOUR, LAND_COLOUR)
MIN_COLOUR_DISTANCE = 50.0
CLEAR_COLOUR_DISTANCE = 65.0


def manoeuvre_palette(name: str) -> list[tuple[float, float, float, float]]:
    """The colours of matplotlib's qualitative map ``name`` (tab10, tab20) at least
    MIN_COLOUR_DISTANCE from every RESERVED_COLOURS entry: first, in the map's order, those at
    least CLEAR_COLOUR_DISTANCE away, then the others."""
    cmap = matplotlib.colormaps[name]  # pyplot.get_cmap's, without pyplot
    reserved = np.array([matplotlib.colors.to_rgb(c) for c in RESERVED_COLOURS]) * 255.0
    kept = []
    for i in range(cmap.N):
        d = float(np.min(np.linalg.norm(reserved - np.array(cmap(i)[:3]) * 255.0, axis=1)))
        if d >= MIN_COLOUR_DISTANCE:
            kept.append((d < CLEAR_COLOUR_DISTANCE, cmap(i)))
    return [c for _, c in sorted(kept, key=lambda k: k[0])]  # stable: the map's order within each group


def primitive_colours(plan: Plan) -> dict[str, Any]:
    """A colour per step primitive: a distinct one per informative primitive (order of first
    appearance; none that reads as a run-in, a transit or the chart: manoeuvre_palette), green
    for run-ins, grey for transit."""
    inf = list(dict.fromkeys(st.primitive for st in plan.steps if st.segment == "informative"))
    palette = manoeuvre_palette("tab10")
    if len(inf) > len(palette):
        palette = manoeuvre_palette("tab20")
    out: dict[str, Any] = {n: palette[i % len(palette)] for i, n in enumerate(inf)}
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


def map_view(plan: Plan, pad_m: float | None = None) -> tuple[float, float, float, float, float, float]:
    """(lon0, lat0, lon1, lat1, m per degree lon, m per degree lat) of the map window (``pad_m``
    metres round the track; None: room for the sea-room band and the markers)."""
    lon, lat = plan.lonlat[:, 0], plan.lonlat[:, 1]
    m_per_deg_lat = 111_320.0
    m_per_deg_lon = m_per_deg_lat * math.cos(math.radians(float(np.mean(lat))))
    if pad_m is None:  # room for the sea-room band and the markers
        pad_m = max(1.5 * (0.5 * plan.hull[1] + plan.margin_m), 3.0 * plan.hull[0], 1.0)
    pad = max(pad_m, 0.08 * max((lon.max() - lon.min()) * m_per_deg_lon, (lat.max() - lat.min()) * m_per_deg_lat))
    return (
        lon.min() - pad / m_per_deg_lon,
        lat.min() - pad / m_per_deg_lat,
        lon.max() + pad / m_per_deg_lon,
        lat.max() + pad / m_per_deg_lat,
        m_per_deg_lon,
        m_per_deg_lat,
    )


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
        xy = np.concatenate(verts)
        # add_artist, not add_patch: add_patch finds the patch's data limits by walking its path segment by segment in
        # Python (a chart's rings: some 0.03 s of a track figure's CPU); a polygon's limits are its vertices' (update_datalim)
        ax.add_artist(PathPatch(MPath(xy, np.concatenate(codes)), **kw))
        ax.update_datalim(xy)
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


def _draw_chart(ax: Any, plan: Plan, sea_map: Any, view: Any) -> None:
    """Depth areas (blue shades, deeper lighter), land (tan) and other no-go water (hatched:
    shallow for the ship, restricted, charted obstacles)."""
    from maps.export.chart import plan_chart

    chart = plan_chart(plan, sea_map)
    if chart is None:
        return
    layers, face, label = depth_layers(chart)
    any_drawn = False
    for g, shade in layers:
        any_drawn |= _draw_geom(ax, g, view, facecolor=shade, edgecolor=DEPTH_EDGE, lw=0.4, zorder=0.5)
    if any_drawn:
        ax.fill([], [], facecolor=face, edgecolor=DEPTH_EDGE, label=label)
    if _draw_geom(ax, chart.no_go, view, facecolor=NO_GO_COLOUR, edgecolor=NO_GO_EDGE, hatch="////", lw=0.6, zorder=1):
        ax.fill([], [], facecolor=NO_GO_COLOUR, edgecolor=NO_GO_EDGE, hatch="////", label=NO_GO_LABEL)
    if _draw_geom(ax, chart.land, view, facecolor=LAND_COLOUR, edgecolor=LAND_EDGE, lw=0.6, zorder=1):
        ax.fill([], [], facecolor=LAND_COLOUR, edgecolor=LAND_EDGE, label="land")


def _draw_track(ax: Any, plan: Plan) -> None:
    lon, lat = plan.lonlat[:, 0], plan.lonlat[:, 1]
    colours = primitive_colours(plan)
    labelled: set[str] = set()
    for st in plan.steps:
        sl = step_slice(plan, st)
        seg = st.segment
        key = st.primitive if seg == "informative" else seg
        label = None if key in labelled else track_label(plan, st)
        labelled.add(key)
        style = {"run-in": {"ls": (0, (4, 2)), "lw": 1.8}, "transit": {"ls": "-", "lw": 1.1}}.get(seg, {"ls": "-", "lw": 2.2})
        ax.plot(lon[sl], lat[sl], color=step_colour(plan, st, colours), zorder=3, solid_capstyle="butt", label=label, **style)
    execs = [st for st in plan.steps if getattr(st, "execute", False)]
    if execs:
        ax.plot(
            [st.entry_lon for st in execs],
            [st.entry_lat for st in execs],
            ls="none",
            marker="*",
            ms=15,
            mfc=EXECUTE_COLOUR,
            mec="k",
            mew=0.8,
            zorder=4.5,
            label="execute point",
        )
    ax.plot(lon[0], lat[0], marker="^", ms=11, color="green", mec="k", zorder=4, ls="none", label="start")
    ax.plot(lon[-1], lat[-1], marker="s", ms=END_MARKER_PT, color="red", mec="k", zorder=4, ls="none", label="end")


def track_label(plan: Plan, st: PlanStep) -> str:
    """The legend's words for the line of ``st`` (one entry per colour): a manoeuvre by its
    bridge name with the design's code in brackets, as the step table names it; run-ins and stops,
    transit by their phase."""
    if st.segment == "informative":
        return f"{manoeuvre_name(plan, st)} [{st.primitive}]"
    return {"run-in": "run-in, or stop before a manoeuvre", "transit": "transit"}.get(st.segment, st.segment)


def annotate_steps(ax: Any, plan: Plan) -> None:
    """Every step's number in a circle, placed by :func:`maps.export.labels.place_labels` in the
    axes' present layout (call it once the figure's size and the axes' limits are final): up and
    right of the entry point, or set aside with a leader line where that place is taken."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextToPath

    from maps.export.labels import place_labels

    ax.apply_aspect()
    fig = ax.figure
    to_pt = 72.0 / fig.dpi
    trans = ax.transData
    anchors = trans.transform(np.array([[st.entry_lon, st.entry_lat] for st in plan.steps])) * to_pt
    track = trans.transform(plan.lonlat[:, :2]) * to_pt
    bb = ax.get_window_extent()
    frame = (bb.x0 * to_pt, bb.y0 * to_pt, bb.x1 * to_pt, bb.y1 * to_pt)
    inside = [k for k, (x, y) in enumerate(anchors) if frame[0] <= x <= frame[2] and frame[1] <= y <= frame[3]]
    texts = [str(plan.steps[k].index + 1) for k in inside]
    prop = FontProperties(family="DejaVu Sans", weight="bold", size=LABEL_FS)
    widths = [TextToPath().get_text_width_height_descent(s, prop, ismath=False)[0] for s in texts]
    radii = [0.5 * max(w, 1.17 * LABEL_FS) + 0.15 * LABEL_FS for w in widths]
    colours = primitive_colours(plan)
    for k, lab in zip(inside, place_labels(texts, anchors[inside], radii, track, frame)):
        st = plan.steps[k]
        colour = step_colour(plan, st, colours)
        ax.annotate(
            lab.text,
            (st.entry_lon, st.entry_lat),
            xytext=(lab.x - lab.anchor[0], lab.y - lab.anchor[1]),
            textcoords="offset points",
            fontsize=LABEL_FS,
            fontweight="bold",
            ha="center",
            va="center",
            zorder=5,
            gid=f"step-label-{lab.text}",
            bbox={"boxstyle": "circle,pad=0.15", "fc": "white", "ec": colour, "lw": 1.2},
            arrowprops={"arrowstyle": "-", "color": colour, "lw": 0.7, "shrinkA": 0, "shrinkB": 0} if lab.moved else None,
        )


LABEL_FS = 7.0


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


def m_per_deg(view: Any) -> tuple[float, float]:
    """Metres a degree of longitude and of latitude at the middle of ``view`` (a lon/lat box)."""
    lat = 0.5 * (view.bounds[1] + view.bounds[3])
    return 111_320.0 * math.cos(math.radians(lat)), 111_320.0


def draw_map(
    ax: Any, plan: Plan, sea_map: Any = None, *, pad_m: float | None = None, numbers: bool = True, sea_room: bool = True
) -> None:
    """Chart (depth areas, land, shallow/restricted water), sea room (light blue), the track
    (informative manoeuvres coloured by primitive, run-ins dashed green, transit grey), execute
    points (stars), numbered manoeuvre starts, start/end marks, a scale bar and a north arrow,
    on lon/lat axes. ``sea_map``: see the module docstring (default: the plan's own chart)."""
    from matplotlib.ticker import MaxNLocator
    from shapely.geometry import box

    x0, y0, x1, y1, m_per_deg_lon, m_per_deg_lat = map_view(plan, pad_m)
    view = box(x0, y0, x1, y1)
    _draw_chart(ax, plan, sea_map, view)
    if sea_room:
        from maps.export.geojson import sea_room_lonlat

        room = sea_room_lonlat(plan)
        if room is not None and _draw_geom(ax, room, view, facecolor=SEA_ROOM_COLOUR, edgecolor="none", zorder=2):
            ax.fill([], [], facecolor=SEA_ROOM_COLOUR, label="sea room (hull + margin)")
    _draw_track(ax, plan)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    lat0 = float(np.mean(plan.lonlat[:, 1]))
    ax.set_aspect(1.0 / math.cos(math.radians(lat0)))
    ax.set_facecolor(WATER_COLOUR)
    ax.xaxis.set_major_formatter(_dm_formatter("E", "W", 3))
    ax.yaxis.set_major_formatter(_dm_formatter("N", "S", 2))
    ax.tick_params(labelsize=7)
    ax.xaxis.set_major_locator(MaxNLocator(4))
    ax.grid(color="white", lw=0.6, zorder=0)
    _scale_bar(ax, x0, y0, x1, y1, m_per_deg_lon)
    nx, ny = north_place(plan.lonlat[:, :2], (x0, y0, x1, y1))  # a corner the track keeps clear of
    ax.annotate(
        "N",
        xy=(nx, ny[1]),
        xytext=(nx, ny[0]),
        xycoords="axes fraction",
        ha="center",
        fontsize=NORTH_FS,
        fontweight="bold",
        arrowprops={"arrowstyle": "-|>", "color": "k"},
        zorder=6,
    )
    if numbers:
        annotate_steps(ax, plan)


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
