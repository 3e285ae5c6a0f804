"""LS / IV estimators of the block-diagonal predictor (9.2) on the model ship (Table 9.1), and the
output-error refinement started from the IV estimate."""

from __future__ import annotations

import numpy as np
import pytest

from expdesign.errors import DesignError
from expdesign.estimators import OEData, Segment, estimate, output_error, output_error_unsupported
from expdesign.ivsolve import iv_solve
from primitives.library import model_ship_thesis
from primitives.regressors import predictor_regressors
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
    segs = [Segment(q.inputs, q.nu[None], q.nu0, q.track[None, :, 2]) for q in lib]  # the nominal states as data
    est = estimate(profile, segs, method=method, mean_subtraction=ms)
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


def test_singular_system_fails_instead_of_giving_a_number(ship):
    """tau3 and tau6 hold their surge force: with the mean removed per sub-experiment (7.19) the
    tau_x instrument is rounding residue, so the surge DOF is not identifiable. Its estimate is a
    NaN and a note, never a number made of that residue; the sway and yaw DOFs stay solved."""
    profile, lib = ship
    segs = _noisy_segments(profile, [q for q in lib if q.name in ("tau3", "tau6")], batch=4, seed=2)
    for method in ("ls", "iv"):
        est = estimate(profile, segs, method=method, mean_subtraction="batchwise")
        surge = profile.predictor.dof_slice(0)
        assert np.isnan(est.theta[:, surge]).all() and np.isnan(est.cov[:, surge, surge]).all()
        assert np.isfinite(est.theta[:, surge.stop :]).all()
        assert any("4 realisation(s) failed: a singular or ill-conditioned IV system" in n for n in est.notes)
        assert not any("kept earlier instruments" in n for n in est.notes)
    # over the whole experiment the two surge-force levels differ: every DOF is solved
    est = estimate(profile, segs, method="iv", mean_subtraction="complete")
    assert np.isfinite(est.theta).all() and not any("failed" in n for n in est.notes)


def test_iv_solve_gives_each_system_its_own_numbers(ship):
    """The one IV solve of the estimator and the Monte Carlo: a batch's systems solved together
    equal each one solved alone, bit for bit, and a failed one does not touch the others."""
    profile, lib = ship
    segs = _noisy_segments(profile, [q for q in lib if q.name in ("tau3", "tau6", "tau9")], batch=3, seed=4)
    phi, tgt = (
        np.concatenate(x, axis=1)
        for x in zip(*(predictor_regressors(profile, s.y, np.broadcast_to(s.inputs, (3,) + s.inputs.shape), s.psi) for s in segs))
    )
    starts = np.cumsum([0] + [len(s.inputs) for s in segs[:-1]])
    z = phi.copy()
    z[1, :, 0] = np.nan  # realisation 1's surge system is not finite
    batch = iv_solve(profile.predictor, phi, z, tgt, "batchwise", starts)[0]
    for b in range(3):
        one = iv_solve(profile.predictor, phi[b], z[b], tgt[b], "batchwise", starts)[0]
        assert np.array_equal(one, batch[b], equal_nan=True)
    assert np.isnan(batch[1, :4]).all() and np.isfinite(batch[1, 4:]).all() and np.isfinite(batch[[0, 2]]).all()


def test_iv_solve_fails_an_ill_conditioned_or_constant_instrument_system(ship):
    profile, _ = ship
    rng = np.random.default_rng(0)
    phi, tgt = rng.normal(size=(200, 10)), rng.normal(size=(200, 3))
    phi[:, 1] = phi[:, 0] * (1.0 + 1e-14 * rng.normal(size=200))  # surge: two regressors equal to rounding
    z = phi.copy()
    z[:, 4] = 3.0  # sway: an instrument constant, mean removed over the experiment (7.20)
    assert np.isfinite(np.linalg.solve(z[:, :4].T @ phi[:, :4], z[:, :4].T @ tgt[:, 0])).all()  # LAPACK gives a number
    theta = iv_solve(profile.predictor, phi, z, tgt, "complete")[0]
    assert np.isnan(theta[:7]).all() and np.isfinite(theta[7:]).all()
    z[:, 4] = 0.0  # without mean removal only an all-zero instrument is constant
    theta = iv_solve(profile.predictor, phi, z, tgt, "none")[0]
    assert np.isnan(theta[4:7]).all() and np.isfinite(theta[7:]).all()


# -- output-error refinement ------------------------------------------------------------------------


def _continuous(profile, lib, names, batch, seed, dist=None):
    """One experiment: the named primitives' inputs back to back from the first one's start state,
    simulated ``batch`` times with the profile's disturbances (or ``dist``)."""
    prims = {q.name: q for q in lib}
    inputs = np.concatenate([prims[n].inputs for n in names])
    nu0 = np.asarray(prims[names[0]].nu0, float)
    d = Disturbances.from_profile(profile) if dist is None else dist
    r = simulate(profile, inputs, nu0=nu0, disturbances=d, batch=batch, seed=seed)
    return OEData(np.broadcast_to(inputs, (batch,) + inputs.shape), np.broadcast_to(nu0, (batch, 3)), r.y)


def test_output_error_recovers_table_9_1_from_the_nominal_model(ship):
    """Noise-free data: started from the crude nominal parameters (Table 9.1, right column) the
    refinement converges to the true parameters."""
    profile, lib = ship
    data = _continuous(profile, lib, ["tau1", "tau6", "tau8", "tau11"], 1, 0, Disturbances())
    start = profile.params("nominal")[None] * 1.0
    start[0, [1, 2, 5, 8]] = 0.5 * profile.params("true")[[1, 2, 5, 8]]  # zero would be a fixed point of no sign
    res = output_error(profile, [data], start, max_iter=40, tol=1e-20)
    np.testing.assert_allclose(res.theta[0], profile.params("true"), rtol=1e-5)
    assert res.cost[0] < 1e-6 * res.cost_start[0]


def test_output_error_cuts_the_spread_of_the_iv_estimate(ship):
    """The measurement noise enters the IV regressors (errors in variables); the output-error
    estimate, started from the IV one, has a much smaller spread, most of all for Yur."""
    profile, lib = ship
    data = _continuous(profile, lib, ["tau1", "tau6", "tau8", "tau11"], 60, 7)
    seg = Segment(data.inputs[0], data.y, data.nu0[0], None)
    iv = estimate(profile, [seg], method="iv")
    oe = output_error(profile, [data], iv.theta)
    true = profile.params("true")
    spread = {k: np.std((t - true) / np.abs(true), axis=0) for k, t in (("iv", iv.theta), ("oe", oe.theta))}
    yur = profile.predictor_param_names.index("Yur")
    assert spread["oe"][yur] < 0.7 * spread["iv"][yur]
    assert np.mean(spread["oe"]) < 0.7 * np.mean(spread["iv"])
    assert (oe.cost <= oe.cost_start).all() and oe.converged.mean() > 0.9


def test_output_error_run_does_not_depend_on_its_batch(ship):
    profile, lib = ship
    data = _continuous(profile, lib, ["tau2", "tau5"], 3, 2)
    seg = Segment(data.inputs[0], data.y, data.nu0[0], None)
    start = estimate(profile, [seg], method="iv").theta
    start[2] = 1e3  # an estimate whose simulation explodes keeps its start value
    batched = output_error(profile, [data], start)
    assert np.isinf(batched.cost[2]) and np.array_equal(batched.theta[2], start[2])
    for b in range(2):
        one = output_error(profile, [OEData(data.inputs[b : b + 1], data.nu0[b : b + 1], data.y[b : b + 1])], start[b : b + 1])
        assert np.array_equal(one.theta[0], batched.theta[b]) and one.iterations[0] == batched.iterations[b]


def test_output_error_says_which_models_it_cannot_refine():
    assert output_error_unsupported(load_profile("model-ship")) is None
    naval = load_profile("naval-vessel")
    assert "planar" in output_error_unsupported(naval)
    with pytest.raises(DesignError, match="planar"):
        output_error(naval, [], np.zeros((1, naval.predictor.n_params)))
