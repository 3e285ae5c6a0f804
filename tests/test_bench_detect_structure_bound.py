"""The bound of ``detect``'s own structure (benchmarks/bench_detect_structure_bound.py): the Neyman-Pearson
separation of a yaw-inertia change on the recorded yaw rate, the yaw row driven by the measured inputs."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.bench_detect_structure_bound import yaw_row_separation
from identify.detect.api import simulated_recording
from identify.detect.inputs import signals
from identify.detect.vessel import Vessel
from identify.detect.yawmodel import NOMINAL, PARAMS, PREFILTER_HZ, model_inputs, simulate_r

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
    assert 0.0 < d5[-1] < d10[-1] < d20[-1]
    # a small change of I_r moves the yaw rate about linearly: twice the change, about twice d
    assert 1.7 < d10[-1] / d5[-1] < 2.3
    # a change from the start has more data after it than one at 50 s
    assert d_of(inputs, 0.10, change_at=0)[-1] > d10[-1]


def delta_of(inputs, rel, change_at=500):
    """The two hypotheses' yaw-rate difference, simulated here: the changed row restarted at the change."""
    w, dt = inputs
    values = {k: NOMINAL[k] for k in PARAMS[KIND]}
    r = simulate_r(KIND, values, w, dt)
    after = {k: x[change_at:] for k, x in w.items()}
    changed = simulate_r(KIND, values | {"I_r": values["I_r"] * (1 + rel)}, after, dt, r0=float(r[change_at]))
    return np.concatenate([np.zeros(change_at), changed - r[change_at:]])


def test_d_is_the_neyman_pearson_separation_in_the_truths_noise(inputs):
    """d^2 = delta' C^-1 delta with C the truth's noise covariance built here, not by whitening: white of sd SD,
    or podded_truth's AR(1) (1.5 s) of stationary sd SD started from zero (innovation sd SD sqrt(1 - a^2))."""
    _, dt = inputs
    k = 800  # up to 300 samples after the change
    delta = delta_of(inputs, 0.10)[: k + 1]
    d_white, d_ar1 = d_of(inputs, 0.10)[k], d_of(inputs, 0.10, coloured=True)[k]
    assert d_white == pytest.approx(np.sqrt(np.sum(delta**2)) / SD, rel=1e-9)
    a = np.exp(-dt / 1.5)
    i = np.arange(k + 1)
    var = SD**2 * (1 - a ** (2 * (np.minimum.outer(i, i) + 1)))  # Var of the earlier sample of each pair
    C = a ** np.abs(np.subtract.outer(i, i)) * var
    assert d_ar1 == pytest.approx(np.sqrt(delta @ np.linalg.solve(C, delta)), rel=1e-6)
    # AR(1) noise of the same sd has more power at the manoeuvre's slow frequencies: it separates less
    assert d_ar1 < 0.5 * d_white
