"""Sea maps: load a GeoJSON chart, validate and repair it, project it to a local metric frame.

Format (docs/commands/plan-trial.md: 'Sea maps'): a GeoJSON FeatureCollection in WGS-84 lon/lat (RFC 7946) whose
``properties.kind`` says what a feature is: ``land`` (Polygon/MultiPolygon, the default when
``kind`` is missing), ``depth_area`` (Polygon with ``min_depth_m``; shallower than draught +
under-keel clearance is an obstacle), ``obstacle`` (Point with ``radius_m``, required, or Polygon),
``restricted`` (no-go polygon), ``trial_area`` (where trials are allowed), ``start``/``goal``
(Point with optional ``heading_deg``).

Metric coordinates follow the ship convention: x north, y east (metres from the projection
origin, a transverse Mercator centred on the map). Shapely geometries of a :class:`SeaMap`
store (x north, y east) as their (x, y), the same frame as ``Primitive.footprint``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from pyproj import Transformer
from shapely.geometry import Point, shape
from shapely.geometry.base import BaseGeometry

from primitives.errors import UserError

KINDS = ("land", "depth_area", "obstacle", "restricted", "trial_area", "start", "goal")
POLYGONAL = ("Polygon", "MultiPolygon")


# the map's projection exactly as :func:`load_map` writes it (and plan.json keeps it: centre to 9 decimals);
# any other string (a hand-edited plan.json's "lat_0=1.2.3" that CRS() refuses but PROJ's pipeline parser
# would read as 1.2) goes through ``from_crs`` and its errors
_TMERC = re.compile(
    r"\+proj=tmerc \+lat_0=(-?[0-9]+\.[0-9]{9}) \+lon_0=(-?[0-9]+\.[0-9]{9}) "
    r"\+k=1 \+x_0=0 \+y_0=0 \+ellps=WGS84 \+units=m \+no_defs"
)
_DEG_RAD = "+proj=unitconvert +xy_in=deg +xy_out=rad"


@lru_cache(maxsize=16)
def transformer(src: str, dst: str) -> Transformer:
    """``Transformer.from_crs(src, dst, always_xy=True)``, built once per pair of CRS strings (a plan's map
    projection, export chart, sea room and corridors each need the map's transverse Mercator one way or
    the other; pyproj >= 3.1 Transformers are safe to share between threads).

    Between lon/lat (EPSG:4326) and the map's own transverse Mercator (:data:`_TMERC`) it is built from
    the PROJ pipeline that ``from_crs`` resolves that pair to (``Transformer.definition``: degrees to
    radians, then tmerc; the inverse the other way): the same operations and the same numbers (a test
    compares them bit for bit with ``from_crs``), without the search of PROJ's database (30 ms of CPU a
    transformer, paid again whenever a pickled :class:`SeaMap` is loaded: the drawer's, the plan cache's)."""
    fwd, inv = _TMERC.fullmatch(dst) if src == "EPSG:4326" else None, _TMERC.fullmatch(src) if dst == "EPSG:4326" else None
    tm = fwd or inv
    if tm is None:
        return Transformer.from_crs(src, dst, always_xy=True)
    step = f"+proj=tmerc +lat_0={tm[1]} +lon_0={tm[2]} +k=1 +x_0=0 +y_0=0 +ellps=WGS84"
    if fwd is not None:
        return Transformer.from_pipeline(f"+proj=pipeline +step {_DEG_RAD} +step {step}")
    return Transformer.from_pipeline(f"+proj=pipeline +step +inv {step} +step +inv {_DEG_RAD}")


class MapError(UserError):
    """A sea map that cannot be used; the message names the file, feature and fix."""


def bundled_map_path(name: str = "helsinki") -> Path:
    """Path of a sea map shipped with the package (``maps/data/<name>.geojson``)."""
    return Path(__file__).resolve().parent / "data" / f"{name}.geojson"


def bundled_map_names() -> list[str]:
    """Names of the sea maps shipped with the package (``helsinki``, ``open-sea``)."""
    return sorted(p.stem for p in bundled_map_path().parent.glob("*.geojson"))


def map_source(path: str | Path | None) -> Path:
    """The file a ``--map`` value names: an existing file as given, else a bundled map's name
    (``open-sea``) resolved to its file, as ``--ship kvlcc2`` names a bundled profile; None is the
    Helsinki example."""
    if path is None:
        return bundled_map_path()
    path = Path(path)
    if not path.exists() and path.name == str(path) and bundled_map_path(path.name).is_file():
        return bundled_map_path(path.name)
    return path


@dataclass
class MapPoint:
    """A start or goal point of the map (metric, ship convention) with its lon/lat."""

    x: float
    y: float
    psi: float | None
    lon: float
    lat: float


#: :meth:`SeaMap.no_go`'s geometries, keyed by the ids of the obstacles and trial area (held beside the result, and
#: checked by identity), the extent and the margin; at most _NO_GO_KEPT of them
_NO_GO: dict[tuple[int, int, tuple[float, ...], float], tuple[BaseGeometry, BaseGeometry | None, BaseGeometry]] = {}
_NO_GO_KEPT = 16


@dataclass
class SeaMap:
    """A projected sea map. Geometries are (x north, y east) in metres.

    ``land``: land polygons; ``obstacles``: everything the hull must not touch (land, shallow
    depth areas, obstacles, restricted areas), unbuffered; ``trial_area``: where trials may be
    run (None: anywhere on the map); ``extent``: (xmin, ymin, xmax, ymax) of the map's features.
    """

    name: str
    source: str
    lon0: float
    lat0: float
    proj4: str
    land: BaseGeometry
    obstacles: BaseGeometry
    trial_area: BaseGeometry | None
    extent: tuple[float, float, float, float]
    lonlat_extent: tuple[float, float, float, float]
    start: MapPoint | None = None
    goal: MapPoint | None = None
    draught_m: float = 0.0
    ukc_m: float = 0.0
    n_shallow: int = 0
    warnings: list[str] = field(default_factory=list)
    _fwd: Any = field(default=None, repr=False)
    _inv: Any = field(default=None, repr=False)

    # -- projection ---------------------------------------------------------------------------
    def to_local(self, lon: Any, lat: Any) -> tuple[np.ndarray, np.ndarray]:
        """lon/lat (degrees) -> (x north, y east) in metres."""
        e, n = self._fwd.transform(np.asarray(lon, float), np.asarray(lat, float))
        return np.asarray(n), np.asarray(e)

    def to_lonlat(self, x: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
        """(x north, y east) in metres -> lon, lat (degrees)."""
        lon, lat = self._inv.transform(np.asarray(y, float), np.asarray(x, float))
        return np.asarray(lon), np.asarray(lat)

    def projection_info(self) -> dict[str, Any]:
        """What an exporter needs to go metric <-> lon/lat without the map."""
        return {"proj4": self.proj4, "lon0": self.lon0, "lat0": self.lat0, "axis_order": "x_north,y_east"}

    # -- queries ------------------------------------------------------------------------------
    def no_go(self, margin: float = 0.0) -> BaseGeometry:
        """Obstacles buffered by ``margin``, plus everything outside the trial area. Made once per
        obstacles, trial area, extent and margin (:data:`_NO_GO`): a plan asks for it 7 times (the start and
        goal checks, the lattice, sizing, smoothing, verification), each a buffer or union of the whole map."""
        kept = self._kept_no_go(margin)
        if kept is not None:
            return kept  # shapely geometries are immutable: the same object serves every caller
        geom = self.obstacles.buffer(margin) if margin > 0 else self.obstacles
        if self.trial_area is not None:
            xmin, ymin, xmax, ymax = self.extent
            big = shapely.box(xmin - 1e5, ymin - 1e5, xmax + 1e5, ymax + 1e5)
            geom = shapely.union(geom, big.difference(self.trial_area))
        self.adopt_no_go(margin, geom)
        return geom

    def _no_go_key(self, margin: float) -> tuple[int, int, tuple[float, ...], float]:
        return (id(self.obstacles), id(self.trial_area), tuple(self.extent), float(margin))

    def _kept_no_go(self, margin: float) -> BaseGeometry | None:
        """:meth:`no_go` of ``margin`` as kept in this process for these very obstacles and trial area, else None (an id
        of a freed geometry may be reused by another: the kept inputs must be this map's own)."""
        kept = _NO_GO.get(self._no_go_key(margin))
        return kept[2] if kept is not None and kept[0] is self.obstacles and kept[1] is self.trial_area else None

    def has_no_go(self, margin: float) -> bool:
        """Whether :meth:`no_go` of ``margin`` is made already (kept in this process)."""
        return self._kept_no_go(margin) is not None

    def adopt_no_go(self, margin: float, geom: BaseGeometry) -> None:
        """Take ``geom`` as :meth:`no_go` of ``margin``: the geometry that call made for this map in another
        process (read back from :mod:`maps.mapcache`, the same coordinates)."""
        if len(_NO_GO) >= _NO_GO_KEPT:
            _NO_GO.clear()
        # the inputs held: their ids stay theirs while kept
        _NO_GO[self._no_go_key(margin)] = (self.obstacles, self.trial_area, geom)

    def clearance(self, geom: BaseGeometry) -> float:
        """Distance from ``geom`` to the nearest obstacle (0 when touching)."""
        return float(shapely.distance(geom, self.no_go())) if not self.no_go().is_empty else float("inf")

    def inside(self, x: float, y: float) -> bool:
        xmin, ymin, xmax, ymax = self.extent
        return xmin <= x <= xmax and ymin <= y <= ymax

    def locate(self, lat: float, lon: float, what: str, margin: float = 0.0) -> tuple[float, float]:
        """Project a user's (lat, lon) and check it is on the map, in navigable water.

        Raises MapError naming the point; says so when the numbers look swapped (lon, lat).
        """
        lo0, la0, lo1, la1 = self.lonlat_extent

        def on_map(la: float, lo: float) -> bool:
            return la0 <= la <= la1 and lo0 <= lo <= lo1

        if not on_map(lat, lon):
            hint = ""
            if on_map(lon, lat) or abs(lat) > 90:
                hint = f"; the values look swapped: give latitude first ({lon:g},{lat:g})"
            raise MapError(
                f"{self.source}: {what} lat {lat:g}, lon {lon:g} is outside the map "
                f"(lat {la0:.4f}..{la1:.4f}, lon {lo0:.4f}..{lo1:.4f}){hint}"
            )
        x, y = (float(v) for v in self.to_local(lon, lat))
        p = Point(x, y)
        if shapely.intersects(self.land, p):
            raise MapError(f"{self.source}: {what} lat {lat:g}, lon {lon:g} is on land: choose a point in open water")
        if self.trial_area is not None and not shapely.intersects(self.trial_area, p):
            raise MapError(
                f"{self.source}: {what} lat {lat:g}, lon {lon:g} is outside the map's trial_area: choose a point inside it"
            )
        if shapely.intersects(self.no_go(margin), p):
            d = float(shapely.distance(self.obstacles, p))  # inside the trial area: the obstacles' margin is what holds
            raise MapError(
                f"{self.source}: {what} lat {lat:g}, lon {lon:g} is not navigable ({d:.0f} m from a shallow, restricted or "
                f"obstacle area, within the margin of {margin:g} m): choose a point in open water"
            )
        return x, y


def _finite_number(v: Any) -> bool:
    """A JSON number that is finite (NaN, inf and integers beyond float range are not)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


def _fail(src: str, i: int, msg: str) -> MapError:
    return MapError(f"{src}: feature {i}: {msg}")


def _polygonal(geom: BaseGeometry) -> BaseGeometry:
    """Polygonal part of a (repaired) geometry."""
    if geom.geom_type in POLYGONAL:
        return geom
    parts = [g for g in getattr(geom, "geoms", []) if g.geom_type in POLYGONAL]
    return shapely.union_all(parts) if parts else shapely.Polygon()


def _check_coords(src: str, i: int, geom: BaseGeometry) -> None:
    xy = shapely.get_coordinates(geom)
    if len(xy) == 0:
        raise _fail(src, i, "geometry has no coordinates")
    if not np.all(np.isfinite(xy)):
        raise _fail(src, i, "coordinates are not finite numbers")
    lon, lat = xy[:, 0], xy[:, 1]
    if np.any(np.abs(lat) > 90) or np.any(np.abs(lon) > 180):
        swap = " (they look swapped: GeoJSON wants [lon, lat])" if np.all(np.abs(lon) <= 90) else ""
        raise _fail(src, i, f"coordinates out of range for WGS-84 lon/lat{swap}")


def load_map(path: str | Path | None = None, *, draught_m: float = 0.0, ukc_m: float = 0.5, repair: bool = True) -> SeaMap:
    """Load and project a GeoJSON sea map, a file or a bundled map's name (:func:`map_source`;
    default: the bundled Helsinki map).

    Invalid polygons are repaired with ``shapely.make_valid`` and reported in ``warnings``.
    Depth areas with ``min_depth_m < draught_m + ukc_m`` become obstacles.
    """
    path = map_source(path)
    src = str(path)
    doc = _read_collection(path, src)
    warnings: list[str] = []
    groups: dict[str, list[tuple[int, BaseGeometry, dict]]] = {k: [] for k in KINDS}
    for i, f in enumerate(doc["features"]):
        kind, geom, props = _feature(src, i, f, repair, warnings)
        if geom is not None:
            groups[kind].append((i, geom, props))
    _check_groups(src, groups)
    lo0, la0, lo1, la1 = _lonlat_extent(src, groups)
    lon0, lat0 = 0.5 * (lo0 + lo1), 0.5 * (la0 + la1)
    # projection: transverse Mercator centred on the map's extent
    proj4 = f"+proj=tmerc +lat_0={lat0:.9f} +lon_0={lon0:.9f} +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
    fwd = transformer("EPSG:4326", proj4)
    inv = transformer(proj4, "EPSG:4326")

    def project(arr: np.ndarray) -> np.ndarray:
        e, n = fwd.transform(arr[:, 0], arr[:, 1])
        return np.column_stack([n, e])

    land, obstacles, trial, n_shallow = _combine(src, groups, project, draught_m + ukc_m)
    ex = project(np.array([[lo0, la0], [lo1, la1], [lo0, la1], [lo1, la0]]))
    extent = (float(ex[:, 0].min()), float(ex[:, 1].min()), float(ex[:, 0].max()), float(ex[:, 1].max()))
    sm = SeaMap(
        name=str(doc.get("name") or path.stem),
        source=src,
        lon0=float(lon0),
        lat0=float(lat0),
        proj4=proj4,
        land=land,
        obstacles=obstacles,
        trial_area=trial,
        extent=extent,
        lonlat_extent=(float(lo0), float(la0), float(lo1), float(la1)),
        draught_m=draught_m,
        ukc_m=ukc_m,
        n_shallow=n_shallow,
        warnings=warnings,
        _fwd=fwd,
        _inv=inv,
    )
    _set_endpoints(sm, src, groups)
    return sm


def _read_collection(path: Path, src: str) -> dict:
    """The file's GeoJSON FeatureCollection, with at least one feature (MapError otherwise)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise MapError(
            f"{src}: no such map file (give a GeoJSON FeatureCollection or a bundled map's name: "
            f"{', '.join(bundled_map_names())}; omit --map for the Helsinki example)"
        ) from None
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise MapError(f"{src}: not valid JSON ({type(exc).__name__}): a sea map must be a GeoJSON FeatureCollection") from None
    except IsADirectoryError:
        raise MapError(f"{src}: is a directory; give a GeoJSON sea map file") from None
    if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection":
        raise MapError(f"{src}: field 'type' must be 'FeatureCollection' (GeoJSON, RFC 7946)")
    feats = doc.get("features")
    if not isinstance(feats, list) or not feats:
        raise MapError(f"{src}: the map has no features: add land/depth_area polygons (properties.kind) or a trial_area")
    return doc


def _feature(src: str, i: int, f: object, repair: bool, warnings: list[str]) -> tuple[str, BaseGeometry | None, dict]:
    """Feature ``i``'s kind, geometry (in degrees; an invalid polygon repaired and said in
    ``warnings`` when ``repair``) and properties, checked for what its kind needs; the geometry is None for a
    polygon other than the trial area that encloses no area (left out, said in ``warnings``)."""
    if not isinstance(f, dict) or f.get("type") != "Feature" or not isinstance(f.get("geometry"), dict):
        raise _fail(src, i, "not a GeoJSON Feature with a geometry")
    props = f.get("properties") or {}
    if not isinstance(props, dict):
        raise _fail(src, i, 'properties must be an object (e.g. {"kind": "land"})')
    kind = props.get("kind", "land")
    if kind not in KINDS:
        raise _fail(src, i, f"properties.kind {kind!r} unknown; use one of {', '.join(KINDS)}")
    try:
        geom = shape(f["geometry"])
    except Exception as exc:  # shapely raises several types for malformed coordinates
        raise _fail(src, i, f"malformed geometry ({exc})") from None
    _check_coords(src, i, geom)
    gt = geom.geom_type
    if kind in ("land", "depth_area", "restricted", "trial_area") and gt not in POLYGONAL:
        raise _fail(src, i, f"kind {kind!r} must be a Polygon or MultiPolygon, got {gt}")
    if kind == "obstacle" and gt not in POLYGONAL + ("Point",):
        raise _fail(src, i, f"kind 'obstacle' must be a Point (with radius_m) or a Polygon, got {gt}")
    if kind in ("start", "goal") and gt != "Point":
        raise _fail(src, i, f"kind {kind!r} must be a Point, got {gt}")
    corners = len(shapely.get_coordinates(geom))  # as given: the message below names them, not the repair's
    if gt in POLYGONAL and not geom.is_valid:
        reason = shapely.is_valid_reason(geom)
        if not repair:
            raise _fail(src, i, f"invalid polygon ({reason})")
        geom = _polygonal(shapely.make_valid(geom))
        warnings.append(f"feature {i} ({kind}): invalid polygon ({reason}) repaired with make_valid")
    if gt in POLYGONAL and not geom.area > 0:  # a ring on a line, or of fewer than three distinct corners
        if kind == "trial_area":  # it would allow no water at all
            raise _fail(
                src,
                i,
                f"the {kind} polygon encloses no area (its {corners} ring points lie "
                "on one line or repeat); give its corners, the first repeated last",
            )
        # land, depth, restricted or obstacle: a sliver (e.g. from a converted chart) blocks no water: left out
        warnings.append(f"feature {i} ({kind}): the polygon encloses no area ({corners} ring points on a line): left out")
        return kind, None, props
    if kind == "depth_area" and not _finite_number(props.get("min_depth_m")):
        raise _fail(src, i, "depth_area needs a numeric properties.min_depth_m (S-57 DRVAL1, metres)")
    if kind == "obstacle" and gt == "Point":
        if "radius_m" not in props:  # read as radius 0 before: a wreck or shoal of hundreds of metres planned as a point
            raise _fail(
                src,
                i,
                "obstacle point has no properties.radius_m: give the radius that keeps the ship clear in metres "
                "(0..100000; 0 for a mark of no extent, the --margin still applies)",
            )
        r = props["radius_m"]
        if not _finite_number(r) or not 0 <= r <= 1e5:
            raise _fail(src, i, "obstacle point needs properties.radius_m, 0..100000 metres")
    return kind, geom, props


def _check_groups(src: str, groups: dict[str, list[tuple[int, BaseGeometry, dict]]]) -> None:
    """At most one start and one goal, and at least one polygon saying where the water ends."""
    for k in ("start", "goal"):
        if len(groups[k]) > 1:
            raise MapError(f"{src}: {len(groups[k])} features of kind {k!r}; give at most one")
    if not any(g.geom_type in POLYGONAL for grp in groups.values() for _, g, _ in grp):
        raise MapError(
            f"{src}: the map holds only points (start, goal, point obstacles) and no land, depth_area, restricted or "
            "trial_area polygon, so it says nothing of where the water ends: add the coast as land polygons, or a "
            "trial_area polygon around the open water to plan in"
        )


def _lonlat_extent(src: str, groups: dict[str, list[tuple[int, BaseGeometry, dict]]]) -> tuple[float, float, float, float]:
    """(lon min, lat min, lon max, lat max) of every feature; refused when it covers no area or
    more than 180 degrees of longitude."""
    allxy = np.vstack([shapely.get_coordinates(g) for grp in groups.values() for _, g, _ in grp])
    lo0, la0 = allxy.min(axis=0)
    lo1, la1 = allxy.max(axis=0)
    if lo1 - lo0 <= 0 or la1 - la0 <= 0:
        raise MapError(f"{src}: the map's features cover no area: add land polygons or a trial_area polygon")
    if lo1 - lo0 > 180.0:  # the centre of such an extent is on the far side of the globe from the map
        raise MapError(
            f"{src}: the map's longitudes run from {lo0:g} to {lo1:g}, more than 180 degrees (a map across the 180th "
            "meridian reads so), which the map's projection (centred on its extent) cannot take: split the map at 180 "
            "degrees, or crop it to the trial's sea area, and plan on one side"
        )
    return lo0, la0, lo1, la1


def _combine(
    src: str,
    groups: dict[str, list[tuple[int, BaseGeometry, dict]]],
    project: Callable[[np.ndarray], np.ndarray],
    draft_need: float,
) -> tuple[BaseGeometry, BaseGeometry, BaseGeometry | None, int]:
    """Projected land, every obstacle (land, depth areas shallower than ``draft_need``, obstacles,
    restricted areas) as one prepared geometry, the trial area (None without one) and the
    number of shallow depth areas."""

    def proj_geoms(kind: str) -> list[BaseGeometry]:
        """The kind's geometries in metres; a polygon the projection leaves self-touching (vertices
        a few nanodegrees apart collapse) repaired again, as GEOS's overlay needs valid input."""
        gs = [g for _, g, _ in groups[kind]]
        out = list(shapely.transform(np.array(gs, dtype=object), project)) if gs else []
        return [_polygonal(shapely.make_valid(g)) if g.geom_type in POLYGONAL and not g.is_valid else g for g in out]

    try:
        land = shapely.union_all(proj_geoms("land")) if groups["land"] else shapely.Polygon()
        shallow = [
            g for (_, _, pr), g in zip(groups["depth_area"], proj_geoms("depth_area")) if float(pr["min_depth_m"]) < draft_need
        ]
        obst = []
        for (_, _, pr), g in zip(groups["obstacle"], proj_geoms("obstacle")):
            # radius 0 (given: a mark of no extent) is a 1 m disc: a point buffered by 0 is empty and blocks nothing
            obst.append(g.buffer(float(pr["radius_m"]) or 1.0) if g.geom_type == "Point" else g)
        restricted = proj_geoms("restricted")
        obstacles = shapely.union_all([land, *shallow, *obst, *restricted])
        trial = shapely.union_all(proj_geoms("trial_area")) if groups["trial_area"] else None
    except shapely.errors.GEOSException as exc:  # a topology GEOS cannot overlay even after make_valid
        raise MapError(
            f"{src}: the map's polygons cannot be combined ({str(exc).splitlines()[0][:80]}): repair them in a GIS "
            "(e.g. QGIS 'Fix geometries') or remove the self-touching polygon"
        ) from None
    shapely.prepare(land)
    shapely.prepare(obstacles)
    return land, obstacles, trial, len(shallow)


def _set_endpoints(sm: SeaMap, src: str, groups: dict[str, list[tuple[int, BaseGeometry, dict]]]) -> None:
    """The map's start and goal points (local metres, heading from north in radians), if given."""
    for k in ("start", "goal"):
        if groups[k]:
            i, g, pr = groups[k][0]
            hd = pr.get("heading_deg")
            if hd is not None and not (_finite_number(hd) and -360 <= hd <= 360):
                raise _fail(src, i, "properties.heading_deg must be a number of degrees from north, clockwise, within -360..360")
            x, y = (float(v) for v in sm.to_local(g.x, g.y))
            setattr(sm, k, MapPoint(x, y, None if hd is None else float(np.radians(float(hd))), float(g.x), float(g.y)))
