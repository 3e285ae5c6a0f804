"""The 95 % interval of a finding at its parts' degrees of freedom (issue 26)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from diagnose.uncertainty import half_width_95, small_sample


def test_95_interval_of_noise_alone_is_normal():
    assert half_width_95(2.0) == pytest.approx(1.96 * 2.0, rel=1e-3)


def test_95_interval_of_a_misfit_over_three_runs_is_student_t():
    """A run-to-run part alone (its std widened by small_sample(3) for a one-std interval): 95 %
    half-width t(2, 0.975) = 4.30 of its measured std, not 1.96 x the widened std (2.59)."""
    raw = 1.0
    sd = raw * np.sqrt(small_sample(3))
    assert half_width_95(0.0, sd, n_runs=3) == pytest.approx(stats.t.ppf(0.975, 2) * raw, rel=1e-6)
    assert half_width_95(0.0, sd, n_runs=3) > 1.6 * 1.96 * sd


def test_95_interval_between_the_normal_and_the_parts_own():
    """Noise and a misfit part together: wider than 1.96 total stds, narrower than the t of the
    misfit's own degrees of freedom over the total; one draw of the --fit-on misfit alone: t(1)."""
    total = np.sqrt(1.0 + small_sample(3))
    h = half_width_95(1.0, np.sqrt(small_sample(3)), n_runs=3)
    assert 1.96 * np.sqrt(2.0) < h < stats.t.ppf(0.975, 2) * np.sqrt(2.0) and h < 1.96 * total * 2
    assert half_width_95(0.0, reference=1.0) == pytest.approx(stats.t.ppf(0.975, 1), rel=1e-6)


def test_95_interval_never_narrower_than_the_printed_std_allows():
    """Noise and a small within-run part over 24 blocks (its widening for a one-std interval, x1.04,
    taken out for the t quantile: 2.187): the half-width stays at 1.96 of the std printed beside it."""
    assert half_width_95(1.0, 0.0, 0.5, n_runs=3) == pytest.approx(1.96 * np.sqrt(1.25), rel=1e-4)


def test_95_interval_of_the_held_out_runs_part_has_a_degree_of_freedom_a_run():
    """Two held-out runs' misfit alone: t(2) of its std; one run: t(1). With a run-to-run part the
    held-out part tops up, the model error as a whole takes the held-out runs' degrees of freedom:
    the interval never narrows by the top-up (as a fifth independent part it did: measured on the
    MMG battery's delay-2.5, median half-width 42.6 -> 41.3 % of the delay)."""
    assert half_width_95(0.0, heldout=1.0, n_heldout=2) == pytest.approx(stats.t.ppf(0.975, 2), rel=1e-6)
    assert half_width_95(0.0, heldout=1.0, n_heldout=1) == pytest.approx(stats.t.ppf(0.975, 1), rel=1e-6)
    m = np.sqrt(small_sample(3))
    for top_up in (0.1, 0.5, 1.0, 3.0):
        assert half_width_95(0.3, m, heldout=top_up, n_runs=3, n_heldout=2) > half_width_95(0.3, m, n_runs=3)
    both = half_width_95(0.0, m, heldout=m, n_runs=3, n_heldout=2)
    assert both == pytest.approx(stats.t.ppf(0.975, 2) * np.sqrt(2 * small_sample(3)), rel=1e-6)


def test_an_interval_with_the_held_out_part_says_so():
    from diagnose.describe import interval_note
    from diagnose.uncertainty import FindingCov

    c = FindingCov(np.eye(2), np.zeros((2, 2)), 3, fit_on=True, runs_given=3)
    c.reference, c.reference_keys = np.zeros((2, 2)), frozenset({"delay"})
    c.heldout, c.heldout_runs = np.eye(2), 2
    covers = interval_note(c, "delay")["covers"]
    assert "the misfit the 2 held-out (--validate) runs show on it" in covers
    assert "that the --fit-on runs and the held-out runs do not show" in covers
    assert np.allclose(c.total, 2 * np.eye(2))
