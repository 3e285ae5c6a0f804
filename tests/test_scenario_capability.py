"""The section 9.4 scenario says which ships it can be built for (maps.scenario.scenario_supports):
--counts resolution asks it instead of catching the scenario's ProfileError for rudder ships, and
the scenario still refuses those ships with the same one-line message."""

from __future__ import annotations

import pytest

from maps.motionset import resolve_primitives
from maps.scenario import scenario_supports, thesis_planning_scenario
from primitives.ship import ProfileError, load_profile

SUPPORTED = {"model-ship": True, "full-scale": True, "kvlcc2": False, "kvlcc2-linear": False, "naval-vessel": False}


@pytest.mark.parametrize("name", sorted(SUPPORTED))
def test_the_scenario_says_which_ships_it_supports(name):
    prof = load_profile(name)
    assert scenario_supports(prof) is SUPPORTED[name]
    if not SUPPORTED[name]:
        with pytest.raises(ProfileError) as err:
            thesis_planning_scenario(prof)
        if prof.planar:  # the message of before: the scenario's zig-zags hold steady generalized forces
            assert str(err.value) == (
                f"profile {name!r}: steady generalized forces need generalized-force or azimuth inputs, not rudder/propeller"
            )
        else:
            assert "is a 4-DOF pods profile; steady_forces supports 3-DOF ships only" in str(err.value)


def test_counts_resolve_from_the_scenario_only_where_it_applies():
    full = load_profile("full-scale")
    assert [p.name for p in resolve_primitives(full, {"steep_zigzag_surge": 1})] == ["steep_zigzag_surge"]
    kv = load_profile("kvlcc2")
    assert [p.name for p in resolve_primitives(kv, {"turning_circle_35_s": 1})] == ["turning_circle_35_s"]
    from maps.geo import MapError

    with pytest.raises(MapError, match=r"--counts: unknown primitive\(s\) steep_zigzag_surge for kvlcc2; known: ") as err:
        resolve_primitives(kv, {"steep_zigzag_surge": 1})
    assert "turning_circle_35_s" in str(err.value)
