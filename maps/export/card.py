"""Trial card for the bridge: a self-contained HTML page (PNG figures embedded as data URIs)
and a printable PDF (matplotlib PdfPages, A4).

Page 1: the plan at a glance (start, totals, abort criteria), the map with obstacles and the
numbered track coloured by primitive (like Fig. 9.13 of seed 001) and the list of manoeuvres.
Then one block per manoeuvre: entry time, position (degrees and minutes), heading and speed,
the orders in sailor's words, the thruster/force settings read from the planned inputs,
expected duration, sea room and abort criteria. Last page: speed, heading and inputs over time.
"""

from __future__ import annotations

import base64
import html
import io
import math
import textwrap
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np

from maps.export._common import (
    KN_PER_MPS,
    M_PER_NM,
    check_plan,
    clock,
    cross_track,
    input_phases,
    latlon_dm,
    resolve_start,
    waypoints,
)
from maps.export.plots import draw_map, plt, states_figure
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
    clear = f"{plan.min_clearance_m:.0f} m" if math.isfinite(plan.min_clearance_m) else "n/a"
    return [
        f"true wind above {w:.0f} m/s ({w * KN_PER_MPS:.0f} kn, Beaufort {beaufort(w)})",
        f"distance from the hull to land, shallows or any obstacle below {plan.margin_m:.0f} m (planned minimum {clear})",
        "the ship leaves the corridor of the leg (cross-track limits below) or traffic comes within the sea room",
    ]


def step_sheets(plan: Plan, start: datetime | str | None = None) -> list[dict[str, Any]]:
    """Per manoeuvre, the card's facts as text."""
    t0 = resolve_start(plan, start)
    wps = waypoints(plan)
    half = 0.5 * plan.hull[1] + plan.margin_m
    out = []
    for i, wp in enumerate(wps[:-1]):
        st = wp.step
        stbd, port = cross_track(plan, wps, i + 1)
        nxt = wps[i + 1]
        out.append(
            {
                "n": st.index + 1,
                "primitive": st.primitive,
                "description": st.description,
                "kind": st.kind,
                "start": f"+{clock(wp.t_s)} ({(t0 + timedelta(seconds=wp.t_s)).strftime('%H:%M:%S')} UTC)",
                "position": latlon_dm(wp.lat, wp.lon),
                "heading": f"{wp.heading_deg:03.0f}°",
                "speed": f"{wp.speed_kn:.1f} kn ({wp.speed_mps:.2f} m/s)",
                "orders": list(st.commands),
                "settings": input_phases(plan, st),
                "duration": clock(st.duration_s),
                "space": f"{_m(st.space_m[0])} along x {_m(st.space_m[1])} across",
                "ends": f"at {nxt.name.split()[0]} {latlon_dm(nxt.lat, nxt.lon)}, heading {nxt.heading_deg:03.0f}°, "
                f"{nxt.speed_kn:.1f} kn",
                "abort": [
                    f"more than {port + half:.0f} m to port or {stbd + half:.0f} m to starboard of the line "
                    f"{wp.name.split()[0]} -> {nxt.name.split()[0]}",
                    f"clearance below {plan.margin_m:.0f} m; wind above {plan.max_wind_mps:.0f} m/s",
                ],
            }
        )
    return out


def _summary(plan: Plan, t0: datetime) -> list[str]:
    return [
        f"Ship {plan.ship}" + (f"   Area {plan.map_name}" if plan.map_name else "") + f"   Start {t0.strftime('%Y-%m-%d %H:%M')} UTC",
        f"{len(plan.steps)} manoeuvres ({plan.basic_moves} repositioning), duration {clock(plan.duration_s)} (h:)min:s, "
        f"{plan.length_m:.0f} m ({plan.length_m / M_PER_NM:.2f} NM)",
        "Plan " + ("feasible" if plan.feasible else "NOT FEASIBLE") + (", optimal" if plan.optimal else "")
        + f"; hull {plan.hull[0]:g} m x {plan.hull[1]:g} m; safety margin {plan.margin_m:.0f} m",
    ]


# -- PDF / PNG pages ---------------------------------------------------------------------------


def _page1(plan: Plan, sheets: list[dict], t0: datetime, sea_map: Any):
    fig = plt.figure(figsize=A4)
    fig.text(0.05, 0.965, f"SEA TRIAL CARD  -  {plan.ship}", fontsize=15, fontweight="bold", va="top")
    y = 0.935
    for line in _summary(plan, t0):
        fig.text(0.05, y, line, fontsize=8.5, va="top")
        y -= 0.017
    abort = ["ABORT the manoeuvre (stop, steer clear) if:"] + [f"  - {a}" for a in abort_criteria(plan)]
    fig.text(0.05, y - 0.006, "\n".join(abort), fontsize=8.5, va="top", color="#a00000",
             bbox={"boxstyle": "round,pad=0.4", "fc": "#fff3f3", "ec": "#a00000"})
    ax = fig.add_axes((0.1, 0.31, 0.85, 0.5))
    draw_map(ax, plan, sea_map)
    ax.legend(fontsize=7, loc="best", framealpha=0.9)
    rows = [[str(s["n"]), textwrap.shorten(f"{s['primitive']}: {s['description']}", 40, placeholder="..."),
             s["start"].replace(" UTC", ""), s["position"], s["heading"], s["speed"].split(" (")[0], s["duration"],
             s["space"].replace(" along x ", " x ").replace(" across", "")] for s in sheets]
    tab_ax = fig.add_axes((0.04, 0.02, 0.92, 0.25))
    tab_ax.axis("off")
    cols = ["#", "manoeuvre", "start (UTC)", "entry position", "hdg", "speed", "time", "sea room"]
    max_rows = 16
    more = [["...", f"{len(rows) - max_rows} more manoeuvres on the next pages", "", "", "", "", "", ""]]
    shown = rows[:max_rows] + (more if len(rows) > max_rows else [])
    tab = tab_ax.table(cellText=shown, colLabels=cols, loc="upper center", cellLoc="left", colLoc="left",
                       colWidths=[0.03, 0.31, 0.15, 0.22, 0.05, 0.07, 0.05, 0.12])
    tab.auto_set_font_size(False)
    tab.set_fontsize(7)
    tab.scale(1.0, 1.25)
    return fig


def _detail_pages(plan: Plan, sheets: list[dict]) -> list:
    lines: list[tuple[str, dict]] = []
    bold = {"fontweight": "bold", "fontsize": 9.5}
    norm = {"fontsize": 8.5}
    red = {"fontsize": 8.5, "color": "#a00000"}
    for s in sheets:
        lines.append((f"{s['n']}. {s['primitive']}  -  {s['description']}", bold))
        lines.append((f"Start {s['start']} at {s['position']}, heading {s['heading']}, speed {s['speed']}", norm))
        for title, items in (("Orders", s["orders"]), ("Settings", s["settings"])):
            for j, item in enumerate(items):
                for k, w in enumerate(textwrap.wrap(item, 100)):
                    lead = f"{title}: " if (j == 0 and k == 0) else " " * (len(title) + 2)
                    lines.append((f"   {lead}{'- ' if k == 0 else '  '}{w}", norm))
        lines.append((f"   Duration {s['duration']}; sea room {s['space']}; ends {s['ends']}", norm))
        for a in s["abort"]:
            lines.append((f"   Abort if {a}", red))
        lines.append(("", norm))
    per_page = 62
    pages = []
    for p in range(0, len(lines), per_page):
        fig = plt.figure(figsize=A4)
        fig.text(0.05, 0.975, f"{plan.ship}: manoeuvres in sailing order (page {len(pages) + 2})", fontsize=10, va="top", color="0.3")
        for i, (text, style) in enumerate(lines[p : p + per_page]):
            fig.text(0.05, 0.95 - i * 0.0148, text, va="top", family="DejaVu Sans", **style)
        pages.append(fig)
    return pages


def card_figures(plan: Plan, sea_map: Any = None, start: datetime | str | None = None) -> list:
    """The card's pages as matplotlib figures (page 1, manoeuvre pages, states)."""
    check_plan(plan)
    t0 = resolve_start(plan, start)
    sheets = step_sheets(plan, t0)
    return [_page1(plan, sheets, t0, sea_map), *_detail_pages(plan, sheets), states_figure(plan)]


def write_card_pdf(plan: Plan, path: str | Path, sea_map: Any = None, start: datetime | str | None = None) -> Path:
    """The printable card (A4 PDF)."""
    from matplotlib.backends.backend_pdf import PdfPages

    figs = card_figures(plan, sea_map, start)
    buf = io.BytesIO()
    try:
        with PdfPages(buf) as pdf:
            for f in figs:
                pdf.savefig(f)
    finally:
        for f in figs:
            plt.close(f)
    return atomic_write_bytes(path, buf.getvalue())


def render_card_page1(plan: Plan, path: str | Path, sea_map: Any = None, start: datetime | str | None = None, dpi: int = 110) -> Path:
    """Page 1 of the card as PNG (what the bridge sees first)."""
    t0 = resolve_start(plan, start)
    fig = _page1(plan, step_sheets(plan, t0), t0, sea_map)
    try:
        return atomic_write_bytes(path, _png(fig, dpi))
    finally:
        plt.close(fig)


# -- HTML --------------------------------------------------------------------------------------


def _png(fig, dpi: int = 110) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def _img(png: bytes, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}">'


_CSS = """
body{font-family:DejaVu Sans,Arial,sans-serif;max-width:60em;margin:1em auto;color:#111;font-size:11pt}
h1{font-size:1.5em;margin:.2em 0} h2{font-size:1.15em;margin:1.2em 0 .3em;border-bottom:1px solid #999}
.abort{border:2px solid #a00000;background:#fff3f3;color:#a00000;padding:.4em .8em;margin:.6em 0}
table{border-collapse:collapse;width:100%;font-size:.9em} td,th{border:1px solid #bbb;padding:.2em .4em;text-align:left;vertical-align:top}
th{background:#eee} img{max-width:100%} .step{page-break-inside:avoid;margin-bottom:.8em}
.step p{margin:.2em 0} .step ul{margin:.1em 0 .1em 1.2em;padding:0} .red{color:#a00000}
"""


def card_html(plan: Plan, sea_map: Any = None, start: datetime | str | None = None) -> str:
    """The card as one self-contained HTML page."""
    check_plan(plan)
    t0 = resolve_start(plan, start)
    sheets = step_sheets(plan, t0)
    e = html.escape
    fig, ax = plt.subplots(figsize=(8, 8))
    try:
        draw_map(ax, plan, sea_map)
        ax.legend(fontsize=7, loc="best", framealpha=0.9)
        map_png = _png(fig, 120)
    finally:
        plt.close(fig)
    fig = states_figure(plan)
    try:
        states_png = _png(fig, 100)
    finally:
        plt.close(fig)
    h = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>Sea trial card {e(plan.ship)}</title>",
         f"<style>{_CSS}</style></head><body>", f"<h1>Sea trial card: {e(plan.ship)}</h1>"]
    h += [f"<p>{e(line)}</p>" for line in _summary(plan, t0)]
    h.append("<div class='abort'><b>ABORT the manoeuvre (stop, steer clear) if:</b><ul>")
    h += [f"<li>{e(a)}</li>" for a in abort_criteria(plan)]
    h.append("</ul></div>")
    h.append("<h2>Map</h2><p>Track coloured by manoeuvre type; circled numbers mark where each manoeuvre starts; "
             "shaded blue: sea room swept by the hull plus margin.</p>")
    h.append(_img(map_png, "map of the planned track"))
    h.append("<h2>Manoeuvres</h2><table><tr><th>#</th><th>manoeuvre</th><th>start</th><th>entry position</th><th>heading</th>"
             "<th>speed</th><th>duration</th><th>sea room</th></tr>")
    for s in sheets:
        h.append("<tr>" + "".join(f"<td>{e(str(s[k]))}</td>" for k in ("n", "primitive", "start", "position", "heading", "speed",
                                                                        "duration", "space")) + "</tr>")
    h.append("</table>")
    for s in sheets:
        h.append(f"<div class='step'><h2>{s['n']}. {e(s['primitive'])}: {e(s['description'])}</h2>")
        h.append(f"<p><b>Start</b> {e(s['start'])} at <b>{e(s['position'])}</b>, heading <b>{e(s['heading'])}</b>, "
                 f"speed <b>{e(s['speed'])}</b></p>")
        if s["orders"]:
            h.append("<p><b>Orders</b></p><ul>" + "".join(f"<li>{e(o)}</li>" for o in s["orders"]) + "</ul>")
        if s["settings"]:
            h.append("<p><b>Settings</b> (from the planned inputs)</p><ul>" + "".join(f"<li>{e(o)}</li>" for o in s["settings"]) + "</ul>")
        h.append(f"<p><b>Expected duration</b> {e(s['duration'])}; <b>sea room</b> {e(s['space'])}; ends {e(s['ends'])}</p>")
        h.append("<p class='red'><b>Abort if</b> " + "; ".join(e(a) for a in s["abort"]) + "</p></div>")
    h.append("<h2>Speed, heading and inputs over time</h2>")
    h.append(_img(states_png, "planned states over time"))
    h.append("</body></html>")
    return "\n".join(h)


def write_card(plan: Plan, path: str | Path, sea_map: Any = None, start: datetime | str | None = None, pdf: bool = True) -> list[Path]:
    """Write the HTML card to ``path`` (suffix .html) and, with ``pdf``, the PDF beside it."""
    path = Path(path)
    if path.suffix.lower() == ".pdf":
        return [write_card_pdf(plan, path, sea_map, start)]
    out = [atomic_write_text(path, card_html(plan, sea_map, start))]
    if pdf:
        out.append(write_card_pdf(plan, path.with_suffix(".pdf"), sea_map, start))
    return out
