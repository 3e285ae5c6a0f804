"""Trial card for the bridge: a self-contained HTML page (PNG figures embedded as data URIs)
and a printable PDF (A4, TrueType fonts embedded; written with fpdf2 by :mod:`maps.export.cardpdf`
from the words, tables and page layout made here).

Page 1: the plan at a glance (ship, start, totals, abort criteria, the experiment design's
D-efficiency), the map with land, shallow/restricted water and depth areas, the track
(informative manoeuvres coloured by primitive like Fig. 9.13 of seed 001, run-ins dashed,
transit grey) with execute points and step numbers. Then the table of every step (continued
over as many pages as it needs) and of the design's weights and counts; then per step: the
execute (or start) waypoint, heading and speed there, the orders in the ship's own terms
(rudder and engine, or azimuth angle and rpm), expected duration, sea room and abort criteria.
Last page: speed, heading and inputs over time.
"""

from __future__ import annotations

import base64
import html
import math
import re
import textwrap
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np

from maps.export._common import (
    HTML_GENERATOR_META,
    KN_PER_MPS,
    check_plan,
    clock,
    cross_track,
    input_phases,
    latlon_dm,
    resolve_start,
    step_abort,
    vessel_name,
    waypoints,
)
from maps.export.cardsummary import DESIGN_COLS, design_rows, summary_lines
from maps.export.chart import plan_chart
from maps.export.figures import PlanFigures
from maps.export.route import build_route
from maps.export.wording import bridge_orders, knots, manoeuvre_name, phase
from maps.plan import Plan
from primitives.io import atomic_write_bytes, atomic_write_text

A4 = (8.27, 11.69)
_BFT = [0.3, 1.6, 3.4, 5.5, 8.0, 10.8, 13.9, 17.2, 20.8, 24.5, 28.5, 32.7]


def beaufort(wind_mps: float) -> int:
    """Beaufort number of a wind speed (WMO upper limits in m/s)."""
    return int(np.searchsorted(_BFT, wind_mps, side="left"))


def _m(metres: float) -> str:
    return f"{metres:.0f} m" if abs(metres) >= 10 else f"{metres:.1f} m"


def abort_criteria(plan: Plan) -> list[str]:
    """Plan-wide abort criteria in plain words."""
    w = plan.max_wind_mps
    # an open-water map has no obstacle to measure against: "planned minimum none within the map"
    # read as a missing figure on the card, so say what the chart shows instead
    clear = (
        f"planned minimum {plan.min_clearance_m:.0f} m"
        if math.isfinite(plan.min_clearance_m)
        else "the chart shows none near the track"
    )
    return [
        f"true wind above {w * KN_PER_MPS:.0f} kn (Beaufort {beaufort(w)})",
        f"distance from the hull to land, shallows or any obstacle below {plan.margin_m:.0f} m ({clear})",
        "the ship leaves the corridor of the leg (cross-track limits below) or traffic comes within the sea room",
    ]


def _step_legs(plan: Plan, sea_map: Any) -> dict[int, tuple[str, str, list[str], float, float]]:
    """Per step index: its route waypoint, the waypoint where it ends, the waypoints between
    (via points) and the tightest port / starboard cross-track limits (m) of its legs, from the
    same route the RTZ file holds (numbers agree with the ECDIS)."""
    route = build_route(plan, plan_chart(plan, sea_map))
    out = {}
    pts = route.points
    for j, pt in enumerate(pts):
        if pt.step is None:
            continue
        k = j + 1
        while k < len(pts) - 1 and pts[k].step is None:
            k += 1
        legs = [route.legs[m] for m in range(j + 1, k + 1)]
        out[pt.step.index] = (
            pts[j].name.split()[0],
            pts[k].name.split()[0],
            [pts[m].name.split()[0] for m in range(j + 1, k)],
            min(g.port_m for g in legs),
            min(g.stbd_m for g in legs),
        )
    return out


def step_sheets(plan: Plan, start: datetime | str | None = None, sea_map: Any = None) -> list[dict[str, Any]]:
    """Per step, the card's facts as text: where and when it starts (the execute waypoint of
    a manoeuvre, numbered as in the RTZ route), heading and speed there, the orders in the
    ship's own terms, expected duration, sea room, where it ends, and its abort criteria
    (its own, clearance, the route's land-free cross-track limits, wind)."""
    t0 = resolve_start(plan, start)
    wps = waypoints(plan)
    legs = _step_legs(plan, sea_map)
    half = 0.5 * plan.hull[1] + plan.margin_m
    out = []
    for i, wp in enumerate(wps[:-1]):
        st = wp.step
        nxt = wps[i + 1]
        if st.index in legs:
            here, there, via, port, stbd = legs[st.index]
        else:  # a step without samples of its own
            stbd, port = (v + half for v in cross_track(plan, wps, i + 1))
            here, there, via = wp.name.split()[0], nxt.name.split()[0], []
        line = " -> ".join([here, *via, there])
        orders = bridge_orders(plan, st)
        out.append(
            {
                "n": st.index + 1,
                "primitive": st.primitive,  # the design's code, in small print beside the name
                "name": manoeuvre_name(plan, st),
                "kind": st.kind,
                "segment": phase(plan, st),
                "execute": bool(getattr(st, "execute", False)),
                "waypoint": here,
                "start": f"+{clock(wp.t_s)} ({(t0 + timedelta(seconds=wp.t_s)).strftime('%H:%M:%S')} UTC)",
                "position": latlon_dm(wp.lat, wp.lon),
                "heading": f"{wp.heading_deg:03.0f}°",
                "speed": f"{wp.speed_kn:.1f} kn",
                "orders": orders,
                # the planned inputs read as timed settings only where the step has no orders of its own
                "settings": [] if orders else input_phases(plan, st),
                "duration": clock(st.duration_s),
                "space": f"{_m(st.space_m[0])} along x {_m(st.space_m[1])} across",
                "ends": f"at {there} {latlon_dm(nxt.lat, nxt.lon)}, heading {nxt.heading_deg:03.0f}°, {nxt.speed_kn:.1f} kn",
                "abort": [
                    *(knots(a) for a in step_abort(plan, st)),
                    f"more than {port:.0f} m to port or {stbd:.0f} m to starboard of the line {line} "
                    "(the route's land-free cross-track limits)",
                    f"wind above {plan.max_wind_mps * KN_PER_MPS:.0f} kn",
                ],
            }
        )
    return out


# heading and speed in the steps table are the ship's at the step's start waypoint: unsaid, "steady
# approach at 2.2 kn | 5.8 kn" and "turn on the spot | 5.8 kn" read as contradictions (a one-line
# note, not longer column heads: a taller head row pushed the PDF's 44th row to the next page)
STEPS_NOTE = "hdg and speed: the ship's at the step's start waypoint (WP)"
STEPS_NOTE_PDF = "hdg, speed at start WP"  # in the PDF table's title, which is not wrapped


# -- PDF pages --------------------------------------------------------------------------------

TABLE_COLS = ["#", "phase", "manoeuvre (design code)", "WP", "start (UTC)", "position", "hdg", "speed", "time", "sea room"]
TABLE_WIDTHS = [0.03, 0.07, 0.22, 0.045, 0.15, 0.205, 0.04, 0.055, 0.045, 0.12]
ROWS_PER_PAGE = 44


def _code(s: dict) -> str:
    """The design's or planner's code of a step, in brackets (none for a run-in or stop: it
    carries the code of the manoeuvre it leads to; none for a straightened transit)."""
    return "" if s["segment"] in ("run-in", "stop") or s["primitive"] == "transit" else f" [{s['primitive']}]"


def _table_rows(sheets: list[dict]) -> list[list[str]]:
    """The steps in sailing order, names in full (the PDF wraps a long one in its cell)."""
    return [
        [
            str(s["n"]),
            s["segment"],
            s["name"] + _code(s),
            s["waypoint"],
            s["start"].replace(" UTC", ""),
            s["position"],
            s["heading"],
            s["speed"],
            s["duration"],
            re.sub(r" m along x (.*) m across$", r" x \1 m", s["space"]),
        ]
        for s in sheets
    ]


# the PDF's tables keep the look of the matplotlib.table the card was first drawn with
TABLE_PAD = 0.02  # gap above a table (matplotlib.table's AXESPAD for loc "upper center")
CELL_PAD = 0.1  # text inset as a fraction of the cell width (matplotlib.table.Cell.PAD)


PAGE1_CHARS = 110


def page1_layout(plan: Plan, t0: datetime, sea_map: Any, vessel: str) -> tuple[list[str], list[str], float, float]:
    """Page 1's summary lines, abort box lines, the abort box's top and the map's top (figure fractions)."""
    d_head, _ = design_rows(plan)
    # wrapped to the page (8.5 pt DejaVu Sans, 0.9 of A4's width: some 110 characters): a long
    # list of unused manoeuvres ran off the page's edge
    lines = [
        w
        for line in summary_lines(plan, t0, vessel, sea_map) + d_head
        for w in textwrap.wrap(line, PAGE1_CHARS, subsequent_indent="    ", break_on_hyphens=False) or [""]
    ]
    y = 0.935 - 0.017 * len(lines)
    abort = ["ABORT the manoeuvre (stop, steer clear) if:"] + [f"  - {a}" for a in abort_criteria(plan)]
    return lines, abort, y - 0.006, y - 0.09


def _title(s: dict) -> str:
    """A step's heading: number, phase and the manoeuvre's name ("3. EXECUTE 10/10 zig-zag to starboard")."""
    return (
        f"{s['n']}. {s['segment']}: {s['name']}"
        if s["segment"] in ("run-in", "stop", "transit")
        else f"{s['n']}. {s['segment']} {s['name']}"
    )


WRAP = 100  # characters of an 8.5 pt line on the card's A4 text width


def _detail_blocks(sheets: list[dict]) -> list[list[tuple[str, dict]]]:
    """Per step, the lines of its orders section (a step's lines stay on one page)."""
    blocks = []
    norm = {"fontsize": 8.5}
    red = {"fontsize": 8.5, "color": "#a00000"}
    for s in sheets:
        lines: list[tuple[str, dict]] = []
        for k, w in enumerate(textwrap.wrap(_title(s), 88)):
            lines.append(
                (w if k == 0 else f"    {w}", {"fontweight": "bold", "fontsize": 9.5, "code": _code(s).strip() if k == 0 else ""})
            )
        where = "Execute at" if s["execute"] else "Start at"
        for k, w in enumerate(
            textwrap.wrap(
                f"{where} {s['waypoint']} {s['position']}, {s['start']}, heading {s['heading']}, speed {s['speed']}", WRAP
            )
        ):
            lines.append((f"   {w}" if k == 0 else f"      {w}", norm))
        for title, items in (("Orders", s["orders"]), ("Settings", s["settings"])):
            for j, item in enumerate(items):
                for k, w in enumerate(textwrap.wrap(item, WRAP)):
                    lead = f"{title}: " if (j == 0 and k == 0) else " " * (len(title) + 2)
                    lines.append((f"   {lead}{'- ' if k == 0 else '  '}{w}", norm))
        for k, w in enumerate(textwrap.wrap(f"Expected duration {s['duration']}; sea room {s['space']}; ends {s['ends']}", WRAP)):
            lines.append((f"   {w}" if k == 0 else f"      {w}", norm))
        for a in s["abort"]:
            for k, w in enumerate(textwrap.wrap(f"Abort if {a}", WRAP)):
                lines.append((f"   {w}" if k == 0 else f"      {w}", red))
        lines.append(("", norm))
        blocks.append(lines)
    return blocks


def detail_pages(sheets: list[dict], per_page: int | None = None) -> list[list[tuple[str, dict]]]:
    """The orders per step laid out on pages of ``per_page`` lines: a step starts a new page when
    it does not fit on the present one (only a step longer than a whole page is split)."""
    per_page = per_page or DETAIL_LINES_PER_PAGE
    pages: list[list[tuple[str, dict]]] = [[]]
    for block in _detail_blocks(sheets):
        if pages[-1] and len(pages[-1]) + len(block) - 1 > per_page:  # the trailing blank line may fall off the page
            pages.append([])
        for line in block:
            if len(pages[-1]) == per_page:
                if line[0] == "":
                    continue
                pages.append([])
            pages[-1].append(line)
    return [p for p in pages if p]


DETAIL_LINES_PER_PAGE = 62


def write_card_pdf(
    plan: Plan, path: str | Path, sea_map: Any = None, start: datetime | str | None = None, vessel: str | None = None
) -> Path:
    """The printable card (A4 PDF, TrueType fonts embedded; written with fpdf2, see
    :mod:`maps.export.cardpdf`): page 1 (summary, abort criteria, design, map), the tables of
    steps and of the design, the orders per step and the states over time."""
    from maps.export.cardpdf import card_pdf_bytes

    check_plan(plan)
    t0 = resolve_start(plan, start)
    sea_map = plan_chart(plan, sea_map)  # one chart for the route, summary and map (a map file is read once)
    return atomic_write_bytes(path, card_pdf_bytes(plan, t0, sea_map, vessel_name(plan, vessel)))


# -- HTML --------------------------------------------------------------------------------------


def _img(png: bytes, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}">'


_CSS = """
body{font-family:DejaVu Sans,Arial,sans-serif;max-width:60em;margin:1em auto;color:#111;font-size:11pt}
h1{font-size:1.5em;margin:.2em 0} h2{font-size:1.15em;margin:1.2em 0 .3em;border-bottom:1px solid #999}
.abort{border:2px solid #a00000;background:#fff3f3;color:#a00000;padding:.4em .8em;margin:.6em 0}
table{border-collapse:collapse;width:100%;font-size:.9em} td,th{border:1px solid #bbb;padding:.2em .4em;text-align:left;vertical-align:top}
th{background:#eee} thead{display:table-header-group} tr{page-break-inside:avoid} img{max-width:100%}
h3{font-size:1em;margin:.8em 0 .2em} .step{page-break-inside:avoid;margin-bottom:.8em;padding-left:.5em;border-left:3px solid #ccc}
.step.exec{border-left-color:#e0a800} .step p{margin:.2em 0} .step ul{margin:.1em 0 .1em 1.2em;padding:0} .red{color:#a00000}
small.code{font-weight:normal;color:#666;font-size:.75em}
"""


def _html_table(cols: list[str], rows: list[list[str]], cls: str = "") -> str:
    e = html.escape
    h = [f"<table class='{cls}'><thead><tr>" + "".join(f"<th>{e(c)}</th>" for c in cols) + "</tr></thead><tbody>"]
    for r in rows:
        h.append("<tr>" + "".join(f"<td>{e(str(v))}</td>" for v in r) + "</tr>")
    return "\n".join(h + ["</tbody></table>"])


def _html_step(s: dict) -> str:
    e = html.escape
    cls = "step exec" if s["execute"] else "step"
    code = _code(s).strip()
    h = [
        f"<div class='{cls}'><h3>{e(_title(s))}" + (f" <small class='code'>{e(code)}</small>" if code else "") + "</h3>",
        f"<p><b>{'Execute' if s['execute'] else 'Start'} at {e(s['waypoint'])}</b> {e(s['position'])}, {e(s['start'])}, "
        f"heading <b>{e(s['heading'])}</b>, speed <b>{e(s['speed'])}</b></p>",
    ]
    if s["orders"]:
        h.append("<p><b>Orders</b></p><ul>" + "".join(f"<li>{e(o)}</li>" for o in s["orders"]) + "</ul>")
    if s["settings"]:
        h.append(
            "<p><b>Settings</b> (from the planned inputs)</p><ul>" + "".join(f"<li>{e(o)}</li>" for o in s["settings"]) + "</ul>"
        )
    h.append(f"<p><b>Expected duration</b> {e(s['duration'])}; <b>sea room</b> {e(s['space'])}; ends {e(s['ends'])}</p>")
    h.append(
        "<p class='red'><b>Abort if</b></p><ul class='red'>" + "".join(f"<li>{e(a)}</li>" for a in s["abort"]) + "</ul></div>"
    )
    return "\n".join(h)


def card_html(
    plan: Plan,
    sea_map: Any = None,
    start: datetime | str | None = None,
    vessel: str | None = None,
    figures: PlanFigures | None = None,
) -> str:
    """The card as one self-contained HTML page (every table complete; prints with repeated
    table headers). Its map and states images are the track and states PNG exports
    (``figures``: the plan's shared figures, drawn here when not given)."""
    check_plan(plan)
    t0 = resolve_start(plan, start)
    sea_map = plan_chart(plan, sea_map)  # one chart for the route, summary and map (a map file is read once)
    sheets = step_sheets(plan, t0, sea_map)
    vname = vessel_name(plan, vessel)
    e = html.escape
    with PlanFigures(plan, sea_map) as own:
        figs = figures or own
        map_png, states_png = figs.png("track"), figs.png("states")
    h = [
        f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>{HTML_GENERATOR_META}<title>Sea trial card {e(vname)}</title>",
        f"<style>{_CSS}</style></head><body>",
        f"<h1>Sea trial card: {e(vname)}</h1>",
    ]
    h += [f"<p>{e(line)}</p>" for line in summary_lines(plan, t0, vname, sea_map)]
    h.append("<div class='abort'><b>ABORT the manoeuvre (stop, steer clear) if:</b><ul>")
    h += [f"<li>{e(a)}</li>" for a in abort_criteria(plan)]
    h.append("</ul></div>")
    d_head, d_rows = design_rows(plan)
    if d_head or d_rows:
        h.append("<h2>Experiment design</h2>")
        h += [f"<p>{e(line)}</p>" for line in d_head]
        h.append(_html_table(DESIGN_COLS, d_rows, "design"))
    h.append(
        "<h2>Map</h2><p>Manoeuvres in one colour each (the legend names them, design code in brackets), run-ins and "
        "stops dashed green, transit grey; stars mark execute points, circled numbers the step numbers (set aside with a "
        "thin line where the water is crowded); "
        "shaded blue: sea room swept by the hull plus margin; hatched: shallow or restricted water.</p>"
    )
    h.append(_img(map_png, "map of the planned track"))
    h.append("<h2>Steps in sailing order</h2>")
    h.append(f"<p>{e(STEPS_NOTE)}.</p>")
    h.append(_html_table(TABLE_COLS, _table_rows(sheets), "steps"))
    h.append("<h2>Orders per step</h2>")
    h += [_html_step(s) for s in sheets]
    h.append("<h2>Speed, heading and inputs over time</h2>")
    h.append(_img(states_png, "planned states over time"))
    h.append("</body></html>")
    return "\n".join(h)


def write_card(
    plan: Plan,
    path: str | Path,
    sea_map: Any = None,
    start: datetime | str | None = None,
    pdf: bool = True,
    vessel: str | None = None,
    figures: PlanFigures | None = None,
) -> list[Path]:
    """Write the HTML card to ``path`` (suffix .html) and, with ``pdf``, the PDF beside it
    (``figures``: the plan's shared figures, see :class:`maps.export.figures.PlanFigures`)."""
    path = Path(path)
    sea_map = plan_chart(plan, sea_map)  # read a map file once for the HTML, the PDF and the figures
    if path.suffix.lower() == ".pdf":  # the PDF draws its own map and states page
        return [write_card_pdf(plan, path, sea_map, start, vessel)]
    with PlanFigures(plan, sea_map) as own:
        figs = figures or own
        out = [atomic_write_text(path, card_html(plan, sea_map, start, vessel, figs))]
        if pdf:
            out.append(write_card_pdf(plan, path.with_suffix(".pdf"), sea_map, start, vessel))
    return out
