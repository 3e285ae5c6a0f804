"""GeoJSON (RFC 7946) export of a plan and an RFC 7946 checker.

Two products (:func:`plan_geojson`): the *trajectory* (``overlay=False``, ``trajectory.geojson``
written with plan.json): the track as one LineString per segment, tagged ``run-in``,
``informative`` (with the primitive) or ``transit``; and the crew's *chart overlay*
(``<ship>-trial.geojson``): the same segments plus one Point per manoeuvre start (execute
points flagged, with orders and abort criteria), the route's land-free cross-track corridors
and the sea room the trial sweeps (track buffered by half the beam plus the planner's margin),
polygons with counter-clockwise exterior rings. Coordinates are WGS-84 lon, lat
with at most 7 decimals (about 1 cm); there is no ``crs`` member (RFC 7946 section 4).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from maps.export._common import KN_PER_MPS, TOOL, check_plan, step_abort, step_slice, vessel_name
from maps.export.wording import step_orders
from maps.plan import Plan
from primitives.io import atomic_write_bytes

DECIMALS = 7


def _pos(lon: float, lat: float) -> list[float]:
    return [round(float(lon), DECIMALS), round(float(lat), DECIMALS)]


def _line(lonlat: np.ndarray) -> list[list[float]]:
    out: list[list[float]] = []
    for lon, lat in lonlat:
        p = _pos(lon, lat)
        if not out or p != out[-1]:
            out.append(p)
    if len(out) == 1:
        out.append(list(out[0]))
    return out


_ROOM_MEMO = "_sea_room_memo"  # kept on the plan object like the route (maps.export.route.build_route)


def sea_room_lonlat(plan: Plan) -> Any:
    """The swept sea room (shapely Polygon, lon/lat, exterior CCW) or None without a projection.
    The overlay, the track figure and the card's map draw the same one: it is kept on the plan
    (for the same track, hull, margin and projection) and travels with it to the drawing process."""
    key = (plan.track, tuple(plan.hull), plan.margin_m, (plan.projection or {}).get("proj4"))
    memo = plan.__dict__.get(_ROOM_MEMO)
    if memo is not None and memo[0][0] is key[0] and memo[0][1:] == key[1:]:
        return memo[1]
    room = _sea_room(plan)
    plan.__dict__[_ROOM_MEMO] = (key, room)
    return room


def _sea_room(plan: Plan) -> Any:
    proj4 = (plan.projection or {}).get("proj4")
    if not proj4:
        return None
    import shapely
    from shapely.geometry import LineString
    from shapely.geometry.polygon import orient

    from maps.geo import transformer

    half = 0.5 * float(plan.hull[1] or 0.0) + float(plan.margin_m or 0.0)
    half = max(half, 0.5 * float(plan.hull[0] or 0.0), 1.0)
    line = LineString(np.column_stack([plan.track[:, 1], plan.track[:, 0]]))  # (east, north)
    area = line.buffer(half, quad_segs=8).simplify(0.05 * half)
    tr = transformer(proj4, "EPSG:4326")
    ll = shapely.transform(area, lambda c: np.column_stack(tr.transform(c[:, 0], c[:, 1])))
    if ll.geom_type != "Polygon" or ll.is_empty:
        return None
    return orient(ll, sign=1.0)


def _polygon_coords(poly: Any) -> list[list[list[float]]]:
    rings = [poly.exterior, *poly.interiors]
    return [[_pos(x, y) for x, y in ring.coords] for ring in rings]


def track_segments(plan: Plan) -> list[dict[str, Any]]:
    """The track cut into segments: consecutive steps of one kind (``run-in`` or ``transit``)
    form one segment, each informative manoeuvre its own. Each: segment, primitive (the
    informative one, else None), steps (indices from 1), sample slice (a, b) inclusive."""
    out: list[dict[str, Any]] = []
    for st in plan.steps:
        seg = st.segment
        sl = step_slice(plan, st)
        a, b = sl.start, min(sl.stop - 1, len(plan.t) - 1)
        if out and seg != "informative" and out[-1]["segment"] == seg:
            out[-1]["steps"].append(st.index + 1)
            out[-1]["b"] = max(out[-1]["b"], b)
            continue
        out.append(
            {"segment": seg, "primitive": st.primitive if seg == "informative" else None, "steps": [st.index + 1], "a": a, "b": b}
        )
    return out


def _to_lonlat(tr: Any, geom: Any) -> Any:
    """``geom`` in the plan's metric frame (x north, y east) in lon/lat by transformer ``tr``."""
    import shapely
    from shapely.geometry.polygon import orient

    ll = shapely.transform(geom, lambda c: np.column_stack(tr.transform(c[:, 1], c[:, 0])))  # (north, east) -> lon, lat
    return orient(ll, sign=1.0) if ll.geom_type == "Polygon" else ll


def segment_features(plan: Plan) -> list[dict[str, Any]]:
    """The track's LineString features, one per segment (run-in, informative, transit): the start of both the
    trajectory and the crew's overlay (:func:`plan_geojson`'s ``segments``: built once for the two files)."""
    feats = []
    for seg in track_segments(plan):
        a, b = seg["a"], seg["b"]
        if b <= a:
            continue
        xy = plan.track[a : b + 1, :2]
        props = {
            "kind": "track",
            "segment": seg["segment"],
            "primitive": seg["primitive"],
            "steps": seg["steps"],
            "start_time_s": round(float(plan.t[a] - plan.t[0]), 2),
            "duration_s": round(float(plan.t[b] - plan.t[a]), 2),
            "length_m": round(float(np.sum(np.hypot(*np.diff(xy, axis=0).T))), 1),
        }
        feats.append(
            {
                "type": "Feature",
                "geometry": {"type": "LineString", "coordinates": _line(plan.lonlat[a : b + 1])},
                "properties": props,
            }
        )
    return feats


def _sailed_features(plan: Plan) -> list[dict[str, Any]]:
    """A resumed plan's trial sailed before it (``stats['resume']``, :mod:`maps.resume`): the
    planned track of the steps sailed, ``kind = "sailed"``."""
    sailed = (plan.stats.get("resume") or {}).get("sailed") or {}
    line = sailed.get("lonlat") or []
    if len(line) < 2:
        return []
    props = {"kind": "sailed", "steps": [s["step"] for s in sailed.get("steps", [])], "duration_s": sailed.get("sailed_s")}
    return [{"type": "Feature", "geometry": {"type": "LineString", "coordinates": _line(np.asarray(line))}, "properties": props}]


def _start_features(plan: Plan) -> list[dict[str, Any]]:
    feats = []
    for st in plan.steps:
        execute = bool(getattr(st, "execute", False))
        feats.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": _pos(st.entry_lon, st.entry_lat)},
                "properties": {
                    "kind": "execute_point" if execute else "manoeuvre_start",
                    "index": st.index + 1,
                    "primitive": st.primitive,
                    "segment": st.segment,
                    "manoeuvre_kind": st.kind,
                    "description": st.description,
                    "commands": list(st.commands),
                    "orders": step_orders(plan, st),
                    "abort": step_abort(plan, st),
                    "start_time_s": round(st.start_time_s, 2),
                    "duration_s": round(st.duration_s, 2),
                    "entry_heading_deg": round(st.entry_heading_deg, 1),
                    "entry_speed_mps": round(st.entry_speed_mps, 3),
                    "entry_speed_kn": round(st.entry_speed_mps * KN_PER_MPS, 2),
                    "space_m": [round(float(v), 1) for v in st.space_m],
                },
            }
        )
    return feats


def _corridor_features(plan: Plan, sea_map: Any) -> list[dict[str, Any]]:
    from maps.export.chart import plan_chart
    from maps.export.route import build_route, corridor_polygons
    from maps.geo import transformer

    route = build_route(plan, plan_chart(plan, sea_map))
    tr = transformer(plan.projection["proj4"], "EPSG:4326")  # one for every corridor
    feats = []
    for i, poly in enumerate(corridor_polygons(route, plan)):
        if poly is None or poly.is_empty:
            continue
        leg = route.legs[i]
        ll = _to_lonlat(tr, poly)
        if ll.geom_type != "Polygon":
            continue
        feats.append(
            {
                "type": "Feature",
                "geometry": {"type": "Polygon", "coordinates": _polygon_coords(ll)},
                "properties": {
                    "kind": "corridor",
                    "waypoint": route.points[i].id,
                    "name": route.points[i].name,
                    "starboard_xtd_m": round(leg.stbd_m, 1),
                    "port_xtd_m": round(leg.port_m, 1),
                    "land_checked": route.land_checked,
                },
            }
        )
    return feats


def plan_geojson(
    plan: Plan,
    *,
    sea_room: bool = True,
    overlay: bool = True,
    sea_map: Any = None,
    segments: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """The plan as an RFC 7946 FeatureCollection (a dict ready for ``json.dumps``).

    Always: the track as one LineString per segment (``properties.kind = "track"``,
    ``segment`` = run-in | informative | transit, ``primitive`` for an informative one).
    With ``overlay`` (the crew's chart overlay): one Point per manoeuvre start (``kind``
    ``execute_point`` where an informative manoeuvre is executed, else ``manoeuvre_start``) with
    its orders and abort criteria, the route's cross-track corridors (``kind = "corridor"``, cut
    to land-free water with ``sea_map`` or the plan's chart) and the swept sea room. ``segments``:
    :func:`segment_features` of this plan when built already (read, not changed).
    """
    check_plan(plan)
    summary = {
        "generator": TOOL,  # first: an export knows its own file by it (maps.export.ownership.is_export_file)
        "kind": "trial",
        "ship": plan.ship,
        "vessel_name": vessel_name(plan),
        "map": plan.map_name,
        "duration_s": round(plan.duration_s, 1),
        "length_m": round(plan.length_m, 1),
        "manoeuvres": len(plan.steps),
        "feasible": bool(plan.feasible),
        "min_clearance_m": None if not math.isfinite(plan.min_clearance_m) else round(plan.min_clearance_m, 1),
        "margin_m": plan.margin_m,
        "max_wind_mps": plan.max_wind_mps,
    }
    feats = [*(segment_features(plan) if segments is None else segments), *_sailed_features(plan)]
    if not overlay:
        return {"type": "FeatureCollection", "properties": summary, "features": feats}
    feats += _start_features(plan)
    if (plan.projection or {}).get("proj4"):
        feats += _corridor_features(plan, sea_map)
    poly = sea_room_lonlat(plan) if sea_room else None
    if poly is not None:
        feats.append(
            {
                "type": "Feature",
                "geometry": {"type": "Polygon", "coordinates": _polygon_coords(poly)},
                "properties": {"kind": "sea_room", "half_width_m": 0.5 * plan.hull[1] + plan.margin_m},
            }
        )
    return {"type": "FeatureCollection", "properties": summary, "features": feats}


def geojson_bytes(collection: dict[str, Any]) -> bytes:
    """A :func:`plan_geojson` collection as the bytes :func:`write_geojson` writes (compact UTF-8 JSON)."""
    return json.dumps(collection, ensure_ascii=False, separators=(",", ":")).encode("utf-8")


def write_geojson(plan: Plan, path: str | Path, **kw: Any) -> Path:
    """Write :func:`plan_geojson` to ``path`` atomically."""
    return atomic_write_bytes(path, geojson_bytes(plan_geojson(plan, **kw)))


# -- RFC 7946 check --------------------------------------------------------------------------

_GEOMS = {"Point", "MultiPoint", "LineString", "MultiLineString", "Polygon", "MultiPolygon", "GeometryCollection"}


def _ring_area(ring: list) -> float:
    """Shoelace signed area in lon/lat (positive: counter-clockwise)."""
    a = 0.0
    for (x1, y1, *_), (x2, y2, *_) in zip(ring[:-1], ring[1:]):
        a += x1 * y2 - x2 * y1
    return 0.5 * a


def _check_position(p: Any, where: str, errs: list[str]) -> None:
    if (
        not isinstance(p, list)
        or len(p) not in (2, 3)
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in p)
    ):
        errs.append(f"{where}: a position is [lon, lat] or [lon, lat, alt] of numbers, got {p!r}")
        return
    lon, lat = p[0], p[1]
    if not (-180.0 <= lon <= 180.0):
        errs.append(f"{where}: longitude {lon} outside [-180, 180]")
    if not (-90.0 <= lat <= 90.0):
        errs.append(f"{where}: latitude {lat} outside [-90, 90] (lon/lat swapped?)")
    for v in p[:2]:
        if not math.isfinite(v) or round(v, DECIMALS) != v:
            errs.append(f"{where}: coordinate {v!r} has more than {DECIMALS} decimals")
            break


def _check_geometry(g: Any, where: str, errs: list[str]) -> None:
    if not isinstance(g, dict) or g.get("type") not in _GEOMS:
        errs.append(f"{where}: not a GeoJSON geometry (type must be one of {sorted(_GEOMS)})")
        return
    t = g["type"]
    if t == "GeometryCollection":
        for i, sub in enumerate(g.get("geometries", [])):
            _check_geometry(sub, f"{where}.geometries[{i}]", errs)
        return
    c = g.get("coordinates")
    if not isinstance(c, list):
        errs.append(f"{where}: {t} needs a 'coordinates' array")
        return
    if t == "Point":
        _check_position(c, where, errs)
    elif t in ("MultiPoint", "LineString"):
        for p in c:
            _check_position(p, where, errs)
        if t == "LineString" and len(c) < 2:
            errs.append(f"{where}: a LineString needs 2 or more positions")
    elif t == "MultiLineString":
        for i, line in enumerate(c):
            _check_geometry({"type": "LineString", "coordinates": line}, f"{where}[{i}]", errs)
    elif t == "Polygon":
        for i, ring in enumerate(c):
            w = f"{where} ring {i}"
            if not isinstance(ring, list) or len(ring) < 4:
                errs.append(f"{w}: a linear ring needs 4 or more positions")
                continue
            for p in ring:
                _check_position(p, w, errs)
            if ring[0] != ring[-1]:
                errs.append(f"{w}: first and last positions differ (ring not closed)")
            area = _ring_area(ring)
            if i == 0 and area <= 0:
                errs.append(f"{w}: exterior ring is not counter-clockwise (right-hand rule, RFC 7946 3.1.6)")
            if i > 0 and area >= 0:
                errs.append(f"{w}: hole is not clockwise (right-hand rule, RFC 7946 3.1.6)")
    elif t == "MultiPolygon":
        for i, poly in enumerate(c):
            _check_geometry({"type": "Polygon", "coordinates": poly}, f"{where}[{i}]", errs)


def validate_geojson(obj: dict[str, Any] | str | Path) -> list[str]:
    """Problems of a GeoJSON object (or file) under RFC 7946; an empty list means it passes.

    Checks: object structure (FeatureCollection / Feature / geometry members), no ``crs``
    member (section 4), positions [lon, lat] inside the WGS-84 ranges (section 3.1.1), at most
    7 decimals, LineStrings of 2+ positions, closed rings of 4+ positions with counter-clockwise
    exteriors and clockwise holes (section 3.1.6), and a consistent ``bbox`` (section 5).
    """
    if isinstance(obj, (str, Path)):
        try:
            obj = json.loads(Path(obj).read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            return [f"{obj}: not readable JSON ({exc})"]
    errs: list[str] = []
    if not isinstance(obj, dict):
        return ["top level: a GeoJSON text is a single JSON object"]
    if "crs" in obj:
        errs.append("top level: member 'crs' is not allowed in RFC 7946 (coordinates are always WGS-84)")
    t = obj.get("type")
    if t == "FeatureCollection":
        feats = obj.get("features")
        if not isinstance(feats, list):
            return errs + ["FeatureCollection: member 'features' must be an array"]
        items = list(enumerate(feats))
    elif t == "Feature":
        items = [(0, obj)]
    else:
        _check_geometry(obj, "geometry", errs)
        return errs
    for i, f in items:
        w = f"features[{i}]"
        if not isinstance(f, dict) or f.get("type") != "Feature":
            errs.append(f"{w}: type must be 'Feature'")
            continue
        if "geometry" not in f or "properties" not in f:
            errs.append(f"{w}: a Feature has members 'geometry' and 'properties' (may be null)")
        if f.get("geometry") is not None:
            _check_geometry(f["geometry"], f"{w}.geometry", errs)
        if f.get("properties") is not None and not isinstance(f["properties"], dict):
            errs.append(f"{w}: 'properties' must be an object or null")
    if "bbox" in obj:
        b = obj["bbox"]
        if not (isinstance(b, list) and len(b) in (4, 6)):
            errs.append("bbox: must hold 2*n numbers")
    return errs
