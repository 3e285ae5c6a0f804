"""GPX 1.1 export: the trial as a route (one route point per manoeuvre start plus the end) for
chart plotters and OpenCPN, and the continuous planned track as a GPX track.

Route points carry a short name ("WP03 turn_s"), the planned time of arrival, a comment with
the entry heading and speed and a description with the orders for the manoeuvre.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np

from maps.export._common import (
    KN_PER_MPS,
    M_PER_NM,
    TOOL,
    Waypoint,
    check_plan,
    clock,
    iso,
    resolve_start,
    sample_times_iso,
    vessel_name,
    xml_document,
)
from maps.export.wording import manoeuvre_name, phase, step_orders
from maps.plan import Plan
from primitives.io import atomic_write_bytes

GPX_NS = "http://www.topografix.com/GPX/1/1"
XSI_NS = "http://www.w3.org/2001/XMLSchema-instance"


def _sub(parent: ET.Element, tag: str, text: str | None = None, **attrib: str) -> ET.Element:
    el = ET.SubElement(parent, f"{{{GPX_NS}}}{tag}", attrib)
    if text is not None:
        el.text = text
    return el


def waypoint_description(plan: Plan, wp: Waypoint, start: datetime, via: bool = False) -> str:
    """What the bridge needs at a route point, as one paragraph (``via``: a point where the
    route bends round land within a step)."""
    eta = (start + timedelta(seconds=wp.t_s)).strftime("%H:%M:%S UTC")
    head = f"At +{clock(wp.t_s)} ({eta}): heading {wp.heading_deg:03.0f}°, speed {wp.speed_kn:.1f} kn."
    if via:
        return f"Via point (the route bends round land): carry on with the current manoeuvre. {head}"
    if wp.step is None:
        return f"End of trial. {head}"
    st = wp.step
    orders = " ".join(f"{o.rstrip('.')}." for o in step_orders(plan, st))
    return (
        f"Step {st.index + 1}: {phase(plan, st)} {manoeuvre_name(plan, st)} (design code {st.primitive}). {head} Orders: {orders} "
        f"Duration {clock(st.duration_s)}; sea room {st.space_m[0]:.0f} m x {st.space_m[1]:.0f} m."
    )


def plan_gpx(
    plan: Plan,
    *,
    start: datetime | str | None = None,
    name: str | None = None,
    track: bool = True,
    vessel: str | None = None,
    sea_map: Any = None,
) -> bytes:
    """The plan as a GPX 1.1 document (UTF-8 bytes). Route points are the manoeuvre starts and
    the end, named as in the RTZ route and on the card (whose numbers also count the RTZ's via
    points, where a corridor bends round land: ``sea_map`` or the plan's chart)."""
    from maps.export.chart import plan_chart
    from maps.export.route import build_route

    check_plan(plan)
    t0 = resolve_start(plan, start)
    # one source of waypoints for every export: the RTZ route's points (via points included)
    route = build_route(plan, plan_chart(plan, sea_map))
    wps = [
        Waypoint(
            pt.id - 1,
            pt.name,
            pt.lon,
            pt.lat,
            pt.t_s,
            float(np.degrees(plan.track[pt.sample, 2]) % 360.0),
            float(plan.speed[pt.sample]),
            pt.step,
            pt.sample,
        )
        for pt in route.points
    ]
    ET.register_namespace("", GPX_NS)
    ET.register_namespace("xsi", XSI_NS)
    root = ET.Element(
        f"{{{GPX_NS}}}gpx",
        {"version": "1.1", "creator": TOOL, f"{{{XSI_NS}}}schemaLocation": f"{GPX_NS} http://www.topografix.com/GPX/1/1/gpx.xsd"},
    )
    title = name or f"{vessel_name(plan, vessel)} trial {plan.map_name}".strip()
    meta = _sub(root, "metadata")
    _sub(meta, "name", title)
    n_man = sum(1 for st in plan.steps if st.segment == "informative")  # run-ins, stops and transits are steps, not manoeuvres
    _sub(
        meta,
        "desc",
        f"{len(plan.steps)} steps ({n_man} manoeuvre{'s' if n_man != 1 else ''}), {clock(plan.duration_s)}, "
        f"{plan.length_m / M_PER_NM:.2f} NM; "
        f"abort if wind exceeds {plan.max_wind_mps * KN_PER_MPS:.0f} kn or clearance drops below {plan.margin_m:.0f} m",
    )
    _sub(meta, "time", iso(t0))
    lon, lat = plan.lonlat[:, 0], plan.lonlat[:, 1]
    _sub(
        meta, "bounds", minlat=f"{lat.min():.7f}", minlon=f"{lon.min():.7f}", maxlat=f"{lat.max():.7f}", maxlon=f"{lon.max():.7f}"
    )
    rte = _sub(root, "rte")
    _sub(rte, "name", title)
    _sub(rte, "desc", "Planned sea trial: sail each manoeuvre from its route point; see the trial card for details.")
    _sub(rte, "number", "1")
    for wp in wps:
        pt = _sub(rte, "rtept", lat=f"{wp.lat:.7f}", lon=f"{wp.lon:.7f}")
        _sub(pt, "time", iso(t0 + timedelta(seconds=wp.t_s)))
        _sub(pt, "name", wp.name)
        _sub(pt, "cmt", f"heading {wp.heading_deg:03.0f}°, {wp.speed_mps * KN_PER_MPS:.1f} kn")
        via = wp.step is None and wp.id < len(wps) - 1
        _sub(pt, "desc", waypoint_description(plan, wp, t0, via=via))
        _sub(pt, "sym", "Flag, Red" if wp.id == 0 or wp.id == len(wps) - 1 else "Waypoint")
        _sub(pt, "type", "WPT")
    if track:
        trk = _sub(root, "trk")
        _sub(trk, "name", f"{title} (planned track)")
        seg = _sub(trk, "trkseg")
        for k, when in enumerate(sample_times_iso(plan, t0)):  # the CSV schedule's times: formatted once
            p = _sub(seg, "trkpt", lat=f"{lat[k]:.7f}", lon=f"{lon[k]:.7f}")
            _sub(p, "time", when)
    ET.indent(root, space=" ")
    return xml_document(root)


def write_gpx(plan: Plan, path: str | Path, **kw: Any) -> Path:
    """Write :func:`plan_gpx` to ``path`` atomically."""
    return atomic_write_bytes(path, plan_gpx(plan, **kw))
