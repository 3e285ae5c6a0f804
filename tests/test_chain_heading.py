"""The start heading's rounding to the lattice is warned only when a master would see it."""

from __future__ import annotations

import math

from maps.headings import heading_rounding_warning, heading_table


def test_heading_rounding_below_a_tenth_of_a_degree_is_not_warned():
    """docs/commands/plan-trial.md's resume example passes --from ...,116.6 and warned 'start
    heading 116.6 deg rounded to the lattice heading 116.6 deg' (the lattice's 116.565 deg)."""
    table = heading_table(16)
    near = min(table, key=lambda h: abs(math.degrees(h) - 116.6))
    assert abs(math.degrees(near) - 116.565) < 1e-3  # the lattice heading the example met
    assert heading_rounding_warning(math.radians(116.6), float(near)) is None
    far = heading_rounding_warning(math.radians(120.0), float(near))
    assert far is not None and "120.0 deg rounded to the lattice heading 116.6 deg (3.4 deg)" in far
    assert heading_rounding_warning(math.radians(359.99), float(table[0])) is None  # across north
