"""The Monte Carlo benchmark's task-cost line (benchmarks/scaling_model.robust_line): one task time
spoilt by a loaded machine moves neither the fixed cost nor the cost per run much, and the fixed
cost is never negative (the least-squares line fitted under load gave negative fixed costs, which
left the 16-worker prediction without meaning)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.scaling_model import robust_line

SIZES = (16, 63, 250, 500)


def test_recovers_a_clean_line():
    f, p = robust_line(SIZES, [0.2 + 0.003 * n for n in SIZES])
    assert f == pytest.approx(0.2) and p == pytest.approx(0.003)


@pytest.mark.parametrize("spoilt", range(4))
def test_one_loaded_point_changes_little(spoilt):
    cost = [0.05 + 0.003 * n for n in SIZES]
    cost[spoilt] *= 1.6  # that task ran beside a heavy process
    f, p = robust_line(SIZES, cost)
    assert p == pytest.approx(0.003, rel=0.1) and 0.0 <= f <= 0.15


def test_fixed_cost_is_never_negative():
    # the 16-run task measured quicker than the line through the others: least squares goes negative
    cost = [0.01, 0.2, 0.8, 1.6]
    assert np.polyfit(SIZES, cost, 1)[1] < 0
    f, p = robust_line(SIZES, cost)
    assert f == 0.0 and p == pytest.approx(0.0032, rel=0.05)
