"""The size of effect the search's acceptance test calls significant, and the --fit-on check's
yardstick built on it (issue 26: three calm runs left the baseline uncertain by 0.53-0.88 noise
units on the 20/20 zig-zags, under the former fixed 1, and the control named quadratic damping)."""

from __future__ import annotations

import numpy as np
import pytest

from diagnose import baseline, plausible
from diagnose.significance import (
    ALPHA_INDEPENDENT,
    ALPHA_STRONG,
    independent_heldout,
    inflation,
    loosest_alpha,
    lr_stats,
    smallest_significant_rms,
)


@pytest.mark.parametrize("n_rows,alpha", [(600, ALPHA_INDEPENDENT), (300, 1e-4)])
def test_a_misfit_of_the_smallest_significant_size_sits_at_the_tests_level(n_rows, alpha):
    """Turned round, the F test gives back its own level: a misfit of that RMS on one run, taken up
    whole by one parameter beside white residuals (their colour as the search measures it), has p = alpha in :func:`lr_stats`."""
    rng = np.random.default_rng(3)
    res1 = rng.standard_normal(3 * 1800)  # three runs of 600 samples, three channels, white
    rss1, M = float(res1 @ res1), res1.size
    e = smallest_significant_rms(n_rows, M, rss1 / (M - 1), inflation(res1), alpha)
    _f, p = lr_stats(res1, rss1 + n_rows * e**2, rss1, 1, M)
    assert p == pytest.approx(alpha, rel=0.05)


def test_the_search_relaxes_its_level_only_with_two_whole_held_out_runs():
    assert independent_heldout(2, 1) and independent_heldout(0, 2)
    assert not independent_heldout(1, 3) and not independent_heldout(0, 1)
    assert loosest_alpha(25, True) == ALPHA_INDEPENDENT and loosest_alpha(25, False) == ALPHA_STRONG / 25


def test_the_pinning_limit_is_the_significant_size_between_the_visible_floor_and_the_noise():
    """Long white runs: any misfit above a fifth of the noise is significant, so the floor
    (plausible.MIN_VISIBLE) is the limit; short coloured runs need more to be significant; never
    more than the noise (baseline.PINNED_SD, the former rule)."""
    assert baseline.pinned_limit(650, 6000, 1.0, 1.0, 0.05) == plausible.MIN_VISIBLE
    mid = baseline.pinned_limit(40, 6000, 1.0, 3.0, 0.05)
    assert mid == pytest.approx(smallest_significant_rms(40, 6000, 1.0, 3.0, 0.05)) and plausible.MIN_VISIBLE < mid < 1
    assert baseline.pinned_limit(40, 6000, 1.0, 30.0, 1e-8) == baseline.PINNED_SD
