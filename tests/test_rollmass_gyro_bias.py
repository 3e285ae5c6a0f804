"""The oe fit's turn input ``(u/U - 1) (r - b)`` takes the yaw-rate gyro's bias ``b`` out, not the ship's own
mean turning (identify.rollmass.gyro_bias)."""

from __future__ import annotations

import numpy as np

from identify.rollmass.gyro_bias import gyro_biases
from identify.rollmass.model import Load, load_profile
from identify.rollmass.output_error import followed_speed, speed_inputs, start_values
from identify.rollmass.simulate import RollRecording
from tests.test_rollmass_oe_model import _ltv_outputs

PROF = load_profile()


def _turning_recording(bias: float) -> tuple[RollRecording, np.ndarray, dict, Load]:
    """A 50 s run of the model ship with its coefficients at the speed of the moment (``_ltv_outputs``),
    turning more to port than to starboard (a rudder offset of 4 deg under 15 deg, 20 s turns), slowing by
    up to 15 % in its turns (below the speed's 0.2 Hz low-pass, so followed), its gyro reading ``r + bias``.
    Returns the recording, the true yaw rate, the parameters and the load."""
    T, n = 0.02, 2500
    t = np.arange(n) * T
    ramp = np.clip(t / 2.0, 0.0, 1.0)
    delta = np.deg2rad(15.0 * np.sin(2 * np.pi * t / 20.0) + 4.0) * ramp
    u = 0.5 * (1.0 - 0.15 * np.sin(2 * np.pi * t / 20.0) ** 2 * ramp)
    v = {**start_values(PROF), "kappa": 0.0}
    load = Load(0.2, -0.256)
    truth = _ltv_outputs(v, PROF.known, load, delta, u, T)
    rec = RollRecording("turning", T, delta, truth[:, 0], truth[:, 1], truth[:, 2] + bias, U=float(np.mean(u)), u=u)
    return rec, truth[:, 2], v, load


def test_the_turn_input_takes_out_the_gyros_bias_not_the_ships_mean_turn():
    """A run that turns more one way than the other has a mean yaw rate of its own. main took ``mean r`` as
    the gyro's bias, so its turn input lost ``(u/U - 1) mean(r_ship)``: the structure that cost the basin
    truth's ``speed_loss`` fits their information on the load (stop 47). The estimate from the model's
    own yaw rate recovers a 0.01 rad/s bias to within 5 % where ``mean r`` is off by more than the bias
    itself, and the turn input built with it is the true ``(u/U - 1) r`` to within a tenth of main's error."""
    bias = 0.01
    rec, r_true, v, load = _turning_recording(bias)
    assert followed_speed(rec) is not None  # the case has a turn input
    assert abs(np.mean(rec.r) - bias) > bias  # the ship's own mean turn is larger than the bias
    got = gyro_biases(v, PROF.known, -0.03, [load], [rec], [None])[0]
    assert abs(got - bias) < 0.05 * bias, got
    want = (followed_speed(rec) - 1.0) * r_true
    err_main = np.sqrt(np.mean((speed_inputs(rec)[1] - want) ** 2))
    err_est = np.sqrt(np.mean((speed_inputs(rec, got)[1] - want) ** 2))
    assert err_est < 0.1 * err_main, (err_est, err_main)


def test_a_recording_without_a_followed_speed_has_no_bias_to_estimate():
    """Without a ``u`` column (the run's U held) there is no turn input, so no bias is estimated: None."""
    import dataclasses

    rec, _, v, load = _turning_recording(0.01)
    assert gyro_biases(v, PROF.known, -0.03, [load], [dataclasses.replace(rec, u=None)], [None]) == [None]
