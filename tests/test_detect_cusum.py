"""The CUSUM recursion's numpy forms (identify.detect.cusum.cusum_path, stop 51: Lindley's closed form by
blocks for a few columns, stepped for many) against the plain recursion g_t = max(0, g_{t-1} + inc_t) on random
increments."""

from __future__ import annotations

import numpy as np
import pytest

from identify.detect import cusum
from primitives import jitloop


def _plain(inc: np.ndarray) -> np.ndarray:
    """The recursion sample by sample, each column on Python floats: the reference."""
    flat = inc.reshape(inc.shape[0], -1)
    out = np.empty(flat.shape)
    for j in range(flat.shape[1]):
        g = 0.0
        for i, x in enumerate(flat[:, j].tolist()):
            g = max(0.0, g + x) if x == x and g == g else float("nan")
            out[i, j] = g
    return out.reshape(inc.shape)


@pytest.mark.parametrize("shape", [(1,), (700,), (1300, 9), (600, 5, 3), (256, 4), (257, 2), (300, 70), (200, 30, 3)])
@pytest.mark.parametrize("drift", [-0.3, 0.0, 0.05])
def test_the_numpy_cusum_agrees_with_the_plain_recursion(shape, drift, monkeypatch) -> None:
    monkeypatch.setattr(jitloop, "AVAILABLE", False)  # the numpy form whatever is installed
    rng = np.random.default_rng(len(shape) * 7 + shape[0])
    inc = rng.standard_normal(shape) + drift
    got, ref = cusum.cusum_path(inc), _plain(inc)
    assert got.shape == ref.shape and (got >= 0).all()
    assert np.abs(got - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max())
    assert ((got == 0) == (ref == 0)).mean() > 0.999  # the resets fall on the same samples (to rounding at a tie)


def test_the_numpy_cusum_carries_a_nan_on_and_tracks_large_sums(monkeypatch) -> None:
    """A NaN stays NaN from its sample on in its column only (a diverged record must not look quiet); a
    statistic that climbs for 5,000 samples keeps its relative accuracy (the sums are per block)."""
    monkeypatch.setattr(jitloop, "AVAILABLE", False)
    rng = np.random.default_rng(2)
    inc = rng.standard_normal((5000, 6)) - 0.2
    inc[:, 5] += 1.0  # climbs to about 4,000
    inc[1234, 2] = np.nan
    got, ref = cusum.cusum_path(inc), _plain(inc)
    assert np.isnan(got[1234:, 2]).all() and not np.isnan(got[:1234, 2]).any()
    assert not np.isnan(np.delete(got, 2, axis=1)).any()
    ok = ~np.isnan(ref)
    assert np.abs(got[ok] - ref[ok]).max() <= 1e-12 * np.abs(ref[ok]).max()
    assert got[-1, 5] > 3000


def test_the_numpy_cusum_of_an_empty_record_is_empty(monkeypatch) -> None:
    monkeypatch.setattr(jitloop, "AVAILABLE", False)
    assert cusum.cusum_path(np.zeros((0, 4))).shape == (0, 4)


def test_a_minus_infinite_increment_resets_the_statistic_as_the_recursion_does(monkeypatch) -> None:
    """max(0, g - inf) = 0: the closed form's S_t - min S_s would be NaN from there on (review of stop 51)."""
    monkeypatch.setattr(jitloop, "AVAILABLE", False)
    inc = np.random.default_rng(3).standard_normal((300, 2)) + 0.1
    inc[10, 0] = -np.inf
    got, ref = cusum.cusum_path(inc), _plain(inc)
    assert not np.isnan(got).any() and got[10, 0] == 0.0
    assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max()


def test_the_dead_zone_peaks_of_many_records_are_the_statistics_largest_values(monkeypatch) -> None:
    """DeadZoneCusum.peaks (the no-change records' calibration: stepped, only the peak kept; stop 60) equals
    statistic().max(axis=0) to the bit on 100 records of a length that is no multiple of the block, in either
    memory order, with a NaN, an infinite and an all-zero record, and calibrate_dead_zone sets the threshold from
    those peaks."""
    from identify.detect.cusum import BLOCK, CLOSED_MAX, DeadZoneCusum, calibrate_dead_zone
    from primitives.orderstats import quantile

    monkeypatch.setattr(jitloop, "AVAILABLE", False)  # the numpy form whatever is installed
    spy = []
    monkeypatch.setattr(DeadZoneCusum, "statistic", lambda self, e, f=DeadZoneCusum.statistic: spy.append(1) or f(self, e))
    rng = np.random.default_rng(3)
    eps = 0.01 * rng.standard_normal((3 * BLOCK + 17, CLOSED_MAX + 36))
    eps[40, 2], eps[41, 3], eps[:, 4] = np.nan, np.inf, 0.0
    det = DeadZoneCusum(0.015, 0.002, np.inf)
    for x in (eps, np.asfortranarray(eps)):
        got = det.peaks(x)
        assert not spy  # stepped here, not through the whole statistic
        ref = det.statistic(x).max(axis=0)
        spy.clear()
        assert np.isinf(got[3]) and got[4] == 0.0  # (a NaN residual is below the dead zone for (5.1)'s where)
        assert got.tobytes() == ref.tobytes()
    finite = eps[:, 5:]
    dz = calibrate_dead_zone(0.0075, finite)
    assert dz.h == float(quantile(DeadZoneCusum(dz.d, dz.l, np.inf).statistic(finite).max(axis=0), 0.98))
