"""The README's main job: plan-trial on the bundled Helsinki example, design to crew exports."""

from __future__ import annotations

import json

import gpxpy
import pytest

from cli.app import _run
from maps.export.geojson import validate_geojson
from maps.export.rtz import validate_rtz
from maps.plan import Plan


@pytest.fixture(scope="module")
def trial(tmp_path_factory):
    out = tmp_path_factory.mktemp("trial")
    rc = _run(["plan", "--out", str(out), "--json", "--start-time", "2026-06-01T08:00Z"])
    return rc, out


def test_main_job_writes_every_export(trial, capsys):
    rc, out = trial
    assert rc == 0
    names = {p.name for p in out.iterdir()}
    for f in (
        "plan.json",
        "trajectory.geojson",
        "plan.png",
        "design-ratios.png",
        "full-scale-trial.geojson",
        "full-scale-trial.gpx",
        "full-scale-trial.rtz",
        "full-scale-trial.csv",
        "full-scale-trial.html",
        "full-scale-trial.pdf",
        "full-scale-trial-track.png",
        "full-scale-trial-states.png",
    ):
        assert f in names, f
    plan = Plan.load(out / "plan.json")
    assert plan.feasible and plan.counts == plan.targets and sum(plan.counts.values()) > 0
    assert validate_geojson(json.loads((out / "full-scale-trial.geojson").read_text())) == []
    assert validate_rtz(out / "full-scale-trial.rtz", file_name="full-scale-trial.rtz") == []
    gpx = gpxpy.parse((out / "full-scale-trial.gpx").read_text())
    # one source of waypoints: the GPX route is the RTZ route, via points (bends round land) included
    from lxml import etree

    from maps.export.rtz import RTZ_NS

    rtz_names = [
        w.get("name")
        for w in etree.parse(str(out / "full-scale-trial.rtz")).findall(f"{{{RTZ_NS}}}waypoints/{{{RTZ_NS}}}waypoint")
    ]
    assert [p.name for p in gpx.routes[0].points] == rtz_names and len(rtz_names) >= len(plan.steps) + 1
    csv_lines = (out / "full-scale-trial.csv").read_text().splitlines()
    assert len(csv_lines) > len(plan.t) // 2


def test_same_seed_same_plan(trial, tmp_path):
    rc, out = trial
    rc2 = _run(["plan", "--out", str(tmp_path), "--no-export", "--json", "--start-time", "2026-06-01T08:00Z"])
    assert rc == rc2 == 0
    a = json.loads((out / "plan.json").read_text())
    b = json.loads((tmp_path / "plan.json").read_text())
    sa, sb = a.pop("stats"), b.pop("stats")  # the stats hold wall-clock timings of the search
    assert a == b
    for k in ("expansions", "states_visited", "basic_moves", "cost"):
        assert sa[k] == sb[k]
