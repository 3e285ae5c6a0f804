"""Change detection (seed 000 ch. 5): dead-zone CUSUM (5.1) and the signature LR-CUSUM."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from diagnose.detect.cusum import DeadZoneCusum, calibrate_dead_zone
from diagnose.detect.glr import calibrate_signature_cusum
from diagnose.detect.yawmodel import YawParams, harbour_inputs, signatures, simulate_yaw

SIGMA = 0.0025  # Table 4.1 yaw-rate noise


def test_dead_zone_cusum_alarms_on_a_step_not_on_nominal():
    rng = np.random.default_rng(1)
    prior = SIGMA * rng.standard_normal(3000)
    det = calibrate_dead_zone(prior, n_eval=3000, false_alarm=0.02, runs=200, seed=2)
    nominal = SIGMA * rng.standard_normal(3000)
    assert det.first_alarm(nominal) is None
    step = nominal.copy()
    step[1500:] += 3 * SIGMA
    i = det.first_alarm(step)
    assert i is not None and 1500 <= i < 1700


def test_dead_zone_statistic_follows_eq_5_1():
    det = DeadZoneCusum(d=1.0, l=0.5, h=2.0)
    g = det.statistic(np.array([2.0, 0.0, 0.0, 3.0, 1.5]))
    np.testing.assert_allclose(g, [1.0, 0.5, 0.0, 2.0, 2.5])
    assert det.first_alarm(np.array([2.0, 0.0, 0.0, 3.0, 1.5])) == 4


def test_signature_cusum_detects_and_names_a_yaw_inertia_change():
    dt, n = 0.1, 2000
    p = YawParams()
    inputs = harbour_inputs(n, dt, seed=3)
    r0, _ = simulate_yaw(p, inputs, dt)
    r1, _ = simulate_yaw(replace(p, I_r=1.1 * p.I_r), inputs, dt)
    names, S = signatures(p, inputs, dt)
    rng = np.random.default_rng(4)
    det = calibrate_signature_cusum(names, SIGMA * rng.standard_normal(n), S, theta1=0.1, false_alarm=0.02, runs=100, seed=5)
    alarms = [det.detect(r1 - r0 + SIGMA * rng.standard_normal(n), S) for _ in range(5)]
    assert all(a[0] is not None and a[1] == "yaw_inertia" for a in alarms)
    assert all(0.03 < a[2] < 0.2 for a in alarms)  # the estimated relative change is ~ +10 %
    assert det.detect(SIGMA * rng.standard_normal(n), S)[0] is None
