"""Loaders that cannot crash (issue 29): a saved plan read against its declared schema before any
exporter runs, sea maps repaired or refused, each in one line naming the file and the field."""

from __future__ import annotations

import json

import pytest
import shapely

from cli.app import _run
from maps.export._testing import synthetic_plan
from maps.geo import MapError, load_map


@pytest.fixture(scope="module")
def plan_doc():
    return json.loads(synthetic_plan("model-ship").to_json())


def _export(tmp_path, doc, fmt="rtz"):
    p = tmp_path / "plan.json"
    p.write_text(json.dumps(doc))
    return _run(["export", str(p), "--format", fmt, "--out", str(tmp_path / f"out.{fmt}")])


@pytest.mark.parametrize(
    "edit,fmt,field",
    [
        (lambda d: d.update(vessel_name="MT Nul\x00"), "rtz", "vessel_name"),
        (lambda d: d["steps"][0].update(description="go\x00"), "csv", "steps[0].description"),
        (lambda d: d["projection"].update(proj4="EPSG:999999"), "geojson", "projection.proj4"),
        (lambda d: d["projection"].update(proj4="EPSG:4326"), "geojson", "projection.proj4"),
        (lambda d: d.update(hull="long"), "gpx", "hull"),
        (lambda d: d["steps"][0].update(entry_lat=True), "rtz", "steps[0].entry_lat"),
        (lambda d: d["samples"]["lat"].__setitem__(3, 1e308), "gpx", "samples.lat"),
        (lambda d: d["samples"]["step"].__setitem__(3, 99), "csv", "samples.step"),
        (lambda d: d["samples"].update(x=d["samples"]["x"][:-1]), "csv", "samples.x"),
        (
            lambda d: d["stats"].update(chart={"land": {"type": "Polygon", "coordinates": [[[1, 2]]]}}),
            "geojson",
            "stats.chart.land",
        ),
        (lambda d: d["steps"][0]["orders"][0].update(t_s="soon"), "rtz", "steps[0].orders[0].t_s"),
        # the 5,000-example fuzz's find: a self-crossing land ring made GEOS's union raise a TopologyException
        (
            lambda d: d["stats"].update(
                chart={"land": {"type": "Polygon", "coordinates": [[[24.93, 60.11], [24.94, 60.11], [24.94, 60.13], [24.93, 0]]]}}
            ),
            "geojson",
            "stats.chart.land",
        ),
    ],
)
def test_a_malformed_plan_is_refused_naming_the_field(tmp_path, capsys, plan_doc, edit, fmt, field):
    """Each of these crashed an exporter (NUL in XML, unknown EPSG code, wrong types...)."""
    doc = json.loads(json.dumps(plan_doc))
    edit(doc)
    assert _export(tmp_path, doc, fmt) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"'{field}'" in err or f"'samples.{field.split('.')[-1]}'" in err, err
    assert not (tmp_path / f"out.{fmt}").exists()


def test_a_written_plan_passes_the_schema(tmp_path, plan_doc):
    assert _export(tmp_path, plan_doc, "geojson") == 0


def _map(tmp_path, features):
    p = tmp_path / "m.geojson"
    p.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    return p


def _point(kind, lon, lat, **props):
    return {"type": "Feature", "properties": {"kind": kind, **props}, "geometry": {"type": "Point", "coordinates": [lon, lat]}}


def test_a_map_of_points_only_is_refused_with_the_fix(tmp_path):
    """It was planned on with exit 0, as if the sea had no edge."""
    p = _map(tmp_path, [_point("start", 24.9, 60.1), _point("goal", 25.0, 60.2), _point("obstacle", 24.95, 60.15, radius_m=50)])
    with pytest.raises(MapError, match="only points .* add the coast as land polygons, or a trial_area polygon"):
        load_map(p)


def test_a_self_touching_polygon_is_repaired_and_said(tmp_path):
    ring = [[24.9, 60.1], [24.92, 60.1], [24.92, 60.12], [24.91, 60.1], [24.9, 60.12], [24.9, 60.1]]
    p = _map(
        tmp_path, [{"type": "Feature", "properties": {"kind": "land"}, "geometry": {"type": "Polygon", "coordinates": [ring]}}]
    )
    sea = load_map(p)
    assert sea.land.is_valid and not sea.land.is_empty
    assert any("repaired with make_valid" in w for w in sea.warnings)


def test_a_topology_geos_cannot_overlay_is_a_map_error(tmp_path, monkeypatch):
    """GEOS's TopologyException in the union of the map's polygons escaped load_map."""
    ring = [[24.9, 60.1], [24.92, 60.1], [24.92, 60.12], [24.9, 60.1]]
    p = _map(
        tmp_path, [{"type": "Feature", "properties": {"kind": "land"}, "geometry": {"type": "Polygon", "coordinates": [ring]}}]
    )

    def boom(*_a, **_k):
        raise shapely.errors.GEOSException("TopologyException: side location conflict at 24.91 60.11")

    monkeypatch.setattr(shapely, "union_all", boom)
    with pytest.raises(MapError, match=r"polygons cannot be combined \(TopologyException.*Fix geometries"):
        load_map(p)


def test_a_map_across_the_180th_meridian_is_refused_not_projected_from_the_far_side(tmp_path):
    """Features on both sides of 180 degrees put the map's centre (and its projection's meridian) at
    0 degrees: every distance would come out wrong without a word. Refused, naming the file and the fix."""
    import json

    land = [[[179.9, -17.0], [179.99, -17.0], [179.99, -16.9], [179.9, -16.9], [179.9, -17.0]]]
    east = [[[-179.99, -17.0], [-179.9, -17.0], [-179.9, -16.9], [-179.99, -16.9], [-179.99, -17.0]]]
    doc = {
        "type": "FeatureCollection",
        "features": [
            {"type": "Feature", "properties": {"kind": "land"}, "geometry": {"type": "Polygon", "coordinates": ring}}
            for ring in (land, east)
        ],
    }
    path = tmp_path / "fiji.geojson"
    path.write_text(json.dumps(doc))
    with pytest.raises(MapError, match=r"fiji.geojson: .* more than 180 degrees .* split the map at 180 degrees"):
        load_map(path)
