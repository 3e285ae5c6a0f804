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


def test_dask_inflation_is_never_below_the_local_pools():
    """The seventh stop's figures: Dask's housekeeping-corrected inflation measured 0.97 and 0.87 of
    inline's at 2 and 4 workers (clamped to 1.00) where the local pool's measured 1.07 and 1.06 for
    the same tasks: the prediction takes the pool's, then the workers' housekeeping share."""
    from benchmarks.scaling_model import dask_inflation

    pool = {1: 1.0, 2: 1.07, 4: 1.06, 16: 1.06}
    infl = dask_inflation(lambda w: 1.0, pool.__getitem__, 0.0165)
    assert infl(16) == pytest.approx(1.06 / (1 - 0.0165))
    assert infl(1) == pytest.approx(1 / (1 - 0.0165))
    assert dask_inflation(lambda w: 1.2, pool.__getitem__, 0.0)(4) == pytest.approx(1.2)
