"""primitives.savgol and primitives.spectrum (the detector's smoothing, derivative and roll spectrum
without scipy.signal) against scipy.signal on random inputs."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from primitives.savgol import savgol_filter
from primitives.spectrum import welch


@pytest.mark.parametrize(
    "window, polyorder, deriv, delta", [(21, 2, 0, 1.0), (21, 2, 1, 0.1), (5, 2, 1, 0.5), (11, 3, 2, 0.2), (3, 0, 0, 1.0)]
)
def test_savgol_matches_scipy(window: int, polyorder: int, deriv: int, delta: float) -> None:
    rng = np.random.default_rng(window + deriv)
    for x, axis in [
        (rng.standard_normal(5000), 0),
        (rng.standard_normal((400, 6)).cumsum(axis=0), 0),
        (rng.standard_normal((3, 60)), 1),
    ]:
        want = ss.savgol_filter(x, window, polyorder, deriv=deriv, delta=delta, axis=axis)
        got = savgol_filter(x, window, polyorder, deriv=deriv, delta=delta, axis=axis)
        assert got.shape == want.shape
        assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want)), (x.shape, axis)


def test_savgol_refuses_a_window_it_cannot_fit() -> None:
    with pytest.raises(ValueError, match="window"):
        savgol_filter(np.ones(10), 4, 2)
    with pytest.raises(ValueError, match="window"):
        savgol_filter(np.ones(10), 11, 2)


@pytest.mark.parametrize("n, nperseg, fs", [(5000, 1024, 10.0), (5000, 5000, 10.0), (3001, 1000, 10.0), (777, 201, 1.0)])
def test_welch_matches_scipy(n: int, nperseg: int, fs: float) -> None:
    x = np.random.default_rng(n).standard_normal(n) + np.sin(0.7 * np.arange(n))
    f0, p0 = ss.welch(x, fs=fs, nperseg=nperseg)
    f1, p1 = welch(x, fs=fs, nperseg=nperseg)
    assert np.array_equal(f0, f1)
    assert np.max(np.abs(p1 - p0)) <= 1e-12 * np.max(p0)
    assert np.argmax(p0) == np.argmax(p1)
