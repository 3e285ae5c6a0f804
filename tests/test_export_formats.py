"""Exports of synthetic plans: GeoJSON (RFC 7946), GPX 1.1, RTZ 1.2 (XSD), CSV schedule."""

from __future__ import annotations

import copy
import csv
import io
import json
import re

import numpy as np
import pytest

from maps.export import ExportError, export_plan
from maps.export._common import KN_PER_MPS, M_PER_NM, cross_track, latlon_dm, waypoints
from maps.export._testing import synthetic_plan
from maps.export.geojson import plan_geojson, validate_geojson
from maps.export.gpx import plan_gpx
from maps.export.rtz import RTZ_NS, plan_rtz, validate_rtz
from maps.plan import Plan

START = "2026-06-01T08:00:00Z"


@pytest.fixture(scope="module")
def azi_plan() -> Plan:
    return synthetic_plan("full-scale")


@pytest.fixture(scope="module")
def model_plan() -> Plan:
    return synthetic_plan("model-ship")


# -- GeoJSON ---------------------------------------------------------------------------------


def test_geojson_passes_rfc7946_check_and_holds_track_and_starts(azi_plan, tmp_path):
    path = export_plan(azi_plan, "geojson", tmp_path / "t.geojson")[0]
    obj = json.loads(path.read_text())
    assert validate_geojson(obj) == []
    assert "crs" not in obj
    kinds = [f["properties"]["kind"] for f in obj["features"]]
    assert kinds.count("manoeuvre_start") + kinds.count("execute_point") == len(azi_plan.steps)
    tracks = [f for f in obj["features"] if f["properties"]["kind"] == "track"]
    # lon, lat order: the first position is the plan's start (lon 24.95, lat 60.12)
    assert tracks[0]["geometry"]["coordinates"][0] == [24.95, 60.12]
    np.testing.assert_allclose(tracks[-1]["geometry"]["coordinates"][-1], azi_plan.lonlat[-1], atol=1e-7)
    starts = [f for f in obj["features"] if f["properties"]["kind"] in ("manoeuvre_start", "execute_point")]
    for f, st in zip(starts, azi_plan.steps):
        p = f["properties"]
        assert p["index"] == st.index + 1 and p["primitive"] == st.primitive and p["commands"] == st.commands
        assert p["duration_s"] == pytest.approx(st.duration_s, abs=0.01)
        assert p["entry_heading_deg"] == pytest.approx(st.entry_heading_deg, abs=0.05)
        assert p["entry_speed_kn"] == pytest.approx(st.entry_speed_mps * KN_PER_MPS, abs=0.01)
        np.testing.assert_allclose(f["geometry"]["coordinates"], [st.entry_lon, st.entry_lat], atol=1e-7)
    # every number has at most 7 decimals in the written text
    assert not re.search(r"\d\.\d{8,}", path.read_text())


def test_geojson_tags_every_segment_and_trajectory_differs_from_overlay(tmp_path):
    plan = synthetic_plan("full-scale", ("straight", "zigzag_10_10_s", "turn_s", "tau17", "straight"), run_in=True)
    overlay = plan_geojson(plan)
    traj = plan_geojson(plan, overlay=False)
    assert validate_geojson(overlay) == [] and validate_geojson(traj) == []
    segs = [f["properties"] for f in traj["features"]]
    assert {f["properties"]["kind"] for f in traj["features"]} == {"track"}
    # transit, run-in, zig-zag, transit + run-in merge? no: turn_s is transit, then run-in, tau17, transit
    assert [(p["segment"], p["primitive"]) for p in segs] == [
        ("transit", None),
        ("run-in", None),
        ("informative", "zigzag_10_10_s"),
        ("transit", None),
        ("run-in", None),
        ("informative", "tau17"),
        ("transit", None),
    ]
    # the segments join end to start and together are the whole track
    coords = [f["geometry"]["coordinates"] for f in traj["features"]]
    assert all(a[-1] == b[0] for a, b in zip(coords[:-1], coords[1:]))
    assert sum(p["duration_s"] for p in segs) == pytest.approx(plan.duration_s, abs=0.01)
    # the overlay adds execute points (with orders in the ship's terms), corridors and the sea room
    kinds = [f["properties"]["kind"] for f in overlay["features"]]
    assert kinds.count("execute_point") == 2 and "corridor" in kinds and "sea_room" in kinds
    ex = next(f["properties"] for f in overlay["features"] if f["properties"]["kind"] == "execute_point")
    assert ex["primitive"] == "zigzag_10_10_s" and ex["orders"] and "Azimuth" in " ".join(ex["orders"])
    assert ex["abort"] and any("speed" in a for a in ex["abort"])


def test_geojson_sea_room_polygon_is_ccw_and_contains_the_track(azi_plan):
    from shapely.geometry import Point, shape

    obj = plan_geojson(azi_plan)
    room = next(f for f in obj["features"] if f["properties"]["kind"] == "sea_room")["geometry"]
    ring = np.asarray(room["coordinates"][0])
    area = 0.5 * np.sum(ring[:-1, 0] * ring[1:, 1] - ring[1:, 0] * ring[:-1, 1])
    assert area > 0
    poly = shape(room)
    assert all(poly.buffer(1e-6).contains(Point(lon, lat)) for lon, lat in azi_plan.lonlat[::25])


@pytest.mark.parametrize(
    "geom, message",
    [
        ({"type": "Point", "coordinates": [60.12, 124.95]}, "latitude"),
        ({"type": "Point", "coordinates": [24.123456789, 60.1]}, "decimals"),
        ({"type": "LineString", "coordinates": [[24.9, 60.1]]}, "2 or more"),
        ({"type": "Polygon", "coordinates": [[[0, 0], [0, 1], [1, 1], [1, 0], [0, 0]]]}, "counter-clockwise"),
        ({"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], [0, 0.5]]]}, "not closed"),
    ],
)
def test_geojson_checker_rejects_rfc7946_violations(geom, message):
    errs = validate_geojson({"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": geom, "properties": {}}]})
    assert any(message in e for e in errs), errs


def test_geojson_checker_rejects_crs_member():
    assert any("crs" in e for e in validate_geojson({"type": "FeatureCollection", "features": [], "crs": {}}))


# -- GPX -------------------------------------------------------------------------------------


def test_gpx_route_parses_with_gpxpy(azi_plan, tmp_path):
    import gpxpy

    path = export_plan(azi_plan, "gpx", tmp_path / "t.gpx", start=START)[0]
    gpx = gpxpy.parse(path.read_text(encoding="utf-8"))
    assert gpx.version == "1.1"
    (rte,) = gpx.routes
    assert len(rte.points) == len(azi_plan.steps) + 1
    for pt, st in zip(rte.points, azi_plan.steps):
        assert pt.name.endswith(st.primitive)
        assert pt.latitude == pytest.approx(st.entry_lat, abs=1e-7) and pt.longitude == pytest.approx(st.entry_lon, abs=1e-7)
        for o in st.orders:
            assert o["text"] in pt.description
    assert rte.points[-1].name.endswith("end")
    times = [p.time for p in rte.points]
    assert times == sorted(times) and (times[-1] - times[0]).total_seconds() == pytest.approx(azi_plan.duration_s, abs=1)
    assert times[0].isoformat().startswith("2026-06-01T08:00:00")
    assert len(gpx.tracks[0].segments[0].points) == len(azi_plan.t)


def test_gpx_of_subsecond_plan_has_distinct_track_times(model_plan):
    import gpxpy

    gpx = gpxpy.parse(plan_gpx(model_plan, start=START).decode())
    times = [p.time for p in gpx.tracks[0].segments[0].points]
    assert len(set(times)) == len(times)


# -- RTZ -------------------------------------------------------------------------------------


def test_rtz_validates_against_the_rtz12_xsd(azi_plan, model_plan, tmp_path):
    for plan in (azi_plan, model_plan):
        path = export_plan(plan, "rtz", tmp_path / f"{plan.ship}.rtz", start=START)[0]
        assert validate_rtz(path) == []


def test_rtz_waypoints_legs_xtd_speeds_schedule_and_extensions(azi_plan):
    from lxml import etree

    doc = etree.fromstring(plan_rtz(azi_plan, route_name="trial", start=START))
    ns = {"r": RTZ_NS}
    wps = doc.findall("r:waypoints/r:waypoint", ns)
    assert len(wps) == len(azi_plan.steps) + 1  # no chart: no via points
    assert wps[0].find("r:leg", ns) is None and all(w.find("r:leg", ns) is not None for w in wps[1:])
    half = 0.5 * azi_plan.hull[1] + azi_plan.margin_m
    ours = waypoints(azi_plan)
    for i, w in enumerate(wps[1:], start=1):
        leg = w.find("r:leg", ns)
        stbd, port = cross_track(azi_plan, ours, i)
        # excursion + half beam + margin, rounded down to 0.001 NM
        assert 0 <= (stbd + half) / M_PER_NM - float(leg.get("starboardXTD")) < 1.001e-3
        assert 0 <= (port + half) / M_PER_NM - float(leg.get("portsideXTD")) < 1.001e-3
        assert float(leg.get("speedMax")) <= np.max(azi_plan.speed) * KN_PER_MPS + 0.01
    # the zig-zag leg (into waypoint 3) swings out to both sides by more than the corridor half width
    zz = wps[2].find("r:leg", ns)
    assert float(zz.get("starboardXTD")) > (half + 5) / M_PER_NM
    # the straight first leg is sailed at the cruise speed, 3 m/s = 5.83 kn
    assert float(wps[1].find("r:leg", ns).get("speedMin")) == pytest.approx(5.83, abs=0.01)
    elems = doc.findall("r:schedules/r:schedule/r:calculated/r:scheduleElement", ns)
    assert [int(e.get("waypointId")) for e in elems] == [int(w.get("id")) for w in wps]
    assert elems[0].get("etd") == "2026-06-01T08:00:00Z" and elems[0].get("eta") is None and elems[0].get("speed") is None
    assert elems[-1].get("etd") is None
    assert elems[2].get("eta") == "2026-06-01T08:03:51Z"  # zig-zag of 181 s after a 50 s straight
    # each leg's own speed: the straight run into waypoint 2 at 5.83 kn, not the zig-zag's
    assert float(elems[1].get("speed")) == pytest.approx(5.83, abs=0.02)
    ext = wps[1].find("r:extensions/r:extension", ns)
    assert ext.get("manufacturer") == "shiptrial" and ext.get("name") == "trialManoeuvre"
    orders = [c.text for c in ext.iter("{urn:shiptrial:rtz-trial:1}order")]
    assert orders == [o["text"] for o in azi_plan.steps[1].orders] and orders
    assert [c for c in ext.iter("{urn:shiptrial:rtz-trial:1}abort")]


def test_rtz_validation_catches_schema_and_rule_violations(azi_plan):
    good = plan_rtz(azi_plan, route_name="trial", start=START)
    assert validate_rtz(good, file_name="trial.rtz") == []
    bad_xtd = re.sub(rb'starboardXTD="[0-9.]+"', b'starboardXTD="12.5"', good, count=1)
    assert any("starboardXTD" in e for e in validate_rtz(bad_xtd))
    no_pos = re.sub(rb"<position [^>]*/>", b"", good, count=1)
    assert validate_rtz(no_pos)
    assert any("routeName" in e for e in validate_rtz(good, file_name="other.rtz"))


# -- CSV -------------------------------------------------------------------------------------


def test_csv_schedule_rows_columns_and_units(azi_plan, tmp_path):
    path = export_plan(azi_plan, "csv", tmp_path / "t.csv", start=START)[0]
    rows = list(csv.DictReader(io.StringIO(path.read_text())))
    assert len(rows) == len(azi_plan.t)
    assert {
        "time_s",
        "lat",
        "lon",
        "heading_deg",
        "speed_mps",
        "speed_kn",
        "manoeuvre",
        "primitive",
        "n1_rpm",
        "alpha1_deg",
    } <= set(rows[0])
    assert not {"n1", "n2"} & set(rows[0])  # a bare n1 of 24.85 (rev/s) read as rpm beside the card's 1452 rpm
    k = 300
    r = rows[k]
    assert float(r["lat"]) == pytest.approx(azi_plan.lonlat[k, 1], abs=1e-7)
    assert float(r["lon"]) == pytest.approx(azi_plan.lonlat[k, 0], abs=1e-7)
    assert float(r["speed_kn"]) == pytest.approx(float(r["speed_mps"]) * KN_PER_MPS, abs=0.01)
    assert float(r["alpha1_deg"]) == pytest.approx(np.degrees(azi_plan.inputs[k, 1]), abs=0.01)
    # propellers in rpm, as the card's steps and the orders give them (the plan holds rev/s)
    assert float(r["n1_rpm"]) == pytest.approx(60.0 * azi_plan.inputs[k, 0], abs=0.05)
    assert float(r["n2_rpm"]) == pytest.approx(60.0 * azi_plan.inputs[k, 2], abs=0.05)
    headings = [float(x["heading_deg"]) for x in rows]
    assert min(headings) >= 0 and max(headings) < 360
    firsts = [x for x in rows if x["orders"]]
    assert [x["primitive"] for x in firsts] == [st.primitive for st in azi_plan.steps]
    assert rows[-1]["utc"] == "2026-06-01T08:13:10Z"


def test_sample_times_follow_a_plan_changed_in_place(azi_plan):
    """The CSV's and GPX's sample times, formatted once for both (``sample_times_iso``), are each sample's own
    after the plan's times are changed in place (the same plan and array objects): a memo keyed on the object
    would hand back the times before the change."""
    from datetime import UTC, datetime, timedelta

    from maps.export._common import iso, sample_times_iso
    from maps.export.csv import plan_csv

    plan = copy.deepcopy(azi_plan)
    t0 = datetime(2026, 6, 1, 8, tzinfo=UTC)

    def each(p: Plan) -> list[str]:
        return [iso(t0 + timedelta(seconds=float(p.t[k] - p.t[0]))) for k in range(len(p.t))]

    assert list(sample_times_iso(plan, t0)) == each(plan)
    plan.t[1:] += 0.25  # in place: 0.25 s later from the second sample on
    later = sample_times_iso(plan, t0)
    assert list(later) == each(plan) and later[1].endswith(".250Z")
    assert [r["utc"] for r in csv.DictReader(io.StringIO(plan_csv(plan, start=t0)))] == list(later)
    gpx = plan_gpx(plan, start=t0).decode()
    assert re.findall(r"<trkpt[^>]*>\s*<time>([^<]+)</time>", gpx) == list(later)


def test_text_exports_build_the_track_features_once(azi_plan, tmp_path, monkeypatch):
    """plan-trial's text exports build the GeoJSON track features once for trajectory.geojson and the crew's
    overlay (passed to both, not kept on the plan), and each file is what its export writes alone."""
    from datetime import UTC, datetime

    import maps.export.geojson as gj
    from cli.plan_outputs import write_outputs_all

    class Beside:  # the drawer's place: takes the job and draws nothing (the figures are not under test)
        def send(self, job):
            pass

        def wait(self, quiet=False):
            pass

        def cancel(self):
            pass

    plan, calls, real = copy.deepcopy(azi_plan), [], gj.segment_features
    monkeypatch.setattr(gj, "segment_features", lambda p: calls.append(1) or real(p))
    files = write_outputs_all(plan, None, tmp_path, None, datetime(2026, 6, 1, 8, tzinfo=UTC), False, True, drawer=Beside())
    assert len(calls) == 1
    assert json.loads(files["trajectory_geojson"].read_text()) == plan_geojson(plan, overlay=False)
    assert json.loads(files["geojson"].read_text()) == plan_geojson(plan)


# -- shared pieces and errors ----------------------------------------------------------------


def test_positions_in_degrees_and_minutes():
    assert latlon_dm(60.12, 24.95) == "60°07.200'N 024°57.000'E"
    assert latlon_dm(-33.5, -70.25) == "33°30.000'S 070°15.000'W"


def test_exports_survive_json_round_trip(azi_plan, tmp_path):
    p = tmp_path / "plan.json"
    p.write_text(azi_plan.to_json())
    loaded = Plan.load(p)
    assert plan_rtz(loaded, route_name="x", start=START) == plan_rtz(azi_plan, route_name="x", start=START)


def test_plan_without_steps_or_with_ragged_samples_is_a_user_error(azi_plan, tmp_path):
    empty = copy.deepcopy(azi_plan)
    empty.steps = []
    with pytest.raises(ExportError, match="steps"):
        export_plan(empty, "gpx", tmp_path / "x.gpx")
    ragged = copy.deepcopy(azi_plan)
    ragged.speed = ragged.speed[:-3]
    with pytest.raises(ExportError, match="samples.speed"):
        export_plan(ragged, "rtz", tmp_path / "x.rtz")
    with pytest.raises(ExportError, match="format"):
        export_plan(azi_plan, "kml", tmp_path / "x.kml")
    assert not list(tmp_path.iterdir())


def test_csv_every_n_formats_only_the_times_it_writes(azi_plan, monkeypatch):
    """``plan_csv(every=N)`` writes each kept row as the full schedule writes it (every manoeuvre's first sample
    and the last kept), and formats the UTC time of those rows only: it formatted every sample's before stop 60."""
    from datetime import UTC, datetime

    import maps.export._common as common
    from maps.export.csv import plan_csv

    t0 = datetime(2026, 6, 1, 8, tzinfo=UTC)
    full = plan_csv(azi_plan, start=t0).splitlines()
    formatted = []
    real_iso = common.iso
    monkeypatch.setattr(common, "iso", lambda t: formatted.append(t) or real_iso(t))
    common._sample_times_iso.cache_clear()  # a kept full list would hide the formatting
    lines = plan_csv(azi_plan, start=t0, every=7).splitlines()
    step = azi_plan.step_of_sample.tolist()
    n = len(step)
    kept = [k for k in range(n) if k % 7 == 0 or k == n - 1 or (k and step[k] != step[k - 1])]
    assert 3 < len(kept) < n / 3 and lines == [full[0]] + [full[1 + k] for k in kept]
    assert len(formatted) == len(kept)
