"""Transits: no longer than 1.3 x the shortest path through water + one full turn (2 pi x 1.5 L)
+ two ship lengths (issue 28), checked against an independent shortest path (tests/water_path.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely

from maps.geo import bundled_map_path, load_map
from maps.planner import plan_with_design
from maps.smooth import Shortcutter
from maps.testmaps import _feature, open_sea
from tests.water_path import shortest_water_path, transit_lengths


def test_a_reversal_shortcut_arrives_on_the_final_course(kvlcc2):
    """A course reversal a lattice round turn would sail: the shortcut keeps its approach point, so
    it arrives on the last lattice pose along its course (string pulling past it arrived on the
    bearing of the last leg, and the shortcut was refused)."""
    sea = load_map(bundled_map_path("open-sea"), draught_m=kvlcc2.draught_m)  # 60 x 60 km, origin mid-map
    res = 1275.0
    cut = Shortcutter(sea, kvlcc2, res, 16, 20.0)
    start, end = np.array([0.0, 0.0, np.pi / 4]), np.array([-2000.0, 4000.0, np.pi / 4 + np.pi])
    leg = cut.legs(np.array([start, end]), np.array([kvlcc2.cruise_speed_mps, 0.0, 0.0]), start.copy())
    assert leg is not None
    tr = leg.sim[1]
    assert np.hypot(*(tr[-1, :2] - end[:2])) <= 0.25 * res
    assert abs(np.angle(np.exp(1j * (tr[-1, 2] - end[2])))) <= np.radians(5)


def test_every_transit_within_the_bound_of_the_shortest_path_through_water(tmp_path, kvlcc2):
    doc = open_sea(size_m=30000.0)
    doc["features"].append(_feature("land", shapely.box(9000, 4000, 12000, 7000), 57.0, 11.0))  # an island
    path = tmp_path / "island.geojson"
    path.write_text(json.dumps(doc))
    sea = load_map(path, draught_m=kvlcc2.draught_m)
    plan, _ = plan_with_design(sea, profile=kvlcc2, counts={"zz_exc_25_5_100": 2, "stopping": 1, "turning_circle_35_p": 1})
    assert plan.feasible
    rows = transit_lengths(plan, sea, kvlcc2.length_m)
    assert rows, "the plan has transits to check"
    for step, sailed, shortest, bound in rows:
        assert shortest > 0 and sailed <= bound, f"transit step {step}: {sailed:.0f} m sailed, bound {bound:.0f} m"


def test_the_independent_shortest_path_goes_round_an_island():
    """Round a 2 x 2 km island: to its corners, along its side, and on: 2000 + 2 x sqrt(2) x 1000 m."""
    island = shapely.box(-1000, -1000, 1000, 1000)
    d = shortest_water_path(island, (-5000, -5000, 5000, 5000), (-2000, 0), (2000, 0))
    assert d == pytest.approx(2000 + 2 * np.sqrt(2) * 1000, rel=1e-6)
