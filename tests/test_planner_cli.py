"""``shiptrial plan`` / ``plan-trial``: outputs, JSON summary, exit codes and user errors."""

from __future__ import annotations

import json

import pytest
import shapely
from shapely.geometry import LineString, shape

from cli.app import _run
from maps.geo import bundled_map_path
from maps.plan import Plan

COUNTS = "steep_zigzag_surge=3,wide_zigzag_surge=3,wide_zigzag_sway=3"


def test_plan_writes_outputs_and_json(tmp_path, capsys):
    out = tmp_path / "out"
    rc = _run(["plan", "--counts", COUNTS, "--out", str(out), "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    for key in (
        "feasible",
        "optimal",
        "counts",
        "basic_moves",
        "duration_s",
        "length_m",
        "min_clearance_m",
        "expansions",
        "plan_time_s",
        "trajectory_geojson",
    ):
        assert key in summary
    assert summary["feasible"] and summary["counts"] == {"steep_zigzag_surge": 3, "wide_zigzag_surge": 3, "wide_zigzag_sway": 3}
    doc = json.loads((out / "trajectory.geojson").read_text())
    line = doc["features"][0]["geometry"]
    assert line["type"] == "LineString"
    assert all(len(repr(v).split(".")[-1]) <= 7 for pt in line["coordinates"] for v in pt)
    land = shapely.union_all([shape(f["geometry"]) for f in json.loads(bundled_map_path().read_text())["features"]])
    assert not LineString(line["coordinates"]).intersects(land)
    assert (out / "plan.png").stat().st_size > 10_000
    plan = Plan.load(out / "plan.json")
    assert plan.feasible and plan.counts == summary["counts"]


@pytest.mark.parametrize(
    "args, words",
    [
        (["--start", "60.16"], "LAT,LON"),
        (["--counts", "steep_zigzag_surge=three"], "NAME=N"),
        (["--start", "60.170,24.940,0"], "on land"),
        (["--start", "24.96,60.1625,180"], "swapped"),
        (["--goal", "59.0,24.96"], "outside the map"),
        (["--headings", "6"], "4, 8 or 16"),
        (["--counts", "no_such_primitive=2"], "unknown primitive"),
        (["--ship", "kvlcc2", "--counts", "no_such_primitive=2"], "unknown primitive(s) no_such_primitive for kvlcc2"),
        (["--heuristic", "greedy"], "admissible"),
    ],
)
def test_user_errors_exit_2(args, words, capsys):
    rc = _run(["plan", *args])
    err = capsys.readouterr().err
    assert rc == 2 and words in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_map_with_non_polygon_land_exit_2(tmp_path, capsys):
    p = tmp_path / "m.geojson"
    p.write_text(
        json.dumps(
            {
                "type": "FeatureCollection",
                "features": [
                    {
                        "type": "Feature",
                        "properties": {"kind": "land"},
                        "geometry": {"type": "Point", "coordinates": [25.0, 60.0]},
                    }
                ],
            }
        )
    )
    rc = _run(["plan", "--map", str(p), "--counts", "steep_zigzag_surge=1"])
    assert rc == 2 and "must be a Polygon" in capsys.readouterr().err


def test_no_feasible_plan_exit_1_with_reason(tmp_path, capsys):
    p = tmp_path / "small.geojson"
    p.write_text(
        json.dumps(
            {
                "type": "FeatureCollection",
                "features": [
                    {
                        "type": "Feature",
                        "properties": {"kind": "trial_area"},
                        "geometry": {
                            "type": "Polygon",
                            "coordinates": [[[25.0, 60.0], [25.014, 60.0], [25.014, 60.006], [25.0, 60.006], [25.0, 60.0]]],
                        },
                    },
                    {
                        "type": "Feature",
                        "properties": {"kind": "start", "heading_deg": 90},
                        "geometry": {"type": "Point", "coordinates": [25.002, 60.001]},
                    },
                    {
                        "type": "Feature",
                        "properties": {"kind": "goal"},
                        "geometry": {"type": "Point", "coordinates": [25.012, 60.005]},
                    },
                ],
            }
        )
    )
    rc = _run(["plan", "--map", str(p), "--counts", "wide_zigzag_sway=1", "--json", "--out", str(tmp_path / "o")])
    cap = capsys.readouterr()
    assert rc == 1
    assert Plan.load(tmp_path / "o" / "plan.json").feasible is False
    summary = json.loads(cap.out)
    assert summary["feasible"] is False and "fits nowhere" in summary["reason"]
    assert "would help" in cap.err
