"""The exceedance level of a recording among its no-change records (identify/detect/glr.py:
``null_peaks``, ``exceedance_level``): uniform for records the null describes, low for records that
spread more, and below the design rate exactly for the records ``calibrate``'s thresholds alarm on."""

from __future__ import annotations

import numpy as np
import pytest

from identify.detect.glr import calibrate, exceedance_level, null_peaks


def _peaks(rng, m, scale=1.0):
    """Correlated positive peak statistics (m, 3), as CUSUM maxima of three candidates are."""
    z = rng.standard_normal((m, 3)) @ np.array([[1.0, 0.5, 0.3], [0.0, 1.0, 0.4], [0.0, 0.0, 1.0]])
    return np.exp(0.4 * scale * z) * np.array([8.0, 6.0, 5.0])


def test_levels_of_recordings_the_null_describes_are_uniform():
    rng = np.random.default_rng(3)
    lv = exceedance_level(_peaks(rng, 400), _peaks(rng, 4000))
    for a in (0.02, 0.05, 0.10, 0.25, 0.50):
        # binomial sd of a fraction of 4000, plus the null's own 400-record granularity
        assert abs(np.mean(lv < a) - a) < 4 * np.sqrt(a * (1 - a) / 4000) + 2 / 400, a


def test_levels_of_recordings_that_spread_more_than_the_null_are_low():
    rng = np.random.default_rng(4)
    lv = exceedance_level(_peaks(rng, 400), _peaks(rng, 2000, scale=1.3))
    assert np.mean(lv < 0.05) > 0.10  # a 30 % wider spread: more than twice the design's share
    assert exceedance_level(_peaks(rng, 400), np.array([1e9, 0.0, 0.0])) == 0.0  # beyond every record


@pytest.fixture(scope="module")
def screened(detect_screening):
    prior, _, sc = detect_screening
    return prior, sc


def test_the_records_calibrate_alarms_on_are_those_with_a_level_below_the_design_rate(screened):
    prior, sc = screened
    theta1 = np.array([0.09, 0.05, 0.05])
    det = calibrate(prior, sc.S, sc.null_blocks, theta1=theta1, false_alarm=0.05, seed=0)
    peaks = null_peaks(det, sc.S, sc.null_blocks, seed=0)
    alarms = (peaks > det.h).any(axis=1)
    lv = exceedance_level(peaks, peaks)
    assert 0 < alarms.sum() <= 0.05 * len(peaks)
    # the alarming records are the lowest levels (ties in the combined score aside)
    assert lv[alarms].max() <= np.sort(lv)[alarms.sum() - 1] + 1e-12
    assert lv[~alarms].min() >= lv[alarms].max()
    # null_peaks is what calibrate takes its quantiles of: its thresholds are one common quantile of these peaks
    below = [np.mean(peaks[:, k] <= det.h[k]) for k in range(3)]
    assert max(below) - min(below) <= 1.0 / len(peaks) and min(below) >= 0.95


def test_a_recordings_level_is_the_smallest_design_rate_at_which_calibrate_alarms_on_it(screened):
    """The level is the probability integral transform of the CUSUM stage's decision: at calibrate's
    thresholds for ``false_alarm = a`` a recording's peaks cross some threshold exactly when its level
    is at most ``a`` (recordings between two null records' peaks included)."""
    prior, sc = screened
    theta1 = np.array([0.09, 0.05, 0.05])
    det = calibrate(prior, sc.S, sc.null_blocks, theta1=theta1, false_alarm=0.05, seed=0)
    peaks = null_peaks(det, sc.S, sc.null_blocks, seed=0)
    srt = np.sort(peaks, axis=0)
    rng = np.random.default_rng(5)
    # peaks between two of the top 30 null records' on a random candidate, the others low
    stats = []
    for i in rng.choice(np.arange(len(peaks) - 30, len(peaks) - 1), 6, replace=False):
        k = rng.integers(3)
        x = srt[len(peaks) // 2].copy()
        x[k] = srt[i, k] + rng.uniform(0.05, 0.95) * (srt[i + 1, k] - srt[i, k])
        stats.append(x)
    for x in stats:
        lv = float(exceedance_level(peaks, x))
        assert 0 < lv < 0.5
        for a, alarm in ((lv - 1e-9, False), (lv + 1e-9, True)):
            h = calibrate(prior, sc.S, sc.null_blocks, theta1=theta1, false_alarm=a, seed=0).h
            assert bool((x > h).any()) is alarm, (lv, a)
