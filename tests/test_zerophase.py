"""The compiled zero-phase filter (primitives.zerophase) gives scipy.signal.filtfilt's bits and its
memory layout: the change detector's low-passed inputs, and every sum over them, do not depend on
whether numba is installed or which path a call took."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter
from scipy.signal import filtfilt as scipy_filtfilt

from primitives import jitloop, zerophase

needs_numba = pytest.mark.skipif(not jitloop.AVAILABLE, reason="numba not installed or SHIPTRIAL_KERNEL=numpy")


def _signals(seed: int) -> list[tuple[np.ndarray, int]]:
    """(x, axis): rows along the last axis (C order, 13 rows: a short last group), time along axis 0
    (the detector's (n, runs) records), Fortran order, a reversed view, one signal, a NaN and an inf."""
    rng = np.random.default_rng(seed)
    x = 0.3 + rng.standard_normal((13, 700)).cumsum(axis=1) * 0.01
    y = rng.standard_normal((700, 9))
    nan = rng.standard_normal((3, 200))
    nan[1, 50] = np.nan
    nan[2, 10] = np.inf
    return [(x, -1), (x.T, 0), (np.asfortranarray(x), 1), (x[:, ::-1], -1), (y, 0), (y[:, 0], 0), (nan, 1)]


@needs_numba
@pytest.mark.parametrize("order, cutoff_hz", [(1, 0.3), (2, 0.05), (3, 1.2), (4, 0.5)])
def test_compiled_filter_gives_scipys_bits_and_layout(order: int, cutoff_hz: float, monkeypatch) -> None:
    monkeypatch.setattr(jitloop, "MIN_WORK", 0)
    calls = []
    rows = zerophase._rows
    monkeypatch.setattr(zerophase, "_rows", lambda *a: calls.append(1) or rows(*a))
    b, a = butter(order, cutoff_hz, fs=10.0)
    for i, (x, axis) in enumerate(_signals(order)):
        want = scipy_filtfilt(b, a, x, axis=axis)
        got = zerophase.filtfilt(b, a, x, axis=axis)
        assert len(calls) == i + 1  # the compiled path ran
        assert np.array_equal(got, want, equal_nan=True), (order, i)
        assert got.shape == want.shape and got.strides == want.strides, (order, i)


def test_what_the_loop_does_not_cover_is_scipys_to_rounding_with_a_message(monkeypatch) -> None:
    """Outside the compiled loop the filter is primitives.iir's (no scipy.signal import): scipy's
    to rounding (tests/test_iir.py), with a message for too short a signal."""
    monkeypatch.setattr(jitloop, "MIN_WORK", 0)
    b, a = butter(4, 0.5, fs=10.0)
    x = np.random.default_rng(1).standard_normal((2, 3, 100))
    for got, want in [
        (zerophase.filtfilt(b, a, x, axis=1 + 1), scipy_filtfilt(b, a, x, axis=2)),  # 3-D
        (zerophase.filtfilt(b, 2 * a, x[0], axis=1), scipy_filtfilt(b, 2 * a, x[0], axis=1)),  # a[0] != 1
    ]:
        assert got.shape == want.shape
        assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want))
    with pytest.raises(ValueError, match="must exceed 15 samples"):  # too short
        zerophase.filtfilt(b, a, x[0, :, :15], axis=-1)


def test_designed_lowpass_is_scipys_bits() -> None:
    for order, cutoff in [(1, 0.3), (2, 0.05), (4, 0.5)]:
        b, a = zerophase.lowpass(order, cutoff, 10.0)
        b0, a0 = butter(order, cutoff, fs=10.0)
        assert np.array_equal(b, b0) and np.array_equal(a, a0)
