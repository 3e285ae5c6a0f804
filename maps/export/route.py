"""The plan as a route an ECDIS can monitor: waypoints, legs with their own speeds, turn radii
and land-free cross-track corridors (what the RTZ export writes).

Waypoints are the manoeuvre starts (run-in starts, execute points, transit corners) and the end
of the track. The leg *into* waypoint i is the track sailed between waypoints i-1 and i (the
RTZ convention). Per leg:

- speed: the planned speed made good along the leg line, ``length / (ETA_i - ETA_{i-1})``, so an
  ECDIS that computes ETAs from leg lengths and speeds reproduces the schedule; ``speedMin`` and
  ``speedMax`` span the speeds over ground sailed on the leg (and the speed made good: a
  zig-zag sails faster than it makes good along its leg line).
- corridor (XTD, each side): the track's largest excursion from the leg line plus half the beam
  plus the planner's margin, cut back to the water free of land and every other no-go area of
  the chart (measured perpendicular to the leg). Where even the hull would not fit in the free
  water, the leg is split at the track's largest excursion (a ``via`` waypoint), so each
  corridor holds the hull and touches no land.
- turn radius at a waypoint: the ship's turning radius (:func:`turning_radius`), reduced where
  the legs are too short for that arc (wheel-over arcs must not overlap).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from pyproj import Geod
from shapely.geometry.base import BaseGeometry

from maps.export._common import M_PER_NM, check_plan, line_offsets, step_slice
from maps.export.chart import Chart
from maps.plan import Plan, PlanStep

GEOD = Geod(ellps="WGS84")
XTD_MAX_M = 9.999 * M_PER_NM  # RTZ XtdType < 10 NM
RADIUS_MAX_M = 5.0 * M_PER_NM  # RTZ RadiusType <= 5 NM
IMO_TACTICAL_DIAMETER_L = 5.0  # MSC.137(76): tactical diameter <= 5 ship lengths
MAX_SPLITS = 50


@dataclass
class RoutePoint:
    """A route waypoint (id from 1) with its planned time from the start of the trial."""

    id: int
    name: str
    lon: float
    lat: float
    t_s: float
    sample: int
    step: PlanStep | None  # the manoeuvre that starts here (None: a via point or the end)
    via: bool = False
    radius_m: float = 0.0


@dataclass
class Leg:
    """The leg into a waypoint: length (m, geodesic), time (s), speeds (m/s) and corridor (m)."""

    length_m: float
    dt_s: float
    speed_mps: float  # made good along the leg line
    sailed_min_mps: float
    sailed_max_mps: float
    sailed_mean_mps: float  # along the track
    stbd_m: float
    port_m: float
    need_stbd_m: float  # excursion + half beam + margin
    need_port_m: float
    free_stbd_m: float  # water free of no-go areas (inf: not checked)
    free_port_m: float
    hull_fits: bool  # the hull's excursion stays inside the corridor

    @property
    def speed_min_mps(self) -> float:
        return min(self.sailed_min_mps, self.speed_mps)

    @property
    def speed_max_mps(self) -> float:
        return max(self.sailed_max_mps, self.speed_mps)


@dataclass
class Route:
    points: list[RoutePoint]
    legs: list[Leg | None]  # legs[i] leads into points[i]; legs[0] is None
    turn_radius_m: float
    turn_radius_source: str
    land_checked: bool


def leg_length_m(lon0: float, lat0: float, lon1: float, lat1: float) -> float:
    """Distance between two positions on the WGS-84 ellipsoid (m). At trial scale (a few
    nautical miles) a rhumb line and the geodesic differ by far less than a metre."""
    return float(GEOD.inv(lon0, lat0, lon1, lat1)[2])


def turning_radius(plan: Plan) -> tuple[float, str]:
    """The ship's turning radius (m) and where the figure comes from.

    1. ``plan.stats['turning_radius_m']`` when the planner stored one;
    2. else the tightest turn the plan's own re-simulated track makes at speed: the path's
       radius of curvature, speed over ground over the rate of turn of the course over ground,
       over samples at 80 % or more of the median speed turning at least 0.05 deg/s (the
       profile's model, not a constant);
    3. else half the IMO MSC.137(76) limit on the tactical diameter, 2.5 ship lengths.
    """
    given = plan.stats.get("turning_radius_m") if isinstance(plan.stats, dict) else None
    if isinstance(given, (int, float)) and given > 0:
        return float(given), "planner"
    t, xy = plan.t, plan.track[:, :2]
    if len(t) >= 4:
        dt = np.diff(t)
        step = np.diff(xy, axis=0)
        u = np.hypot(*step.T) / np.where(dt > 0, dt, np.inf)  # speed over ground between samples
        chi = np.unwrap(np.arctan2(step[:, 1], step[:, 0]))  # course over ground
        tm = 0.5 * (t[1:] + t[:-1])
        rate = np.gradient(chi, tm)
        ok = (u >= 0.8 * np.median(u)) & (np.abs(rate) >= np.radians(0.05)) & (u > 0.1)
        if np.count_nonzero(ok) >= 3:
            return float(np.min(u[ok] / np.abs(rate[ok]))), "tightest turn of the planned track"
    return 0.5 * IMO_TACTICAL_DIAMETER_L * float(plan.hull[0] or 0.0), "IMO limit 2.5 L"


def xtd_floor_m(metres: float) -> float:
    """``metres`` rounded down to the RTZ's resolution (0.001 NM): a corridor written to the
    file is never wider than the water found free."""
    return math.floor(min(metres, XTD_MAX_M) / M_PER_NM * 1000.0 + 1e-9) / 1000.0 * M_PER_NM


def free_width(a: np.ndarray, b: np.ndarray, obstacles: BaseGeometry | None, side: float, reach: float) -> float:
    """Width (m, up to ``reach``) of the water free of ``obstacles`` on one side of the leg a -> b
    (``side`` +1 starboard, -1 port), measured perpendicular to the leg (metric x north, y east)."""
    if obstacles is None or obstacles.is_empty:
        return math.inf
    d = b - a
    length = float(np.hypot(*d))
    if length < 1e-6:
        return min(float(shapely.distance(shapely.Point(*a), obstacles)), reach)
    n = side * np.array([-d[1], d[0]]) / length
    strip = shapely.Polygon([a, b, b + reach * n, a + reach * n])
    hit = shapely.intersection(strip, obstacles)
    if hit.is_empty:
        return reach
    return min(float(shapely.distance(shapely.LineString([a, b]), hit)), reach)


def _leg(
    plan: Plan,
    ka: int,
    kb: int,
    lonlat: tuple[float, float, float, float],
    half: float,
    half_beam: float,
    obstacles: BaseGeometry | None,
) -> Leg:
    seg = plan.track[ka : kb + 1, :2]
    off, chord = line_offsets(seg)
    exc_s, exc_p = float(max(off.max(), 0.0)), float(max(-off.min(), 0.0))
    if chord == 0.0:  # a turn on the spot: a circle round the point
        exc_p = exc_s
    need_s, need_p = exc_s + half, exc_p + half
    reach_s, reach_p = min(need_s, XTD_MAX_M), min(need_p, XTD_MAX_M)
    free_s = free_width(seg[0], seg[-1], obstacles, +1.0, reach_s)
    free_p = free_width(seg[0], seg[-1], obstacles, -1.0, reach_p)
    sp = plan.speed[ka : kb + 1]
    dt = float(plan.t[kb] - plan.t[ka])
    length = leg_length_m(*(round(v, 7) for v in lonlat))  # from the positions as written (7 decimals)
    path = float(np.sum(np.hypot(*np.diff(seg, axis=0).T)))
    stbd, port = xtd_floor_m(min(need_s, free_s)), xtd_floor_m(min(need_p, free_p))
    return Leg(
        length_m=length,
        dt_s=dt,
        speed_mps=length / dt if dt > 0 else 0.0,
        sailed_min_mps=float(sp.min()),
        sailed_max_mps=float(sp.max()),
        sailed_mean_mps=path / dt if dt > 0 else 0.0,
        stbd_m=stbd,
        port_m=port,
        need_stbd_m=need_s,
        need_port_m=need_p,
        free_stbd_m=free_s,
        free_port_m=free_p,
        hull_fits=(stbd >= exc_s + half_beam - 1e-6) and (port >= exc_p + half_beam - 1e-6),
    )


def _split_at(plan: Plan, ka: int, kb: int) -> int | None:
    """Sample of the largest excursion from the line ka -> kb (None: nothing to split)."""
    if kb - ka < 2:
        return None
    off, _ = line_offsets(plan.track[ka : kb + 1, :2])
    k = ka + int(np.argmax(np.abs(off[1:-1]))) + 1
    return k if ka < k < kb else None


def _hull_hits(plan: Plan, ka: int, kb: int, half_beam: float, obstacles: BaseGeometry | None) -> bool:
    """True when the planned hull itself touches an obstacle on samples ka..kb: no corridor can
    hold it, and splitting the leg would not help."""
    if obstacles is None:
        return False
    seg = plan.track[ka : kb + 1, :2]
    geom = shapely.LineString(seg) if len(seg) > 1 else shapely.Point(*seg[0])
    return bool(shapely.intersects(geom.buffer(max(half_beam, 0.01)), obstacles))


_MEMO = "_route_memo"  # the last route built for a plan, kept on the plan object (never in its JSON)


def build_route(plan: Plan, chart: Chart | None = None) -> Route:
    """The route of ``plan``; corridors are cut to the land-free water of ``chart`` (when the
    chart is given and the plan has a projection).

    Every export of a plan (GeoJSON, GPX, RTZ, the card's legs) asks for the same route: the last
    one built is kept on the plan, for the same chart object and the same track and steps, and
    travels with it when the plan is pickled to the process that draws (``shiptrial plan``).
    Treat the returned route as read-only."""
    memo = plan.__dict__.get(_MEMO)
    radius = plan.stats.get("turning_radius_m") if isinstance(plan.stats, dict) else None
    key = (tuple(plan.hull), plan.margin_m, radius)  # the values it reads besides those objects
    if memo is not None and memo[0] is chart and memo[1] is plan.lonlat and memo[2] is plan.steps and memo[3] == key:
        return memo[4]
    route = _build_route(plan, chart)
    plan.__dict__[_MEMO] = (chart, plan.lonlat, plan.steps, key, route)
    return route


def _build_route(plan: Plan, chart: Chart | None) -> Route:
    check_plan(plan)
    starts = [(step_slice(plan, st).start, st) for st in plan.steps]
    marks: list[tuple[int, PlanStep | None, bool]] = []
    for k, st in starts:
        if marks and marks[-1][0] == k:  # a step without samples shares its predecessor's point
            continue
        marks.append((k, st, False))
    if marks[-1][0] != len(plan.t) - 1:
        marks.append((len(plan.t) - 1, None, False))
    obstacles = chart.local_obstacles(plan) if chart is not None and not chart.is_empty() else None
    half_beam = 0.5 * float(plan.hull[1] or 0.0)
    half = half_beam + float(plan.margin_m or 0.0)

    def ll(k: int) -> tuple[float, float]:
        return float(plan.lonlat[k, 0]), float(plan.lonlat[k, 1])

    legs: list[Leg | None] = [None]
    i, splits = 1, 0
    while i < len(marks):
        ka, kb = marks[i - 1][0], marks[i][0]
        leg = _leg(plan, ka, kb, (*ll(ka), *ll(kb)), half, half_beam, obstacles)
        k = (
            None
            if leg.hull_fits or splits >= MAX_SPLITS or _hull_hits(plan, ka, kb, half_beam, obstacles)
            else _split_at(plan, ka, kb)
        )
        if k is not None:
            marks.insert(i, (k, None, True))
            splits += 1
            continue
        legs.append(leg)
        i += 1
    r_ship, source = turning_radius(plan)
    points = []
    for n, (k, st, via) in enumerate(marks):
        label = st.primitive if st is not None else ("via" if via else "end")
        if st is not None and getattr(st, "execute", False):
            label = f"EXECUTE {label}"
        points.append(RoutePoint(n + 1, f"WP{n + 1:02d} {label}", *ll(k), float(plan.t[k] - plan.t[0]), k, st, via))
    _set_radii(points, legs, r_ship)
    return Route(points, legs, r_ship, source, obstacles is not None)


def _set_radii(points: list[RoutePoint], legs: list[Leg | None], r_ship: float) -> None:
    """Turn radius per inner waypoint: the ship's radius, cut so the wheel-over arc fits in half
    of each adjacent leg (tangent length R tan(dchi/2))."""
    for i in range(1, len(points) - 1):
        a, b, c = points[i - 1], points[i], points[i + 1]
        c_in = GEOD.inv(a.lon, a.lat, b.lon, b.lat)[0]
        c_out = GEOD.inv(b.lon, b.lat, c.lon, c.lat)[0]
        dchi = abs((c_out - c_in + 180.0) % 360.0 - 180.0)
        r = min(r_ship, RADIUS_MAX_M)
        half_min = 0.5 * min(legs[i].length_m, legs[i + 1].length_m)
        if dchi > 0.5 and half_min > 0:
            r = min(r, half_min / math.tan(math.radians(min(dchi, 179.0)) / 2.0))
        b.radius_m = max(r, 0.0)


def corridor_polygons(route: Route, plan: Plan) -> list[BaseGeometry | None]:
    """The cross-track corridor of each leg as a metric polygon (x north, y east), as the XTD
    values say (None for the first waypoint)."""
    out: list[BaseGeometry | None] = [None]
    for i in range(1, len(route.points)):
        leg = route.legs[i]
        a = plan.track[route.points[i - 1].sample, :2]
        b = plan.track[route.points[i].sample, :2]
        out.append(corridor(a, b, leg.stbd_m, leg.port_m))
    return out


def corridor(a: np.ndarray, b: np.ndarray, stbd_m: float, port_m: float) -> BaseGeometry:
    """Rectangle port_m to port and stbd_m to starboard of the line a -> b (x north, y east)."""
    d = np.asarray(b, float) - np.asarray(a, float)
    length = float(np.hypot(*d))
    if length < 1e-6:
        return shapely.Point(*a).buffer(max(stbd_m, port_m))
    n = np.array([-d[1], d[0]]) / length
    return shapely.Polygon([a - port_m * n, b - port_m * n, b + stbd_m * n, a + stbd_m * n])
