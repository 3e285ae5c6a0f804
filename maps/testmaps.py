"""Synthetic sea maps for tests and benchmarks: a fjord and an archipelago (made here, no source).

Shapes are given in a local metric frame (x north, y east, metres) around (lat0, lon0) and
written as GeoJSON in WGS-84 with an equirectangular approximation (good to a few metres over
20 km, more than the maps need: they are synthetic).
"""

from __future__ import annotations

import numpy as np
import shapely

M_PER_DEG = 111_320.0


def _lonlat(xy: np.ndarray, lat0: float, lon0: float) -> list[list[float]]:
    xy = np.asarray(xy, float)
    lat = lat0 + xy[:, 0] / M_PER_DEG
    lon = lon0 + xy[:, 1] / (M_PER_DEG * np.cos(np.radians(lat0)))
    return [[round(float(a), 7), round(float(b), 7)] for a, b in zip(lon, lat)]


def _feature(kind: str, geom, lat0: float, lon0: float, **props) -> dict:
    if geom.geom_type == "Point":
        c = _lonlat(np.array([[geom.x, geom.y]]), lat0, lon0)[0]
        return {"type": "Feature", "properties": {"kind": kind, **props}, "geometry": {"type": "Point", "coordinates": c}}
    rings = [_lonlat(np.asarray(geom.exterior.coords), lat0, lon0)]
    rings += [_lonlat(np.asarray(r.coords), lat0, lon0) for r in geom.interiors]
    return {"type": "Feature", "properties": {"kind": kind, **props}, "geometry": {"type": "Polygon", "coordinates": rings}}


def archipelago(lat0: float = 60.0, lon0: float = 25.0) -> dict:
    """8 km x 8 km of sea with seven islands between a start in the south-west and a goal in the
    north-east (for transit-length checks against an independent shortest path)."""
    islands = [
        ((2000, 2500), 600),
        ((3500, 1200), 500),
        ((4200, 4200), 700),
        ((2600, 5200), 450),
        ((5600, 2600), 550),
        ((6000, 5600), 600),
        ((1200, 4200), 350),
    ]
    feats = [_feature("trial_area", shapely.box(0, 0, 8000, 8000), lat0, lon0)]
    for (x, y), r in islands:
        feats.append(_feature("land", shapely.Point(x, y).buffer(r, quad_segs=4), lat0, lon0))
    feats.append(_feature("start", shapely.Point(500, 500), lat0, lon0, heading_deg=45.0))
    feats.append(_feature("goal", shapely.Point(7400, 7400), lat0, lon0))
    return {"type": "FeatureCollection", "name": "archipelago (synthetic)", "features": feats}


def fjord(lat0: float = 60.0, lon0: float = 5.0, length_m: float = 20_000.0, width_m: float = 6_000.0) -> dict:
    """A straight fjord ``length_m`` (north) x ``width_m`` (east) of open water between two
    shores, a headland on each side; start at the south end, goal at the north end."""
    L, W = length_m, width_m
    shore = 2000.0
    west = shapely.box(-2000, -shore, L + 2000, 0).union(shapely.Point(0.6 * L, 0).buffer(900, quad_segs=4))
    east = shapely.box(-2000, W, L + 2000, W + shore).union(shapely.Point(0.3 * L, W).buffer(900, quad_segs=4))
    feats = [
        _feature("land", west, lat0, lon0),
        _feature("land", east, lat0, lon0),
        _feature("trial_area", shapely.box(-1000, 0, L + 1000, W), lat0, lon0),
        _feature("start", shapely.Point(1500, 0.5 * W), lat0, lon0, heading_deg=0.0),
        _feature("goal", shapely.Point(L - 1500, 0.5 * W), lat0, lon0),
    ]
    return {"type": "FeatureCollection", "name": f"fjord {L / 1000:.0f} x {W / 1000:.0f} km (synthetic)", "features": feats}


def open_sea(lat0: float = 57.0, lon0: float = 11.0, size_m: float = 60_000.0) -> dict:
    """A square trial area of open deep water (``size_m`` on a side), start in the south-west
    corner heading north-east, goal in the north-east corner: room for a VLCC's trials."""
    S = size_m
    feats = [
        _feature("trial_area", shapely.box(0, 0, S, S), lat0, lon0),
        _feature("start", shapely.Point(0.1 * S, 0.1 * S), lat0, lon0, heading_deg=45.0),
        _feature("goal", shapely.Point(0.9 * S, 0.9 * S), lat0, lon0),
    ]
    return {"type": "FeatureCollection", "name": f"open sea {S / 1000:.0f} x {S / 1000:.0f} km (synthetic)", "features": feats}


def bay(lat0: float = 60.0, lon0: float = 5.0, length_m: float = 8_000.0, width_m: float = 6_000.0) -> dict:
    """``length_m`` (north) x ``width_m`` (east) of navigable water, start in the south-west heading
    north, goal ``width_m`` / 2 to the east of it: a VLCC turns round once to reach it (the
    issue-28 fjord piece of about 8 x 6 km, where the library's long manoeuvres fit nowhere)."""
    L, W = length_m, width_m
    feats = [
        _feature("trial_area", shapely.box(0, 0, L, W), lat0, lon0),
        _feature("start", shapely.Point(L / 8, W / 4), lat0, lon0, heading_deg=0.0),
        _feature("goal", shapely.Point(L / 8, 3 * W / 4), lat0, lon0),
    ]
    return {"type": "FeatureCollection", "name": f"bay {L / 1000:.0f} x {W / 1000:.0f} km (synthetic)", "features": feats}
