"""Sea maps: loading, validation, repair, projection and point checks."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely

from maps.geo import MapError, bundled_map_path, load_map


def fc(*features, name="test"):
    return {"type": "FeatureCollection", "name": name, "features": list(features)}


def feat(geom, **props):
    return {"type": "Feature", "geometry": geom, "properties": props}


def square(lon, lat, dlon, dlat):
    return {
        "type": "Polygon",
        "coordinates": [[[lon, lat], [lon + dlon, lat], [lon + dlon, lat + dlat], [lon, lat + dlat], [lon, lat]]],
    }


def write(tmp_path, doc, name="m.geojson"):
    p = tmp_path / name
    p.write_text(json.dumps(doc))
    return p


def test_bundled_helsinki_loads_projected_in_ship_frame():
    sea = load_map()
    assert sea.land.geom_type in ("Polygon", "MultiPolygon") and sea.land.area > 1e7  # tens of km2 of land
    assert sea.warnings == []
    # x north, y east: a point north-east of the centre has x > 0 and y > 0
    x, y = sea.to_local(sea.lon0 + 0.01, sea.lat0 + 0.01)
    assert x > 1000 and y > 500
    lon, lat = sea.to_lonlat(x, y)
    assert abs(lon - (sea.lon0 + 0.01)) < 1e-9 and abs(lat - (sea.lat0 + 0.01)) < 1e-9
    # the map spans about 19 km north-south and 17-20 km east-west
    xmin, ymin, xmax, ymax = sea.extent
    assert 15e3 < xmax - xmin < 20e3 and 15e3 < ymax - ymin < 22e3


def test_projection_is_metric():
    sea = load_map()
    x0, y0 = sea.to_local(24.95, 60.10)
    x1, y1 = sea.to_local(24.95, 60.11)  # 0.01 deg latitude = 1113 m
    assert abs((x1 - x0) - 1113.0) < 5 and abs(y1 - y0) < 1


def test_invalid_polygon_repaired_and_reported(tmp_path):
    bowtie = {"type": "Polygon", "coordinates": [[[25.0, 60.0], [25.02, 60.01], [25.02, 60.0], [25.0, 60.01], [25.0, 60.0]]]}
    sea = load_map(write(tmp_path, fc(feat(bowtie, kind="land"), feat(square(24.98, 59.98, 0.06, 0.04), kind="trial_area"))))
    assert sea.land.is_valid and sea.land.area > 0
    assert any("repaired" in w and "feature 0" in w for w in sea.warnings)


def test_depth_areas_shallower_than_draught_plus_ukc_are_obstacles(tmp_path):
    doc = fc(
        feat(square(25.0, 60.0, 0.01, 0.005), kind="depth_area", min_depth_m=2.0),
        feat(square(25.03, 60.0, 0.01, 0.005), kind="depth_area", min_depth_m=10.0),
        feat(square(24.99, 59.99, 0.06, 0.03), kind="trial_area"),
    )
    p = write(tmp_path, doc)
    deep_ship = load_map(p, draught_m=2.5, ukc_m=0.5)
    assert deep_ship.n_shallow == 1
    x, y = deep_ship.to_local(25.005, 60.0025)
    assert deep_ship.obstacles.contains(shapely.Point(float(x), float(y)))
    x2, y2 = deep_ship.to_local(25.035, 60.0025)
    assert not deep_ship.obstacles.contains(shapely.Point(float(x2), float(y2)))
    small = load_map(p, draught_m=1.0, ukc_m=0.5)
    assert small.n_shallow == 0


def test_obstacle_point_radius_and_start_goal(tmp_path):
    doc = fc(
        feat({"type": "Point", "coordinates": [25.01, 60.005]}, kind="obstacle", radius_m=100.0),
        feat({"type": "Point", "coordinates": [25.0, 60.0]}, kind="start", heading_deg=90),
        feat({"type": "Point", "coordinates": [25.03, 60.01]}, kind="goal"),
        feat(square(24.98, 59.99, 0.07, 0.03), kind="trial_area"),
    )
    sea = load_map(write(tmp_path, doc))
    assert abs(sea.obstacles.area - np.pi * 100**2) < 0.02 * np.pi * 100**2
    assert sea.start is not None and abs(sea.start.psi - np.pi / 2) < 1e-12 and sea.goal.psi is None


@pytest.mark.parametrize(
    "doc, words",
    [
        (fc(), "no features"),
        (fc(feat({"type": "LineString", "coordinates": [[25, 60], [25.1, 60.1]]}, kind="land")), "must be a Polygon"),
        (fc(feat(square(25, 60, 0.1, 0.1), kind="harbour")), "unknown"),
        (fc(feat(square(25, 60, 0.1, 0.1), kind="depth_area")), "min_depth_m"),
        (fc(feat({"type": "Polygon", "coordinates": [[[60, 125], [60.1, 125], [60.1, 125.1], [60, 125]]]})), "swapped"),
        ({"type": "Feature"}, "FeatureCollection"),
        # a ring of three points (two distinct corners) and one on a line: no water at all, stop 60's sweep had the
        # plan refuse the start "nan m from an obstacle"
        (fc(feat({"type": "Polygon", "coordinates": [[[25, 60], [25.1, 60], [25, 60]]]}, kind="trial_area")), "encloses no area"),
        # a JSON integer beyond int64 (found by the fuzz test) and a heading of turns, not degrees
        (
            fc(
                feat(square(25, 60, 0.1, 0.1)),
                feat({"type": "Point", "coordinates": [25.2, 60.2]}, kind="start", heading_deg=2**70),
            ),
            "within -360..360",
        ),
        (
            fc(
                feat(square(25, 60, 0.1, 0.1)), feat({"type": "Point", "coordinates": [25.2, 60.2]}, kind="goal", heading_deg=720)
            ),
            "within -360..360",
        ),
    ],
)
def test_bad_maps_rejected_with_reason(tmp_path, doc, words):
    with pytest.raises(MapError, match=words):
        load_map(write(tmp_path, doc))


def test_an_obstacle_point_without_radius_is_refused_and_radius_0_is_a_mark(tmp_path):
    """Stop 61: an obstacle point without properties.radius_m was read as radius 0 (a 1 m disc), so a wreck whose
    radius the user forgot was planned past within the margin. Refused naming the feature and the field; a radius of
    0 given explicitly is a mark of no extent (a pile, a buoy): kept, as a 1 m disc the margin keeps the ship off."""
    start, goal = (
        feat({"type": "Point", "coordinates": c}, kind=k) for c, k in (([25.0, 60.0], "start"), ([25.03, 60.01], "goal"))
    )
    area = feat(square(24.98, 59.99, 0.07, 0.03), kind="trial_area")
    point = {"type": "Point", "coordinates": [25.01, 60.005]}
    with pytest.raises(MapError, match=r"m.geojson: feature 3: obstacle point has no properties.radius_m: give"):
        load_map(write(tmp_path, fc(start, goal, area, feat(point, kind="obstacle"))))
    sea = load_map(write(tmp_path, fc(start, goal, area, feat(point, kind="obstacle", radius_m=0))))
    assert abs(sea.obstacles.area - np.pi) < 0.05 * np.pi


def test_a_land_sliver_without_area_is_left_out_with_a_warning(tmp_path):
    """A land, depth or restricted polygon on a line (a sliver from a converted chart) blocks no water: the map loads
    without it and says so; only a trial area without area is refused (above), since it would allow no water."""
    sliver = {"type": "Polygon", "coordinates": [[[25, 60], [25.1, 60], [25.2, 60], [25, 60]]]}
    sea = load_map(write(tmp_path, fc(feat(square(25, 60.2, 0.1, 0.1)), feat(sliver, kind="land"))))
    alone = load_map(write(tmp_path, fc(feat(square(25, 60.2, 0.1, 0.1))), name="alone.geojson"))
    assert [w for w in sea.warnings if "encloses no area" in w] == [
        "feature 1 (land): the polygon encloses no area (4 ring points on a line): left out"
    ]
    assert sea.land.equals(alone.land)


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(MapError, match="no such map"):
        load_map(tmp_path / "nope.geojson")
    bad = tmp_path / "bad.geojson"
    bad.write_text("{not json")
    with pytest.raises(MapError, match="not valid JSON"):
        load_map(bad)


def test_locate_checks_land_outside_and_swapped():
    sea = load_map()
    x, y = sea.locate(60.1625, 24.9600, "start")
    assert np.isfinite(x) and np.isfinite(y)
    with pytest.raises(MapError, match="on land"):
        sea.locate(60.170, 24.940, "start")  # Helsinki peninsula
    with pytest.raises(MapError, match="swapped"):
        sea.locate(24.96, 60.16, "start")
    with pytest.raises(MapError, match="outside the map"):
        sea.locate(59.0, 24.96, "goal")


def test_bundled_map_is_packaged():
    assert bundled_map_path().is_file()


@pytest.mark.parametrize("lat0, lon0", [(60.17, 24.95), (-33.85, 151.21), (0.0, -179.9), (71.3, -8.25)])
def test_map_transformers_give_from_crs_numbers_bit_for_bit(lat0, lon0):
    """The map's transverse Mercator both ways (built from PROJ's pipeline, not searched in its database)
    gives exactly what ``Transformer.from_crs`` gives, and survives a pickle (the drawer's and the plan
    cache's copy of a SeaMap); other pairs are ``from_crs``'s own."""
    import pickle

    from pyproj import Transformer

    from maps.geo import transformer

    proj4 = f"+proj=tmerc +lat_0={lat0:.9f} +lon_0={lon0:.9f} +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
    rng = np.random.default_rng(7)
    lon, lat = lon0 + rng.uniform(-0.5, 0.5, 5000), lat0 + rng.uniform(-0.3, 0.3, 5000)
    fwd, inv = transformer("EPSG:4326", proj4), transformer(proj4, "EPSG:4326")
    ref_fwd = Transformer.from_crs("EPSG:4326", proj4, always_xy=True)
    ref_inv = Transformer.from_crs(proj4, "EPSG:4326", always_xy=True)
    e, n = ref_fwd.transform(lon, lat)
    for got, want in ((fwd.transform(lon, lat), (e, n)), (inv.transform(e, n), ref_inv.transform(e, n))):
        assert all(np.array_equal(g, w) for g, w in zip(got, want))
    assert all(np.array_equal(g, w) for g, w in zip(pickle.loads(pickle.dumps(inv)).transform(e, n), ref_inv.transform(e, n)))
    assert transformer("EPSG:4326", proj4) is fwd  # built once per pair
    from pyproj.exceptions import CRSError

    with pytest.raises(CRSError):  # not load_map's form: from_crs's refusal, not PROJ's pipeline reading it as 1.2
        transformer("EPSG:4326", proj4.replace(f"+lat_0={lat0:.9f}", "+lat_0=1.2.3"))
    other = transformer("EPSG:4326", "EPSG:3857")
    assert other.definition == Transformer.from_crs("EPSG:4326", "EPSG:3857", always_xy=True).definition


def test_no_go_is_made_once_and_is_what_it_was(tmp_path):
    # stop 52: SeaMap.no_go kept per obstacles, trial area, extent and margin; the same bits as made afresh, and a
    # map with other obstacles or another trial area is never served another's
    from dataclasses import replace

    import maps.geo as geo

    doc = fc(feat(square(25.0, 60.0, 0.01, 0.01), kind="land"), feat(square(24.98, 59.98, 0.06, 0.04), kind="trial_area"))
    sea = load_map(write(tmp_path, doc))
    assert sea.trial_area is not None
    geo._NO_GO.clear()
    made = {m: sea.no_go(m) for m in (0.0, 20.0)}
    assert sea.no_go(0.0) is made[0.0] and sea.no_go(20) is made[20.0]
    geo._NO_GO.clear()
    for m, g in made.items():
        assert shapely.to_wkb(sea.no_go(m)) == shapely.to_wkb(g)
    smaller = replace(sea, obstacles=sea.obstacles.buffer(-1.0))
    assert shapely.to_wkb(smaller.no_go(20.0)) != shapely.to_wkb(made[20.0])
    open_water = replace(sea, trial_area=None)
    assert open_water.no_go(0.0) is sea.obstacles  # nothing outside a trial area added
    assert shapely.to_wkb(sea.no_go(0.0)) != shapely.to_wkb(open_water.no_go(0.0))


def test_a_point_outside_the_trial_area_is_named_so(tmp_path):
    """Stop 60: a start outside the trial area (of a bow-tie trial area repaired by make_valid, or a typo) was
    "not navigable (shallow, restricted, outside the trial area or nan m from an obstacle, ...)"."""
    sea = load_map(
        write(
            tmp_path,
            fc(
                feat(square(25, 60, 0.1, 0.1), kind="trial_area"),
                feat(square(25.15, 60.0, 0.05, 0.05), kind="land"),
                feat({"type": "Point", "coordinates": [25.05, 60.05]}, kind="obstacle", radius_m=100),
            ),
        )
    )
    with pytest.raises(MapError, match=r"start lat 60.02, lon 25.12 is outside the map's trial_area: choose a point inside"):
        sea.locate(60.02, 25.12, "start")
    with pytest.raises(MapError, match=r"goal lat 60.05, lon 25.0525 is not navigable \(\d+ m from a shallow, restricted or "):
        sea.locate(60.05, 25.0525, "goal", margin=200.0)
