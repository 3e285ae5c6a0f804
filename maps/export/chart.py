"""The chart around a plan: land, the other water the hull must avoid (shallow, restricted,
obstacles) and the depth areas, in WGS-84 lon/lat.

A plan JSON is self-contained: :func:`embed_chart` stores the part of the sea map around the
track in ``plan.stats["chart"]`` when the plan is written, so a later ``shiptrial export``
draws the same map and keeps the route's cross-track corridors off the same land without the
map file. :func:`plan_chart` picks the chart for an export: an explicit ``sea_map`` first, else
the one stored in the plan, else none.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.geometry import mapping, shape
from shapely.geometry.base import BaseGeometry

from maps.plan import Plan

DECIMALS = 7
CHART_KEY = "chart"


@dataclass
class Chart:
    """What an exporter draws and keeps the route off (lon/lat geometries).

    ``land``: land; ``no_go``: everything else the hull must avoid (shallow water for the
    plan's draught, restricted areas, charted obstacles); ``depth_areas``: (polygon,
    minimum depth in metres) for drawing; ``extent``: lon/lat box the chart is known in
    (None: everywhere), outside it nothing is known.
    """

    name: str = ""
    land: BaseGeometry = field(default_factory=shapely.Polygon)
    no_go: BaseGeometry = field(default_factory=shapely.Polygon)
    depth_areas: list[tuple[BaseGeometry, float]] = field(default_factory=list)
    extent: tuple[float, float, float, float] | None = None
    # local_obstacles per projection: every export of a plan builds its route on the same chart
    _local: dict[str, BaseGeometry] = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def obstacles(self) -> BaseGeometry:
        """Land and every other no-go area (lon/lat)."""
        return shapely.union(self.land, self.no_go)

    def is_empty(self) -> bool:
        return self.land.is_empty and self.no_go.is_empty and not self.depth_areas

    def local_obstacles(self, plan: Plan) -> BaseGeometry | None:
        """The obstacles in the plan's metric frame (shapely x = north, y = east), or None
        when the plan has no projection."""
        proj4 = (plan.projection or {}).get("proj4")
        if not proj4:
            return None
        if proj4 not in self._local:
            self._local[proj4] = self._project(proj4)
        return self._local[proj4]

    def _project(self, proj4: str) -> BaseGeometry:
        from maps.geo import transformer

        tr = transformer("EPSG:4326", proj4)

        def fwd(c: np.ndarray) -> np.ndarray:
            e, n = tr.transform(c[:, 0], c[:, 1])
            return np.column_stack([n, e])

        return shapely.transform(self.obstacles, fwd)

    def to_dict(self) -> dict[str, Any]:
        """JSON form stored in ``plan.stats['chart']`` (GeoJSON geometries, 7 decimals)."""
        return {
            "name": self.name,
            "land": _geom_json(self.land),
            "no_go": _geom_json(self.no_go),
            "depth_areas": [{"min_depth_m": d, "geometry": _geom_json(g)} for g, d in self.depth_areas],
            "extent": list(self.extent) if self.extent else None,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Chart:
        def geom(v: Any) -> BaseGeometry:
            return shape(v) if v else shapely.Polygon()

        ext = d.get("extent")
        return cls(
            name=str(d.get("name", "")),
            land=geom(d.get("land")),
            no_go=geom(d.get("no_go")),
            depth_areas=[(geom(a.get("geometry")), float(a.get("min_depth_m", 0.0))) for a in d.get("depth_areas", [])],
            extent=tuple(float(v) for v in ext) if ext else None,
        )


def _geom_json(g: BaseGeometry) -> dict[str, Any] | None:
    if g is None or g.is_empty:
        return None
    g = shapely.set_precision(g, 10.0**-DECIMALS)
    return json.loads(json.dumps(mapping(g)))  # tuples -> lists


def _depth_areas_of(features: list[dict]) -> list[tuple[BaseGeometry, float]]:
    out = []
    for f in features:
        p = f.get("properties") or {}
        d = p.get("min_depth_m")
        if p.get("kind") == "depth_area" and f.get("geometry") and isinstance(d, (int, float)):
            g = shape(f["geometry"])
            out.append((g if g.is_valid else shapely.make_valid(g), float(d)))
    return out


def chart_of(sea_map: Any) -> Chart | None:
    """A :class:`Chart` from a ``maps.geo.SeaMap``, a GeoJSON sea map (path or mapping), a
    shapely geometry or a list of them (all obstacles counted as land), or None."""
    if sea_map is None:
        return None
    if isinstance(sea_map, Chart):
        return sea_map
    if hasattr(sea_map, "obstacles") and hasattr(sea_map, "to_lonlat"):  # maps.geo.SeaMap (metric)

        def to_ll(c: np.ndarray) -> np.ndarray:
            return np.column_stack(sea_map.to_lonlat(c[:, 0], c[:, 1]))

        land = shapely.transform(sea_map.land, to_ll)
        others = shapely.transform(shapely.difference(sea_map.obstacles, sea_map.land), to_ll)
        depth: list[tuple[BaseGeometry, float]] = []
        try:  # depth areas for drawing come from the map file itself
            depth = _depth_areas_of(json.loads(Path(sea_map.source).read_text(encoding="utf-8")).get("features", []))
        except (OSError, ValueError, AttributeError, TypeError):
            pass
        return Chart(str(getattr(sea_map, "name", "")), land, others, depth, tuple(sea_map.lonlat_extent))
    if isinstance(sea_map, dict) and sea_map.get("type") == "FeatureCollection":
        from maps.export.mapplot import obstacle_geoms

        feats = sea_map.get("features", [])
        land = [
            shape(f["geometry"]) for f in feats if f.get("geometry") and (f.get("properties") or {}).get("kind", "land") == "land"
        ]
        other = [
            g
            for g in obstacle_geoms(
                {
                    "type": "FeatureCollection",
                    "features": [f for f in feats if (f.get("properties") or {}).get("kind", "land") != "land"],
                }
            )
        ]
        return Chart(
            str(sea_map.get("name", "")),
            shapely.union_all(land) if land else shapely.Polygon(),
            shapely.union_all(other) if other else shapely.Polygon(),
            _depth_areas_of(feats),
        )
    if isinstance(sea_map, (str, Path)):
        from maps.export.mapplot import load_geojson

        return chart_of(load_geojson(sea_map))
    from maps.export.mapplot import obstacle_geoms

    geoms = obstacle_geoms(sea_map)
    return Chart(land=shapely.union_all(geoms) if geoms else shapely.Polygon())


def plan_chart(plan: Plan, sea_map: Any = None) -> Chart | None:
    """The chart for exporting ``plan``: ``sea_map`` when given, else the chart stored in the plan."""
    if sea_map is not None:
        return chart_of(sea_map)
    d = plan.stats.get(CHART_KEY) if isinstance(plan.stats, dict) else None
    return Chart.from_dict(d) if isinstance(d, dict) else None


def chart_window(plan: Plan, pad_m: float | None = None) -> tuple[float, float, float, float]:
    """Lon/lat box around the track, ``pad_m`` wide on each side (default: 2 km or 10 ship
    lengths, whichever is more), that an embedded chart covers."""
    if pad_m is None:
        pad_m = max(2000.0, 10.0 * float(plan.hull[0] or 0.0))
    lon, lat = plan.lonlat[:, 0], plan.lonlat[:, 1]
    m_lat = 111_320.0
    m_lon = m_lat * math.cos(math.radians(float(np.mean(lat))))
    return (
        float(lon.min() - pad_m / m_lon),
        float(lat.min() - pad_m / m_lat),
        float(lon.max() + pad_m / m_lon),
        float(lat.max() + pad_m / m_lat),
    )


def embed_chart(plan: Plan, sea_map: Any, pad_m: float | None = None) -> dict[str, Any] | None:
    """Store the chart around the track in ``plan.stats['chart']`` (clipped to
    :func:`chart_window`); returns the stored dict (None without a chart or a track)."""
    chart = chart_of(sea_map)
    if chart is None or len(plan.lonlat) < 2:
        return None
    box = chart_window(plan, pad_m)
    clip = Chart(
        name=chart.name,
        land=shapely.clip_by_rect(chart.land, *box),
        no_go=shapely.clip_by_rect(chart.no_go, *box),
        depth_areas=[(c, d) for g, d in chart.depth_areas if not (c := shapely.clip_by_rect(g, *box)).is_empty],
        extent=box,
    )
    plan.stats[CHART_KEY] = clip.to_dict()
    return plan.stats[CHART_KEY]
