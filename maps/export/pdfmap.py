"""The map of the trial card's page 1 drawn straight into the PDF with fpdf2: the chart's
polygons, the hatching, the sea room, the track, markers, numbers, ticks, scale bar, north arrow
and legend as PDF path operators and text in the card's embedded font.

It draws what :func:`maps.export.mapplot.draw_map` draws (same view, aspect, colours -- the
style constants of :mod:`maps.export.mapplot` --, line widths, markers, ticks and legend as the
matplotlib axes of :func:`maps.export.mapplot.draw_map` with the legend below the map)
without the round trip the card made before: matplotlib drawing the figure, writing it as SVG and
fpdf2 parsing the SVG back cost about half the CPU of the whole card.

The operators are written by :class:`maps.export.pdfdraw.Painter`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from maps.export._common import deg_min, step_slice
from maps.export.labels import END_MARKER_PT, NORTH_FS, Label, leader, north_place, place_labels
from maps.export.mapplot import (
    DEPTH_EDGE,
    EXECUTE_COLOUR,
    HATCH_PT,
    LAND_COLOUR,
    LAND_EDGE,
    NO_GO_COLOUR,
    NO_GO_EDGE,
    NO_GO_LABEL,
    SEA_ROOM_COLOUR,
    WATER_COLOUR,
    depth_layers,
    hatch_segments,
    lon_ticks,
    m_per_deg,
    map_view,
    primitive_colours,
    scale_bar,
    step_colour,
    track_label,
)
from maps.export.pdfdraw import LINE_HEIGHT, Painter, col, rings_ops
from maps.plan import Plan, PlanStep

TICK_FS, NUM_FS, LEGEND_FS = 7.0, 7.0, 6.5


@dataclass
class Frame:
    """The map axes on the page: lon/lat -> PDF points (y up, from the page's bottom)."""

    x0: float
    y0: float
    x1: float
    y1: float
    left: float  # axes box, PDF points from the page's left and bottom
    bottom: float
    width: float
    height: float
    m_per_deg: tuple[float, float] = field(default=(1.0, 1.0))

    def xy(self, lonlat: np.ndarray) -> np.ndarray:
        c = np.asarray(lonlat, dtype=float)[:, :2]
        return np.column_stack(
            [
                self.left + (c[:, 0] - self.x0) / (self.x1 - self.x0) * self.width,
                self.bottom + (c[:, 1] - self.y0) / (self.y1 - self.y0) * self.height,
            ]
        )

    def m_per_pt(self) -> float:
        return max((self.x1 - self.x0) * self.m_per_deg[0] / self.width, (self.y1 - self.y0) * self.m_per_deg[1] / self.height)


def map_frame(plan: Plan, box: tuple[float, float, float, float]) -> Frame:
    """The view of :func:`maps.export.mapplot.draw_map` placed in ``box`` (left, bottom, width,
    height in PDF points) as matplotlib places an axes of fixed aspect: shrunk to the map's aspect
    (1 / cos of the track's mean latitude), centred."""
    x0, y0, x1, y1, _, _ = map_view(plan)
    lat0 = float(np.mean(plan.lonlat[:, 1]))
    ratio = (y1 - y0) / math.cos(math.radians(lat0)) / (x1 - x0)  # height / width on the page
    left, bottom, bw, bh = box
    if bh / bw > ratio:
        w, h = bw, bw * ratio
    else:
        w, h = bh / ratio, bh
    from shapely.geometry import box as sbox

    return Frame(x0, y0, x1, y1, left + 0.5 * (bw - w), bottom + 0.5 * (bh - h), w, h, m_per_deg(sbox(x0, y0, x1, y1)))


def _geom_rings(geom: Any, view: Any) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Polygon rings and line strings of ``geom`` inside ``view`` (lon/lat)."""
    if geom is None or geom.is_empty or not geom.intersects(view):
        return [], []
    rings: list[np.ndarray] = []
    lines: list[np.ndarray] = []
    stack = [geom.intersection(view)]
    while stack:
        g = stack.pop()
        if g.is_empty:
            continue
        if g.geom_type == "Polygon":
            rings += [np.asarray(r.coords) for r in (g.exterior, *g.interiors)]
        elif g.geom_type in ("LineString", "LinearRing"):
            lines.append(np.asarray(g.coords))
        elif hasattr(g, "geoms"):
            stack.extend(reversed(list(g.geoms)))
    return rings, lines


class MapWriter(Painter):
    """Writes the map into the current page of an fpdf2 document (unit pt)."""

    def __init__(self, pdf: Any, font: str, plan: Plan, chart: Any, frame: Frame) -> None:
        from shapely.geometry import box

        super().__init__(pdf, font)
        self.plan, self.chart, self.f = plan, chart, frame
        self.view = box(frame.x0, frame.y0, frame.x1, frame.y1)
        self.legend: list[dict[str, Any]] = []

    def page_xy(self, lonlat: np.ndarray) -> np.ndarray:
        return self.f.xy(lonlat)

    def fill_geom(self, geom: Any, face: Any, edge: Any | None, lw: float) -> bool:
        rings, lines = _geom_rings(geom, self.view)
        if rings:
            style = "B*" if edge is not None else "f*"
            ops = [col(face, "rg"), f"{lw:.2f} w 0 j"]
            if edge is not None:
                ops.append(col(edge, "RG"))
            self.out("\n".join(ops) + "\n" + rings_ops([self.page_xy(r) for r in rings]) + f" {style}")
        if lines:
            self.out(f"{col(edge or 'k', 'RG')} 0.8 w\n" + rings_ops([self.page_xy(c) for c in lines], close=False) + " S")
        return bool(rings or lines)

    def marker(self, kind: str, x: float, y: float, size: float, face: Any, edge: Any = "k", mew: float = 1.0) -> None:
        """matplotlib's '*', '^' and 's' markers, ``size`` points across."""
        r = 0.5 * size
        if kind == "*":
            a = np.pi / 2 + np.arange(10) * np.pi / 5
            rad = np.where(np.arange(10) % 2 == 0, r, r * 0.381966)
            pts = np.column_stack([x + rad * np.cos(a), y + rad * np.sin(a)])
        elif kind == "^":
            pts = np.array([[x, y + r], [x - r, y - r], [x + r, y - r]])
        else:
            pts = np.array([[x - r, y - r], [x + r, y - r], [x + r, y + r], [x - r, y + r]])
        self.out(f"{col(face, 'rg')} {col(edge, 'RG')} {mew:.2f} w 0 j [] 0 d\n" + rings_ops([pts]) + " B")

    def circle(self, x: float, y: float, r: float, face: Any, edge: Any, lw: float) -> None:
        k = 0.5523 * r  # four Bezier quarter arcs
        self.out(
            f"{col(face, 'rg')} {col(edge, 'RG')} {lw:.2f} w [] 0 d\n"
            f"{x + r:.2f} {y:.2f} m {x + r:.2f} {y + k:.2f} {x + k:.2f} {y + r:.2f} {x:.2f} {y + r:.2f} c "
            f"{x - k:.2f} {y + r:.2f} {x - r:.2f} {y + k:.2f} {x - r:.2f} {y:.2f} c "
            f"{x - r:.2f} {y - k:.2f} {x - k:.2f} {y - r:.2f} {x:.2f} {y - r:.2f} c "
            f"{x + k:.2f} {y - r:.2f} {x + r:.2f} {y - k:.2f} {x + r:.2f} {y:.2f} c h B"
        )

    # -- the map -------------------------------------------------------------------------------------
    def draw(self) -> None:
        f = self.f
        self.out(f"q {f.left:.2f} {f.bottom:.2f} {f.width:.2f} {f.height:.2f} re W n")
        self.out(f"{col(WATER_COLOUR, 'rg')} {f.left:.2f} {f.bottom:.2f} {f.width:.2f} {f.height:.2f} re f")
        xt, yt = self.ticks()
        self.chart_layers()
        # the grid goes with the axis, which matplotlib draws at zorder 1.5: over the chart, under the sea room
        grid = [np.array([[x, f.bottom], [x, f.bottom + f.height]]) for x in xt]
        grid += [np.array([[f.left, y], [f.left + f.width, y]]) for y in yt]
        if grid:
            self.out(f"{col('white', 'RG')} 0.6 w 2 J [] 0 d\n" + rings_ops(grid, close=False) + " S")
        self.sea_room()
        self.track()
        self.out("Q")
        self.numbers()
        self.furniture(xt, yt)

    def chart_layers(self) -> None:
        chart = self.chart
        if chart is None:
            return
        layers, face, label = depth_layers(chart)
        drawn = False
        for g, shade in layers:
            drawn |= self.fill_geom(g, shade[:3], DEPTH_EDGE, 0.4)
        if drawn:
            self.legend.append({"kind": "patch", "face": face[:3], "edge": DEPTH_EDGE, "label": label})
        if self.fill_geom(chart.no_go, NO_GO_COLOUR, NO_GO_EDGE, 0.6):
            segs = hatch_segments(chart.no_go, self.view, self.f.m_per_deg, self.f.m_per_pt())
            if segs:
                self.out(
                    f"{col(NO_GO_EDGE, 'RG')} 0.6 w 2 J [] 0 d\n" + rings_ops([self.page_xy(s) for s in segs], close=False) + " S"
                )
            self.legend.append({"kind": "hatch", "face": NO_GO_COLOUR, "edge": NO_GO_EDGE, "label": NO_GO_LABEL})
        if self.fill_geom(chart.land, LAND_COLOUR, LAND_EDGE, 0.6):
            self.legend.append({"kind": "patch", "face": LAND_COLOUR, "edge": LAND_EDGE, "label": "land"})

    def sea_room(self) -> None:
        from maps.export.geojson import sea_room_lonlat

        room = sea_room_lonlat(self.plan)
        if room is not None and self.fill_geom(room, SEA_ROOM_COLOUR, None, 0.0):
            self.legend.append({"kind": "patch", "face": SEA_ROOM_COLOUR, "edge": None, "label": "sea room (hull + margin)"})

    def track(self) -> None:
        plan = self.plan
        colours = primitive_colours(plan)
        labelled: set[str] = set()
        xy = self.page_xy(plan.lonlat)
        for st in plan.steps:
            seg = st.segment
            key = st.primitive if seg == "informative" else seg
            lw, dash = {"run-in": (1.8, (4 * 1.8, 2 * 1.8)), "transit": (1.1, None)}.get(seg, (2.2, None))
            colour = step_colour(plan, st, colours)
            pts = xy[step_slice(plan, st)]
            if len(pts) >= 2:
                self.polyline(pts, colour, lw, dash)
            if key not in labelled:
                self.legend.append({"kind": "line", "colour": colour, "lw": lw, "dash": dash, "label": track_label(plan, st)})
                labelled.add(key)
        self.start_end_execute(xy)

    def start_end_execute(self, xy: np.ndarray) -> None:
        plan = self.plan
        self.marker("^", *xy[0], 11, "green")
        self.marker("s", *xy[-1], END_MARKER_PT, "red")
        execs = [st for st in plan.steps if getattr(st, "execute", False)]
        for st in execs:
            self.marker("*", *self.page_xy(np.array([[st.entry_lon, st.entry_lat]]))[0], 15, EXECUTE_COLOUR, mew=0.8)
        if execs:
            self.legend.append(
                {"kind": "marker", "marker": "*", "size": 15, "face": EXECUTE_COLOUR, "mew": 0.8, "label": "execute point"}
            )
        self.legend.append({"kind": "marker", "marker": "^", "size": 11, "face": "green", "mew": 1.0, "label": "start"})
        self.legend.append({"kind": "marker", "marker": "s", "size": END_MARKER_PT, "face": "red", "mew": 1.0, "label": "end"})

    def numbers(self) -> None:
        """Every step's number in a circle: up and right of its entry point, or set aside with a
        leader line where that place is taken (:func:`maps.export.labels.place_labels`)."""
        plan = self.plan
        colours = primitive_colours(plan)
        labels = step_labels(plan, self.f, lambda s: self.text_width(s, NUM_FS, bold=True))
        for st, lab in labels:
            colour = step_colour(plan, st, colours)
            self.out("q")
            if lab.moved:
                self.polyline(leader(lab), colour, 0.7)
            self.circle(lab.x, lab.y, lab.r, "white", colour, 1.2)
            self.out("Q")
            self.text(lab.x, lab.y, lab.text, NUM_FS, bold=True, ha="center", va="center")

    def ticks(self) -> tuple[list[float], list[float]]:
        """Tick positions on the page: matplotlib's MaxNLocator along x (4 intervals, fewer on a narrow
        map: :func:`maps.export.mapplot.lon_ticks`), its AutoLocator along y."""
        from matplotlib.ticker import MaxNLocator

        f = self.f
        xs = lon_ticks(f.x0, f.x1, f.width)
        nbins = int(np.clip(math.floor(f.height / (TICK_FS * 2)), 1, 9))
        ys = [v for v in MaxNLocator(nbins, steps=[1, 2, 2.5, 5, 10]).tick_values(f.y0, f.y1) if f.y0 <= v <= f.y1]
        self._tick_values = (xs, ys)
        return (
            [f.left + (v - f.x0) / (f.x1 - f.x0) * f.width for v in xs],
            [f.bottom + (v - f.y0) / (f.y1 - f.y0) * f.height for v in ys],
        )

    def furniture(self, xt: list[float], yt: list[float]) -> None:
        """Scale bar, north arrow, frame, ticks and tick labels."""
        f = self.f
        bx, by, length, label = scale_bar(f.x0, f.y0, f.x1, f.y1, f.m_per_deg[0])
        (p0, p1) = self.page_xy(np.array([[bx, by], [bx + length, by]]))
        self.out("q")
        self.polyline(np.array([p0, p1]), "k", 3.0, cap=2)
        # north arrow: from above the "N" to the tip, a filled head as '-|>', in the corner the PNG map uses
        fs = NORTH_FS
        nx, ny = north_place(self.plan.lonlat[:, :2], (f.x0, f.y0, f.x1, f.y1))
        ax_, ay0, ay1 = (
            f.left + nx * f.width,
            f.bottom + ny[0] * f.height + 0.76 * fs + 2,
            f.bottom + ny[1] * f.height - 2,
        )
        head = 0.4 * fs
        self.polyline(np.array([[ax_, ay0], [ax_, ay1 - head]]), "k", 1.0)
        self.out(
            f"{col('k', 'rg')} {ax_:.2f} {ay1:.2f} m {ax_ - 0.2 * fs:.2f} {ay1 - head:.2f} l {ax_ + 0.2 * fs:.2f} "
            f"{ay1 - head:.2f} l h B"
        )
        self.out(f"{col('k', 'RG')} 0.8 w 0 J 0 j [] 0 d {f.left:.2f} {f.bottom:.2f} {f.width:.2f} {f.height:.2f} re S")
        ticks = [np.array([[x, f.bottom], [x, f.bottom - 3.5]]) for x in xt] + [
            np.array([[f.left, y], [f.left - 3.5, y]]) for y in yt
        ]
        if ticks:
            self.out("0.8 w\n" + rings_ops(ticks, close=False) + " S")
        self.out("Q")
        self.text(0.5 * (p0[0] + p1[0]), p0[1] + 0.012 * f.height, label, 7, ha="center", va="bottom")
        self.text(ax_, f.bottom + ny[0] * f.height, "N", fs, bold=True, ha="center")
        xs, ys = self._tick_values
        for x, v in zip(xt, xs):
            self.text(x, f.bottom - 7.0, deg_min(v, "E", "W", 3).replace("'", "′"), TICK_FS, ha="center", va="top")
        for y, v in zip(yt, ys):
            self.text(f.left - 7.0, y, deg_min(v, "N", "S", 2).replace("'", "′"), TICK_FS, ha="right", va="center")

    # -- the legend ----------------------------------------------------------------------------------
    def draw_legend(self, ncol: int = 3) -> None:
        """The legend below the map, centred (matplotlib's loc="upper center" at (0.5, -0.05) of
        the axes, ``ncol`` columns filled top to bottom, its paddings in font sizes); fewer
        columns when the manoeuvres' names would take it past the page's 18 pt margins."""
        fs, f = LEGEND_FS, self.f
        entries = self.legend
        if not entries:
            return
        row_h = 1.0 * fs  # matplotlib packs legend rows by the texts' ink height, about the font size
        pitch = row_h + 0.5 * fs
        hl, htp, pad = 2.0 * fs, 0.8 * fs, 0.4 * fs
        centre = f.left + 0.5 * f.width
        room = 2.0 * (min(centre, float(self.pdf.w) - centre) - 18.0)
        for n in range(ncol, 0, -1):
            cols = [c for c in np.array_split(np.arange(len(entries)), n) if len(c)]
            widths = [hl + htp + max(self.text_width(entries[i]["label"], fs) for i in c) for c in cols]
            width = sum(widths) + 2.0 * fs * (len(cols) - 1) + 2 * pad
            if width <= room:
                break
        height = pitch * max(len(c) for c in cols) - 0.5 * fs + 2 * pad
        left = f.left + 0.5 * f.width - 0.5 * width
        top = f.bottom - 0.05 * f.height - 0.5 * fs
        self.out(
            f"q {col('white', 'rg')} {col('0.8', 'RG')} 1 w [] 0 d {left:.2f} {top - height:.2f} {width:.2f} {height:.2f} re B Q"
        )
        x = left + pad
        for c, w in zip(cols, widths):
            for k, i in enumerate(c):
                yc = top - pad - k * pitch - 0.5 * row_h
                self.out("q")
                self._handle(entries[i], x, yc, hl, 0.7 * fs)
                self.out("Q")
                self.text(x + hl + htp, yc, entries[i]["label"], fs, va="center")
            x += w + 2.0 * fs

    def _handle(self, e: dict[str, Any], x: float, yc: float, w: float, h: float) -> None:
        kind = e["kind"]
        if kind == "line":
            self.polyline(np.array([[x, yc], [x + w, yc]]), e["colour"], e["lw"], e["dash"])
        elif kind == "marker":
            self.marker(e["marker"], x + 0.5 * w, yc, e["size"], e["face"], mew=e["mew"])
        else:
            edge = e["edge"]
            ops = f"{col(e['face'], 'rg')} {x:.2f} {yc - 0.5 * h:.2f} {w:.2f} {h:.2f} re "
            self.out((f"{col(edge, 'RG')} 1 w [] 0 d " + ops + "B") if edge is not None else ops + "f")
            if kind == "hatch":
                segs = []
                for t in np.arange(-h, w, HATCH_PT):
                    a, b = max(t, 0.0), min(t + h, w)
                    segs.append(np.array([[x + a, yc - 0.5 * h + a - t], [x + b, yc - 0.5 * h + b - t]]))
                self.out(f"{col(edge, 'RG')} 0.6 w\n" + rings_ops(segs, close=False) + " S")


def step_labels(plan: Plan, f: Frame, width: Callable[[str], float]) -> list[tuple[PlanStep, Label]]:
    """(step, label) of every step whose entry point is on the map ``f``: number circles sized
    for their text (``width(text)`` in points at NUM_FS bold), clear of each other and of the
    track. A step entered outside the map has no label (as matplotlib drops an annotation whose
    point is outside the axes)."""
    xy = f.xy(np.array([[st.entry_lon, st.entry_lat] for st in plan.steps]))
    inside = [k for k, (x, y) in enumerate(xy) if f.left <= x <= f.left + f.width and f.bottom <= y <= f.bottom + f.height]
    texts = [str(plan.steps[k].index + 1) for k in inside]
    radii = [0.5 * max(width(s), LINE_HEIGHT * NUM_FS) + 0.15 * NUM_FS for s in texts]
    labels = place_labels(texts, xy[inside], radii, f.xy(plan.lonlat), (f.left, f.bottom, f.left + f.width, f.bottom + f.height))
    return [(plan.steps[k], lab) for k, lab in zip(inside, labels)]


def draw_page1_map(pdf: Any, font: str, plan: Plan, chart: Any, box: tuple[float, float, float, float]) -> None:
    """The map of page 1 with its legend below, the axes in ``box`` (left, bottom, width, height
    in PDF points from the page's bottom left)."""
    w = MapWriter(pdf, font, plan, chart, map_frame(plan, box))
    w.draw()
    w.draw_legend()
