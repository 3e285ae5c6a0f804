"""RTZ 1.2 (IEC 61174 route exchange, the ECDIS format) export and checks.

The route is :func:`maps.export.route.build_route`: waypoints at the manoeuvre starts (run-in
starts, execute points, transit corners), via points where a corridor must bend round land,
and the end of the trial (ids from 1). The leg of waypoint i describes the track *into* it (the
first waypoint has none): rhumb line ("Loxodrome"), the range of speeds sailed on it, and
land-free cross-track limits (XTD). Each waypoint has the turn radius the ship can sail there.
The calculated schedule gives ETD/ETA per waypoint and, from the second waypoint on, the speed
of the leg into it (speed made good along the leg line, so leg length / speed reproduces the
ETAs). The manoeuvre (primitive, segment, orders, abort criteria, duration, sea room) rides in
``<extension manufacturer="shiptrial" name="trialManoeuvre">`` on its start waypoint.
RTZ units: distances and radii in NM, speeds in knots, depths and draughts in metres.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from datetime import datetime, timedelta
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from maps.export._common import (
    KN_PER_MPS,
    M_PER_NM,
    RTZ_EXT_NS,
    TOOL,
    ExportError,
    check_plan,
    iso,
    order_lines,
    resolve_start,
    step_abort,
    vessel_name,
    xml_document,
)
from maps.export.chart import plan_chart
from maps.export.route import Route, build_route, leg_length_m
from maps.export.wording import knots, manoeuvre_name, phase, step_orders
from maps.plan import Plan
from primitives.io import atomic_write_bytes

RTZ_NS = "http://www.cirm.org/RTZ/1/2"
EXT_NS = RTZ_EXT_NS
MAX_BYTES = 400_000  # the RTZ validator's limit on a route file
VESSEL_NAME_MAX = 32  # the RTZ validator warns above this length
SPEED_DECIMALS = 3


def _el(parent: ET.Element | None, tag: str, ns: str = RTZ_NS, **attrib: Any) -> ET.Element:
    att = {k: str(v) for k, v in attrib.items() if v is not None}
    name = f"{{{ns}}}{tag}"
    return ET.Element(name, att) if parent is None else ET.SubElement(parent, name, att)


def _dec(v: float, nd: int) -> str:
    s = f"{v:.{nd}f}"
    return "0" if float(s) == 0 else s


def _speed(kn: float) -> str:
    """A schedule speed with 4 significant digits (at least 3 decimals): a slow leg, e.g. a turn
    on the spot, keeps its ETA to the second."""
    nd = SPEED_DECIMALS if kn <= 0 else max(SPEED_DECIMALS, 3 - int(np.floor(np.log10(kn))))
    return _dec(kn, min(nd, 9))


def _nm(metres: float, cap_nm: float) -> str:
    """Metres as NM with 3 decimals, rounded down (a limit written never exceeds the one found)."""
    return _dec(min(np.floor(metres / M_PER_NM * 1000.0 + 1e-9) / 1000.0, cap_nm), 3)


def _route_info(root: ET.Element, plan: Plan, route: Route, name: str, vessel: str, t0: datetime) -> None:
    vmax = max(float(np.max(plan.speed)), max(leg.speed_max_mps for leg in route.legs[1:])) * KN_PER_MPS
    info = _el(
        root,
        "routeInfo",
        routeName=name,
        routeAuthor=TOOL,
        routeStatus="planned sea trial" + ("" if plan.feasible else " (NOT FEASIBLE)"),
        validityPeriodStart=iso(t0),
        validityPeriodStop=iso(t0 + timedelta(seconds=plan.duration_s)),
        vesselName=vessel,
        optimizationMethod="D-optimal manoeuvre mix, A* lattice plan",
        vesselMaxWind=_dec(plan.max_wind_mps * KN_PER_MPS, 1),
        vesselSpeedMax=_dec(np.ceil(vmax * 100.0) / 100.0, 2),
    )
    ext = _el(_el(info, "extensions"), "extension", manufacturer=TOOL, name="trialPlan", version="1")
    _el(
        ext,
        "abortCriteria",
        EXT_NS,
        minClearance_m=_dec(plan.margin_m, 1),
        plannedMinClearance_m=_dec(plan.min_clearance_m, 1) if np.isfinite(plan.min_clearance_m) else None,
        maxWind_mps=_dec(plan.max_wind_mps, 1),
    )
    _el(ext, "turning", EXT_NS, radius_m=_dec(route.turn_radius_m, 1), source=route.turn_radius_source)
    _el(ext, "corridors", EXT_NS, landChecked="true" if route.land_checked else "false")
    design = getattr(plan, "design", None) or {}
    if design:
        d = _el(
            ext,
            "design",
            EXT_NS,
            criterion=design.get("criterion"),
            dEfficiency=_dec(float(design["d_efficiency"]), 4) if isinstance(design.get("d_efficiency"), (int, float)) else None,
        )
        for prim, w in (design.get("weights") or {}).items():
            _el(d, "primitive", EXT_NS, name=prim, weight=_dec(float(w), 4), count=(design.get("counts") or {}).get(prim))


def _manoeuvre(w: ET.Element, plan: Plan, st: Any) -> None:
    e = _el(_el(w, "extensions"), "extension", manufacturer=TOOL, name="trialManoeuvre", version="1")
    m = _el(
        e,
        "manoeuvre",
        EXT_NS,
        index=st.index + 1,
        primitive=st.primitive,
        kind=st.kind,
        segment=st.segment,
        execute="true" if getattr(st, "execute", False) else None,
        startTime_s=_dec(st.start_time_s, 2),
        duration_s=_dec(st.duration_s, 2),
        entryHeading_deg=_dec(st.entry_heading_deg, 1),
        entrySpeed_kn=_dec(st.entry_speed_mps * KN_PER_MPS, 2),
        spaceAlong_m=_dec(st.space_m[0], 1),
        spaceAcross_m=_dec(st.space_m[1], 1),
    )
    _el(m, "description", EXT_NS).text = manoeuvre_name(plan, st)
    for o in getattr(st, "orders", None) or []:
        if isinstance(o, dict) and o.get("text"):
            vals = {
                k: v
                for k, v in o.items()
                if k not in ("t_s", "text") and isinstance(v, (int, float, str)) and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", k)
            }
            t = o.get("t_s")
            _el(m, "order", EXT_NS, t_s=_dec(float(t), 1) if isinstance(t, (int, float)) else None, **vals).text = knots(
                str(o["text"])
            )
    if not order_lines(st):
        for c in step_orders(plan, st):
            _el(m, "command", EXT_NS).text = c
    for a in step_abort(plan, st):
        _el(m, "abort", EXT_NS).text = knots(a)


def _waypoints(root: ET.Element, plan: Plan, route: Route) -> None:
    """``<waypoints>``: the default turn radius, each route point with its leg (cross-track
    limits, speed range, what is sailed) and, at a manoeuvre, its orders."""
    wpts = _el(root, "waypoints")
    dflt = _el(wpts, "defaultWaypoint", radius=_nm(route.turn_radius_m, 5.0))
    _el(dflt, "leg", geometryType="Loxodrome")
    for i, wp in enumerate(route.points):
        inner = 0 < i < len(route.points) - 1
        w = _el(wpts, "waypoint", id=wp.id, revision=0, name=wp.name, radius=_nm(wp.radius_m, 5.0) if inner else None)
        _el(w, "position", lat=_dec(wp.lat, 7), lon=_dec(wp.lon, 7))
        if i > 0:
            leg = route.legs[i]
            prev = route.points[i - 1]
            st = prev.step
            _el(
                w,
                "leg",
                starboardXTD=_nm(leg.stbd_m, 9.999),
                portsideXTD=_nm(leg.port_m, 9.999),
                geometryType="Loxodrome",
                speedMin=_dec(np.floor(leg.speed_min_mps * KN_PER_MPS * 100.0) / 100.0, 2),
                speedMax=_dec(np.ceil(leg.speed_max_mps * KN_PER_MPS * 100.0) / 100.0, 2),
                legInfo=(f"step {st.index + 1}: {phase(plan, st)} {manoeuvre_name(plan, st)}" if st else "continued")
                + f"; sails {leg.sailed_mean_mps * KN_PER_MPS:.1f} kn, makes good {leg.speed_mps * KN_PER_MPS:.1f} kn",
                legNote1=f"design code {st.primitive}" if st else None,
            )
        if wp.step is not None:
            _manoeuvre(w, plan, wp.step)


def _schedule(root: ET.Element, route: Route, t0: datetime) -> None:
    """``<schedules>``: one calculated schedule, ETD/ETA at each point and each leg's speed."""
    sched = _el(_el(root, "schedules"), "schedule", id=1, name="planned trial")
    calc = _el(sched, "calculated")
    for i, wp in enumerate(route.points):
        when = iso(t0 + timedelta(seconds=wp.t_s))
        leg = route.legs[i]
        _el(
            calc,
            "scheduleElement",
            waypointId=wp.id,
            etd=when if i + 1 < len(route.points) else None,
            eta=when if i > 0 else None,
            speed=_speed(leg.speed_mps * KN_PER_MPS) if leg is not None and leg.dt_s > 0 else None,
            Note=wp.step.primitive if wp.step else ("via" if wp.via else "end of trial"),
        )


def plan_rtz(
    plan: Plan,
    *,
    route_name: str | None = None,
    start: datetime | str | None = None,
    sea_map: Any = None,
    vessel: str | None = None,
) -> bytes:
    """The plan as an RTZ 1.2 document (UTF-8 bytes). ``route_name`` should equal the file's
    stem (ECDIS validators flag a mismatch); ``sea_map`` (or the chart stored in the plan) keeps
    the corridors off land; ``vessel`` overrides the vessel name."""
    check_plan(plan)
    t0 = resolve_start(plan, start)
    vname = vessel_name(plan, vessel)
    if len(vname) > VESSEL_NAME_MAX:
        if vessel is not None:
            raise ExportError(f"--vessel-name {vname!r} has {len(vname)} characters; RTZ holds at most {VESSEL_NAME_MAX}")
        vname = vname[:VESSEL_NAME_MAX].rstrip()
    route = build_route(plan, plan_chart(plan, sea_map))
    name = route_name or f"{plan.ship}-trial"
    ET.register_namespace("", RTZ_NS)
    ET.register_namespace("st", EXT_NS)
    root = _el(None, "route", version="1.2")
    _route_info(root, plan, route, name, vname, t0)
    _waypoints(root, plan, route)
    _schedule(root, route, t0)
    ET.indent(root, space=" ")
    return xml_document(root)


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


def _time(v: str | None) -> datetime | None:
    return datetime.fromisoformat(v.replace("Z", "+00:00").replace("z", "+00:00")) if v else None


def _leg_warnings(where: str, wps: list, i: int, dt: float, sp: str, vmax: float | None, tolerance_s: float) -> list[str]:
    """Warnings about the leg into waypoint ``i`` (elements ``wps``), scheduled ``dt`` seconds
    at ``sp`` kn: the time the leg takes at that speed, the leg's speed range, the ship's top speed."""
    ns = {"r": RTZ_NS}
    out: list[str] = []
    a, b = wps[i - 1].find("r:position", ns), wps[i].find("r:position", ns)
    length = leg_length_m(float(a.get("lon")), float(a.get("lat")), float(b.get("lon")), float(b.get("lat")))
    v = float(sp) / KN_PER_MPS
    implied = length / v if v > 0 else (0.0 if length < 0.5 else float("inf"))
    if abs(implied - dt) > max(tolerance_s, 0.005 * dt):
        out.append(
            f"{where}: ETA is {dt:.1f} s after the previous ETD, but the leg of {length:.1f} m at {sp} kn takes {implied:.1f} s"
        )
    leg = wps[i].find("r:leg", ns)
    lo = float(leg.get("speedMin")) if leg is not None and leg.get("speedMin") else None
    hi = float(leg.get("speedMax")) if leg is not None and leg.get("speedMax") else None
    if (lo is not None and float(sp) < lo - 1e-9) or (hi is not None and float(sp) > hi + 1e-9):
        out.append(f"{where}: speed {sp} kn outside the leg's speedMin..speedMax {lo}..{hi} kn")
    if vmax is not None and float(sp) > vmax + 1e-9:
        out.append(f"{where}: speed {sp} kn above vesselSpeedMax {vmax} kn")
    return out


def rtz_warnings(doc: bytes | str | Path, *, tolerance_s: float = 1.0) -> list[str]:
    """Warnings about the route's speeds and schedule (an empty list: none), beyond the XSD.

    Per calculated schedule: the first element carries no leg attribute (``speed`` belongs to
    the leg *into* a waypoint, and the first waypoint has none); every later element has a
    speed; times go forward; each ETA equals the previous ETD plus the leg length (ellipsoid,
    from the written positions) over the leg's speed, within ``tolerance_s`` or 0.5 %% of the
    leg time; each scheduled speed lies within its leg's ``speedMin``..``speedMax``, and no
    speed exceeds ``routeInfo/vesselSpeedMax``.
    """
    from lxml import etree

    data = (
        Path(doc).read_bytes()
        if isinstance(doc, Path) or (isinstance(doc, str) and not doc.lstrip().startswith("<"))
        else (doc.encode("utf-8") if isinstance(doc, str) else doc)
    )
    tree = etree.fromstring(data)
    ns = {"r": RTZ_NS}
    out: list[str] = []
    wps = tree.findall("r:waypoints/r:waypoint", ns)
    by_id = {w.get("id"): (i, w) for i, w in enumerate(wps)}
    info = tree.find("r:routeInfo", ns)
    vmax = float(info.get("vesselSpeedMax")) if info is not None and info.get("vesselSpeedMax") else None
    for w in wps:
        leg = w.find("r:leg", ns)
        if leg is not None and vmax is not None and leg.get("speedMax") and float(leg.get("speedMax")) > vmax + 1e-9:
            out.append(f"waypoint {w.get('id')}: leg speedMax {leg.get('speedMax')} kn above vesselSpeedMax {vmax} kn")
    for sch in tree.findall("r:schedules/r:schedule", ns):
        for part in ("manual", "calculated"):
            els = sch.findall(f"r:{part}/r:scheduleElement", ns)
            prev_t = None
            for j, el in enumerate(els):
                wid = el.get("waypointId")
                where = f"schedule {sch.get('id')} {part}, waypoint {wid}"
                eta, etd, sp = _time(el.get("eta")), _time(el.get("etd")), el.get("speed")
                if j == 0:
                    if sp is not None:
                        out.append(f"{where}: speed on the first element (a speed belongs to the leg into its waypoint)")
                    prev_t = etd or eta
                    continue
                if sp is None:
                    out.append(f"{where}: no speed for the leg into this waypoint")
                if eta is None:
                    out.append(f"{where}: no ETA")
                    prev_t = etd
                    continue
                if prev_t is not None and eta <= prev_t:
                    out.append(f"{where}: ETA {el.get('eta')} is not after the previous ETD")
                if etd is not None and etd < eta:
                    out.append(f"{where}: ETD before ETA")
                if sp is not None and prev_t is not None and wid in by_id and by_id[wid][0] > 0:
                    out += _leg_warnings(where, wps, by_id[wid][0], (eta - prev_t).total_seconds(), sp, vmax, tolerance_s)
                prev_t = etd or eta
    return out
