"""detect's roll band (identify/detect/rollband.py): found at the roll's spectral peak, and the
decision that leaves it out blind to a yaw residual confined to it but not to a change outside it."""

from __future__ import annotations

import numpy as np
import pytest

from identify.detect.rollband import BAND, roll_band
from identify.detect.verdict import Whitened
from identify.detect.yawmodel import YawPrior

DT, BLOCK = 0.1, 10


def _prior() -> YawPrior:
    # the decision's whitening reads only ar, sigma_w, block and structure
    return YawPrior("full", {}, 1.0, np.zeros((0, 0)), ar=np.zeros(0), sigma_w=0.01, block=BLOCK, dt=DT)


@pytest.mark.parametrize("period_s", [6.0, 8.0, 12.0])
def test_the_roll_band_lies_around_the_rolls_spectral_peak(period_s):
    t = np.arange(5000) * DT
    rng = np.random.default_rng(1)
    phi = 0.1 * np.sin(2 * np.pi * t / period_s) + 0.02 * np.sin(2 * np.pi * t / 60.0) + 0.01 * rng.standard_normal(len(t))
    band = roll_band(phi, DT, BLOCK)
    f = 1 / period_s
    assert band.lo_hz < f < band.hi_hz
    res = 1 / 102.4  # the spectrum's resolution, Hz
    assert band.lo_hz == pytest.approx(BAND[0] * f, abs=BAND[0] * res / 2)
    assert band.hi_hz == pytest.approx(BAND[1] * f, abs=BAND[1] * res / 2)


def test_no_roll_band_above_the_decisions_block_rate_or_on_a_short_recording():
    t = np.arange(5000) * DT
    assert roll_band(0.1 * np.sin(2 * np.pi * t / 3.0), DT, 40) is None  # 4 s blocks cannot carry a 3 s roll
    assert roll_band(0.1 * np.sin(2 * np.pi * t[:100] / 8.0), DT, BLOCK) is None


def test_leaving_the_roll_band_out_ignores_a_roll_band_misfit_and_keeps_a_change():
    """A residual along the inertia signature's roll-band part only (the roll-coupling misfit of a
    run that rolls more than the nominal one) is an apparent inertia change without the band left
    out, none with it; a true change (the whole signature) is estimated either way."""
    t = np.arange(5000) * DT
    slow = np.sign(np.sin(2 * np.pi * t / 40.0))  # turn onsets and ends, every 20 s
    roll = np.sin(2 * np.pi * t / 8.0)  # yaw at the roll frequency
    S = np.column_stack([slow + roll, 0.5 * slow, 0.3 * roll + 0.1 * slow])
    band = roll_band(np.sin(2 * np.pi * t / 8.0), DT, BLOCK)
    # without the band: the roll part's share of the signature's energy (1 s block means) of 0.05
    for eps, with_band, without in ((0.05 * roll, 0.0, 0.0165), (0.05 * S[:, 0], 0.05, 0.05)):
        est = {}
        for b in (None, band):
            c = Whitened.of(eps, S, _prior(), None, b).attribute(len(t), start=300)["candidates"]["yaw_inertia"]
            est[b is None] = c["relative_change"]
        assert est[False] == pytest.approx(with_band, abs=0.003)
        assert est[True] == pytest.approx(without, abs=0.003)
