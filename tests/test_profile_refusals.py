"""Profiles the planner cannot sail refused in one line naming the field and the fix (issue 29):
an unstable parameter set, a sample time in which the ship sails lengths, a zig-zag the ship never
completes, and values far outside their key's unit (radians in a degrees key and the reverse)."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from shapely.geometry import box

from cli.app import _run
from primitives.errors import UserError
from primitives.ship import PROFILE_DIR, load_profile

DATA = Path(__file__).parent / "data"


def _variant(tmp_path: Path, base: str, name: str, edit) -> Path:
    doc = tomllib.loads((PROFILE_DIR / f"{base}.toml").read_text())
    doc["name"] = name
    edit(doc)
    p = tmp_path / f"{name}.json"
    p.write_text(json.dumps(doc))
    return p


def _flip_yaw_damping(doc):
    for s in doc["parameters"].values():
        s["yaw"][0] = 0.3


@pytest.mark.parametrize("base", ["model-ship", "full-scale"])
def test_primitives_on_an_unstable_profile_exits_2_naming_the_parameter(tmp_path, capsys, base):
    """It exited 0 (model ship: a table of diverging moves) or with a GEOS traceback (full scale)."""
    p = _variant(tmp_path, base, f"unstable-{base}", _flip_yaw_damping)
    assert _run(["primitives", "--ship", str(p)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error:"), err
    assert "[parameters.true]" in err and "Nr = +0.3" in err and "damping must be negative" in err, err


def test_course_unstable_kvlcc2_still_builds_its_library():
    """KVLCC2 is course-unstable (doubling in several ship lengths): that is a real ship, not a fault."""
    from primitives.library import thesis_primitives

    assert thesis_primitives(load_profile("kvlcc2"))


def test_huge_sample_time_refused_at_load_naming_the_field(tmp_path):
    """sample_time = 50 s for the 1 m model ship ended in 'footprint larger than the collision grid padding'."""
    p = _variant(tmp_path, "model-ship", "big-ts", lambda d: d.update(sample_time=50.0))
    with pytest.raises(
        UserError, match=r"field 'sample_time' = 50 s: .* 50 ship lengths per sample.*give sample_time in seconds"
    ):
        load_profile(str(p))


def test_collision_grid_padding_reaches_a_turned_footprint():
    """The padding took the footprint's bounds; turned 45 deg a square reaches sqrt(2) further."""
    from maps.chain import PlanOptions, _collision_grid
    from maps.collision import Window
    from maps.geo import load_map

    sea = load_map(DATA / "open-sea.geojson", draught_m=2.0)
    o = PlanOptions()
    fp = box(0.0, 0.0, 2000.0, 2000.0)
    move = SimpleNamespace(prims=[SimpleNamespace(footprint=fp)], snap_m=np.zeros(16))
    grid = _collision_grid(sea, Window(0.0, 0.0, 100.0, 5, 5), [move], SimpleNamespace(length_m=30.0), o)
    for psi in np.radians([0.0, 45.0, 135.0, 225.0, 315.0]):
        grid.valid_everywhere(grid.footprint_rows(fp, float(psi), o.margin + o.clearance_lengths * 30.0))


def test_scenario_zigzag_the_ship_never_completes_is_a_profile_error(tmp_path):
    """A ship too sluggish in yaw for the section 9.4 zig-zags raised a bare ValueError."""
    from maps.scenario import thesis_planning_scenario

    def weak_yaw(doc):
        for s in doc["parameters"].values():
            s["yaw"][5] *= 1e-3

    prof = load_profile(str(_variant(tmp_path, "full-scale", "sluggish", weak_yaw)))
    with pytest.raises(UserError, match=r"'sluggish': the scenario's zig-zag steep_zigzag_surge did not complete 2 period"):
        thesis_planning_scenario(prof)


@pytest.mark.parametrize(
    "old,new,expect",
    [
        (
            "max_rudder_deg = 35.0",
            "max_rudder_deg = 0.6109",
            r"'helm.max_rudder_deg' = 0.6109 is in degrees.*write max_rudder_deg = 35.0",
        ),
        (
            "delta = [-0.6109, 0.6109]",
            "delta = [-35, 35]",
            r"'input_limits.delta' = \[-35, 35\] is in radians.*write delta = \[-0.6109, 0.6109\]",
        ),
        (
            "rudder_rate_deg_s = 2.32",
            "rudder_rate_deg_s = 0.0405",
            r"'helm.rudder_rate_deg_s' = 0.0405 is in deg/s.*write rudder_rate_deg_s = 2.32",
        ),
        ("approach_rpm = 91.4", "approach_rpm = 1.52", r"'engine.approach_rpm' = 1.52 is in rpm.*write approach_rpm = 91.2"),
    ],
)
def test_a_value_in_the_other_unit_is_refused_with_the_likely_fix(tmp_path, old, new, expect):
    """max_rudder_deg = 0.6109 gave 1,619 s turns; delta = [-35, 35] rad was accepted."""
    text = (PROFILE_DIR / "kvlcc2.toml").read_text()
    assert old in text
    p = tmp_path / "k.toml"
    p.write_text(text.replace(old, new))
    with pytest.raises(UserError, match=expect):
        load_profile(str(p))


def test_azimuth_angles_in_degrees_are_refused(tmp_path):
    def degrees(doc):
        doc["input_limits"]["alpha1"] = [-180.0, 180.0]

    with pytest.raises(UserError, match=r"'input_limits.alpha1' = \[-180, 180\] is in radians.*alpha1 = \[-3.1416, 3.1416\]"):
        load_profile(str(_variant(tmp_path, "full-scale", "deg-azimuth", degrees)))
