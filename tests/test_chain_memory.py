"""The lattice memory estimate stays exact for the counts of a very long trial (no int64 wrap-around
to a negative state count) and the library refuses such a lattice in one line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from maps.chain import estimate_memory
from maps.geo import MapError, load_map
from maps.planner import plan_with_design
from primitives.ship import load_profile


def test_estimate_is_exact_for_numpy_sizes_and_huge_counts():
    targets = [np.int64(10**10)] * 6  # (10**10 + 1)**6 is far past int64
    need, states = estimate_memory(np.int64(41), np.int64(44), 16, 12, targets)
    assert states == 41 * 44 * 16 * (10**10 + 1) ** 6
    edges, D = 41 * 44 * 16 * 12, 6 * 10**10
    assert need == pytest.approx(edges * 120 + edges * (D + 1) * 40 + 41 * 44 * 16 * (D + 1) * 24)
    assert estimate_memory(41, 44, 16, 12, [10**400])[0] == math.inf  # past the float range: no OverflowError


def test_very_long_trial_is_refused_with_its_memory_in_one_line():
    sea = load_map(None, draught_m=load_profile("full-scale").draught_m)
    with pytest.raises(MapError) as exc:
        plan_with_design(sea, profile="full-scale", trial_length_s=1e12)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("the lattice would not fit")
    assert "-" not in msg.split("=")[1].split("states")[0]  # a positive state count
    assert "e+" in msg and "GiB (limit 2 GiB)" in msg and "--trial-length" in msg
