"""The start heading's rounding to the lattice is warned only when a master would see it."""

from __future__ import annotations

import math

from maps.headings import heading_table


def test_a_start_heading_the_lattice_meets_within_a_tenth_of_a_degree_is_not_warned():
    """docs/commands/plan-trial.md's resume example passes --from ...,116.6 and the plan warned
    'start heading 116.6 deg rounded to the lattice heading 116.6 deg' (the lattice's 116.565 deg);
    120 deg is still warned, with the difference. build_lattice's own warnings (0.1 s)."""
    from maps.chain import PlanOptions, build_lattice
    from maps.geo import load_map
    from maps.motionset import resolve_primitives
    from maps.scenario import HELSINKI_START
    from primitives.ship import load_profile

    prof = load_profile("full-scale")
    sea = load_map(None, draught_m=prof.draught_m)
    counts = {"steep_zigzag_surge": 1}
    prims = resolve_primitives(prof, counts, None)
    cache: dict = {}

    def heading_warnings(hdg: float) -> list[str]:
        start = (HELSINKI_START[0], HELSINKI_START[1], hdg)
        lat = build_lattice(sea, prof, prims, counts, start=start, options=PlanOptions(), cache=cache)
        return [w for w in lat.warnings if "start heading" in w]

    assert heading_warnings(116.6) == []
    assert heading_warnings(120.0) == ["start heading 120.0 deg rounded to the lattice heading 116.6 deg (3.4 deg)"]


def test_heading_rounding_is_measured_across_north():
    """359.99 deg against the lattice's 0 deg is 0.01 deg apart, not 359.99."""
    from maps.headings import heading_rounding_warning

    table = heading_table(16)
    near = min(table, key=lambda h: abs(math.degrees(h) - 116.6))
    assert abs(math.degrees(near) - 116.565) < 1e-3  # the lattice heading the resume example met
    assert heading_rounding_warning(math.radians(359.99), float(table[0])) is None
    assert heading_rounding_warning(math.radians(0.2), float(table[0])) is not None
