"""The prior's fitted advance of the measured moment against the yaw rate (api.moment_shift)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from diagnose.recording import write_csv
from identify.detect.api import MOMENT, fit_prior, load_prior, save_prior, simulated_recording
from identify.detect.vessel import Vessel
from identify.detect.yawmodel import NOMINAL


def test_a_load_cell_that_lags_the_gyro_is_fitted_as_a_shift_and_keeps_the_inertia(tmp_path):
    # the podded truth family's load cell lags the gyro (0.5 s against 0.3 s); unshifted, the yaw row's
    # I_r takes the lag up and a run's inertia reading follows its roll level (strong-roll: -0.65 %/deg)
    rec = simulated_recording(Vessel(), 400, seed=21, measured_moment=True)
    t = rec.t - rec.t[0]
    lagged = np.interp(t - 0.5, t, rec.channels[MOMENT])
    path = write_csv(replace(rec, channels=rec.channels | {MOMENT: lagged}), tmp_path / "lagged.csv")
    shifted = fit_prior([path], "full", bootstrap=0)
    plain = fit_prior([path], "full", bootstrap=0, moment_lag=False)
    # the residual's minimum sits 0-0.1 s short of the lag on this data (0.4 s: I_r -7 %; unshifted -21 %)
    assert shifted.moment_shift_s in (0.4, 0.5) and plain.moment_shift_s == 0.0
    assert abs(shifted.values["I_r"] / NOMINAL["I_r"] - 1) < 0.1 < 0.15 < abs(plain.values["I_r"] / NOMINAL["I_r"] - 1)
    assert load_prior(save_prior(shifted, tmp_path / "p.json")).moment_shift_s == shifted.moment_shift_s


def test_no_shift_where_the_moment_does_not_lag(tmp_path):
    path = write_csv(simulated_recording(Vessel(), 400, seed=21, measured_moment=True), tmp_path / "n.csv")
    assert fit_prior([path], "full", bootstrap=0).moment_shift_s == 0.0
