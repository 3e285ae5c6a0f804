"""LS / IV estimators of the block-diagonal predictor (9.2) on the model ship (Table 9.1)."""

from __future__ import annotations

import numpy as np
import pytest

from expdesign.errors import DesignError
from expdesign.estimators import Segment, estimate, segments_from_primitives
from primitives.library import model_ship_thesis
from primitives.ship import load_profile
from primitives.simulate import Disturbances, simulate


@pytest.fixture(scope="module")
def ship():
    p = load_profile("model-ship")
    return p, model_ship_thesis(p)


def _noisy_segments(profile, lib, batch, seed):
    d = Disturbances.from_profile(profile)
    segs = []
    for i, q in enumerate(lib):
        r = simulate(profile, q.inputs, nu0=q.nu0, disturbances=d, batch=batch, seed=seed + i)
        segs.append(Segment(q.inputs, r.y, q.nu0, r.psi_meas))
    return segs


@pytest.mark.parametrize("method", ["ls", "iv"])
@pytest.mark.parametrize("ms", ["none", "complete"])
def test_noise_free_data_recover_table_9_1(ship, method, ms):
    profile, lib = ship
    est = estimate(profile, segments_from_primitives(profile, lib), method=method, mean_subtraction=ms)
    true = profile.params("true")
    np.testing.assert_allclose(est.theta[0], true, rtol=1e-6)
    assert np.abs(est.residuals).max() < 1e-10
    assert est.cov.shape == (1, 10, 10)


def test_iv_less_biased_than_ls_under_noise(ship):
    profile, lib = ship
    segs = _noisy_segments(profile, lib, batch=60, seed=11)
    true = profile.params("true")
    bias = {}
    for method in ("ls", "iv"):
        est = estimate(profile, segs, method=method, mean_subtraction="complete")
        bias[method] = np.abs(np.median((est.theta - true) / np.abs(true), axis=0))
    # LS is pulled towards zero by the noisy regressors; IV is not
    assert np.mean(bias["iv"]) < 0.25 * np.mean(bias["ls"])
    assert bias["ls"][0] > 1.0 and bias["iv"][0] < 0.3  # Xu: the errors-in-variables bias


def test_batched_estimate_equals_one_by_one(ship):
    profile, lib = ship
    segs = _noisy_segments(profile, lib[:8], batch=4, seed=3)
    batched = estimate(profile, segs, max_iter=2)
    for b in range(4):
        single = [Segment(s.inputs, s.y[b : b + 1], s.nu0, s.psi[b : b + 1]) for s in segs]
        one = estimate(profile, single, max_iter=2)
        np.testing.assert_allclose(one.theta[0], batched.theta[b], rtol=1e-8, atol=1e-14)


def test_mean_subtraction_options_differ_and_are_checked(ship):
    profile, lib = ship
    segs = _noisy_segments(profile, lib, batch=5, seed=5)
    a = estimate(profile, segs, mean_subtraction="batchwise", max_iter=0).theta
    b = estimate(profile, segs, mean_subtraction="complete", max_iter=0).theta
    assert not np.allclose(a, b)
    with pytest.raises(DesignError, match="mean subtraction"):
        estimate(profile, segs, mean_subtraction="sometimes")
    with pytest.raises(DesignError, match="no data"):
        estimate(profile, [])
