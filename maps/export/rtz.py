"""RTZ 1.2 (IEC 61174 route exchange, the ECDIS format) export and validation.

Waypoints are the manoeuvre starts and the end of the trial (ids from 1). The leg of waypoint i
describes the track *into* it (the first waypoint has none): rhumb line ("Loxodrome"), the
speed range sailed on it in knots, and cross-track limits (XTD, NM) that cover the planned
track's largest excursion from the straight leg to each side plus half the beam and the
planner's margin. A calculated schedule gives ETD/ETA per waypoint. The manoeuvre (primitive,
entry state, orders, duration, sea room) rides in ``<extension manufacturer="shiptrial"
name="trialManoeuvre">`` on its start waypoint; plan-wide abort criteria on ``routeInfo``.
RTZ units: distances in NM, speeds in knots, depths and draughts in metres.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from datetime import datetime, timedelta
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from maps.export._common import (
    KN_PER_MPS,
    M_PER_NM,
    TOOL,
    check_plan,
    cross_track,
    input_phases,
    iso,
    leg_samples,
    resolve_start,
    waypoints,
)
from maps.plan import Plan
from primitives.io import atomic_write_bytes

RTZ_NS = "http://www.cirm.org/RTZ/1/2"
EXT_NS = "urn:shiptrial:rtz-trial:1"
MAX_BYTES = 400_000  # the RTZ validator's limit on a route file


def _el(parent: ET.Element | None, tag: str, ns: str = RTZ_NS, **attrib: Any) -> ET.Element:
    att = {k: str(v) for k, v in attrib.items() if v is not None}
    name = f"{{{ns}}}{tag}"
    return ET.Element(name, att) if parent is None else ET.SubElement(parent, name, att)


def _dec(v: float, nd: int) -> str:
    s = f"{v:.{nd}f}"
    return "0" if float(s) == 0 else s


def _xtd_nm(metres: float) -> str:
    return _dec(min(max(metres / M_PER_NM, 0.001), 9.999), 3)


def plan_rtz(plan: Plan, *, route_name: str | None = None, start: datetime | str | None = None) -> bytes:
    """The plan as an RTZ 1.2 document (UTF-8 bytes). ``route_name`` should equal the file's
    stem (ECDIS validators flag a mismatch)."""
    check_plan(plan)
    t0 = resolve_start(plan, start)
    wps = waypoints(plan)
    name = route_name or f"{plan.ship}-trial"
    ET.register_namespace("", RTZ_NS)
    ET.register_namespace("st", EXT_NS)
    root = _el(None, "route", version="1.2")
    half = 0.5 * float(plan.hull[1]) + float(plan.margin_m)
    vmax = float(np.max(plan.speed)) * KN_PER_MPS
    info = _el(
        root, "routeInfo",
        routeName=name,
        routeAuthor=TOOL,
        routeStatus="planned sea trial" + ("" if plan.feasible else " (NOT FEASIBLE)"),
        validityPeriodStart=iso(t0),
        validityPeriodStop=iso(t0 + timedelta(seconds=plan.duration_s)),
        vesselName=plan.ship,
        optimizationMethod="D-optimal manoeuvre mix, A* lattice plan",
        vesselMaxWind=_dec(plan.max_wind_mps * KN_PER_MPS, 1),
        vesselSpeedMax=_dec(vmax, 2),
    )
    ext = _el(_el(info, "extensions"), "extension", manufacturer=TOOL, name="trialPlan", version="1")
    _el(
        ext, "abortCriteria", EXT_NS,
        minClearance_m=_dec(plan.margin_m, 1),
        plannedMinClearance_m=_dec(plan.min_clearance_m, 1) if np.isfinite(plan.min_clearance_m) else None,
        maxWind_mps=_dec(plan.max_wind_mps, 1),
        corridorHalfWidth_m=_dec(half, 1),
    )
    wpts = _el(root, "waypoints")
    dflt = _el(wpts, "defaultWaypoint")
    _el(dflt, "leg", geometryType="Loxodrome")
    for i, wp in enumerate(wps):
        w = _el(wpts, "waypoint", id=wp.id + 1, revision=0, name=wp.name)
        _el(w, "position", lat=_dec(wp.lat, 7), lon=_dec(wp.lon, 7))
        if i > 0:
            stbd, port = cross_track(plan, wps, i)
            sp = plan.speed[leg_samples(plan, wps, i)] * KN_PER_MPS
            prev = wps[i - 1].step
            _el(
                w, "leg",
                starboardXTD=_xtd_nm(stbd + half),
                portsideXTD=_xtd_nm(port + half),
                geometryType="Loxodrome",
                speedMin=_dec(float(sp.min()), 2),
                speedMax=_dec(float(sp.max()), 2),
                legInfo=f"manoeuvre {prev.index + 1}: {prev.primitive}" if prev else None,
                legNote1=prev.description if prev else None,
            )
        if wp.step is not None:
            st = wp.step
            e = _el(_el(w, "extensions"), "extension", manufacturer=TOOL, name="trialManoeuvre", version="1")
            m = _el(
                e, "manoeuvre", EXT_NS,
                index=st.index + 1, primitive=st.primitive, kind=st.kind,
                startTime_s=_dec(st.start_time_s, 2), duration_s=_dec(st.duration_s, 2),
                entryHeading_deg=_dec(st.entry_heading_deg, 1), entrySpeed_kn=_dec(st.entry_speed_mps * KN_PER_MPS, 2),
                spaceAlong_m=_dec(st.space_m[0], 1), spaceAcross_m=_dec(st.space_m[1], 1),
            )
            _el(m, "description", EXT_NS).text = st.description
            for c in st.commands:
                _el(m, "command", EXT_NS).text = c
            for s in input_phases(plan, st):
                _el(m, "setting", EXT_NS).text = s
    sched = _el(_el(root, "schedules"), "schedule", id=1, name="planned trial")
    calc = _el(sched, "calculated")
    for i, wp in enumerate(wps):
        when = iso(t0 + timedelta(seconds=wp.t_s))
        speed = None
        if i + 1 < len(wps):
            seg = plan.track[leg_samples(plan, wps, i + 1), :2]
            dt = wps[i + 1].t_s - wp.t_s
            dist = float(np.sum(np.hypot(*np.diff(seg, axis=0).T)))
            speed = _dec(dist / dt * KN_PER_MPS, 2) if dt > 0 else None
        _el(
            calc, "scheduleElement",
            waypointId=wp.id + 1,
            etd=when if i + 1 < len(wps) else None,
            eta=when if i > 0 else None,
            speed=speed,
            Note=wp.step.primitive if wp.step else "end of trial",
        )
    ET.indent(root, space=" ")
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)


def write_rtz(plan: Plan, path: str | Path, **kw: Any) -> Path:
    """Write :func:`plan_rtz` to ``path`` atomically; the route is named after the file."""
    path = Path(path)
    kw.setdefault("route_name", path.stem)
    return atomic_write_bytes(path, plan_rtz(plan, **kw))


def schema_path() -> Path:
    """The bundled RTZ 1.2 XSD (IEC 61174, via AndyNibbs/RTZ, MIT)."""
    return Path(str(resources.files("maps.export") / "schemas" / "RTZ_Schema_version_1_2.xsd"))


def validate_rtz(doc: bytes | str | Path, *, file_name: str | None = None) -> list[str]:
    """Problems of an RTZ 1.2 document; an empty list means it is valid.

    Checks the XSD (needs lxml) and the rules the RTZ validator adds: unique waypoint ids, no
    leg on the first waypoint, schedule elements naming existing waypoints in route order, file
    size below 400 kB, and ``routeName`` equal to the file name's stem.
    """
    from lxml import etree

    if isinstance(doc, (str, Path)) and not (isinstance(doc, str) and doc.lstrip().startswith("<")):
        file_name = file_name or Path(doc).name
        data = Path(doc).read_bytes()
    else:
        data = doc.encode("utf-8") if isinstance(doc, str) else doc
    errs: list[str] = []
    schema = etree.XMLSchema(etree.parse(str(schema_path())))
    try:
        tree = etree.fromstring(data)
    except etree.XMLSyntaxError as exc:
        return [f"not well-formed XML: {exc}"]
    if not schema.validate(tree):
        errs += [f"XSD line {e.line}: {e.message}" for e in schema.error_log]
    if len(data) >= MAX_BYTES:
        errs.append(f"file is {len(data)} bytes; RTZ files must stay below {MAX_BYTES}")
    ns = {"r": RTZ_NS}
    ids = [w.get("id") for w in tree.findall("r:waypoints/r:waypoint", ns)]
    if len(set(ids)) != len(ids):
        errs.append("waypoint ids are not unique")
    first = tree.find("r:waypoints/r:waypoint", ns)
    if first is not None and first.find("r:leg", ns) is not None:
        errs.append("the first waypoint has a leg (a leg describes the track into its waypoint)")
    for sch in tree.findall("r:schedules/r:schedule", ns):
        refs = [e.get("waypointId") for e in sch.iter(f"{{{RTZ_NS}}}scheduleElement")]
        if any(r not in ids for r in refs):
            errs.append(f"schedule {sch.get('id')}: names waypoints that do not exist")
        elif [ids.index(r) for r in refs] != sorted(ids.index(r) for r in refs):
            errs.append(f"schedule {sch.get('id')}: elements are not in route order")
    info = tree.find("r:routeInfo", ns)
    if file_name and info is not None and info.get("routeName") != Path(file_name).stem:
        errs.append(f"routeName {info.get('routeName')!r} does not match the file name {file_name!r}")
    return errs
