"""The bound of ``detect``'s own structure (benchmarks/bench_detect_structure_bound.py): the Neyman-Pearson
separation of a yaw-inertia change on the recorded yaw rate, the yaw row driven by the measured inputs."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.bench_detect_structure_bound import yaw_row_separation
from identify.detect.api import simulated_recording
from identify.detect.inputs import signals
from identify.detect.vessel import Vessel
from identify.detect.yawmodel import NOMINAL, PARAMS, PREFILTER_HZ, model_inputs

KIND = "full"
SD = 0.0025  # Table 4.1's gyro sd


@pytest.fixture(scope="module")
def inputs():
    rec = simulated_recording(Vessel(), 150.0, seed=3, measured_moment=True)
    sig, _ = signals(rec, KIND)
    return model_inputs(sig, rec.sample_time, PREFILTER_HZ), rec.sample_time


def d_of(inputs, rel, change_at=500, sd=SD, coloured=False):
    w, dt = inputs
    values = {k: NOMINAL[k] for k in PARAMS[KIND]}
    return yaw_row_separation(KIND, values, w, dt, change_at, rel, sd, coloured)


def test_no_change_separates_nothing_and_a_larger_change_more(inputs):
    assert np.all(d_of(inputs, 0.0) == 0.0)
    d5, d10, d20 = (d_of(inputs, r) for r in (0.05, 0.10, 0.20))
    assert np.all(d10[:500] == 0.0)  # nothing before the change
    assert np.all(np.diff(d10) >= 0)  # evidence only accumulates
    assert 0.0 < d5[-1] < d10[-1] < d20[-1]
    # a small change of I_r moves the yaw rate about linearly: twice the change, about twice d
    assert 1.7 < d10[-1] / d5[-1] < 2.3
    # a change from the start has more data after it than one at 50 s
    assert d_of(inputs, 0.10, change_at=0)[-1] > d10[-1]


def test_the_noise_sets_the_scale_and_ar1_noise_separates_less(inputs):
    d = d_of(inputs, 0.10)[-1]
    assert d_of(inputs, 0.10, sd=SD / 2)[-1] == pytest.approx(2 * d)
    # AR(1) noise (1.5 s) of the same sd has more power at the manoeuvre's slow frequencies
    assert d_of(inputs, 0.10, coloured=True)[-1] < 0.5 * d
