"""Monte Carlo evaluation of designs (section 9.1.2)."""

from __future__ import annotations

import numpy as np
import pytest

from expdesign.api import run_design
from expdesign.errors import DesignError
from expdesign.montecarlo import evaluate_designs, merge_results
from primitives.library import model_ship_thesis
from primitives.ship import load_profile


@pytest.fixture(scope="module")
def setup():
    p = load_profile("model-ship")
    lib = model_ship_thesis(p)
    d = run_design(p, lib)
    return p, lib, d


def _check_beats(res):
    opt, rnd = res["optimized"].summary(), res["random"].summary()
    assert opt["param_rmse_p50"] < 0.5 * rnd["param_rmse_p50"]
    assert opt["frac_param_rmse_below_1_5"] > rnd["frac_param_rmse_below_1_5"] + 0.3
    assert opt["sim_rmse_p50"] < 0.5 * rnd["sim_rmse_p50"]
    assert opt["frac_sim_rmse_below_0_15"] > rnd["frac_sim_rmse_below_0_15"] + 0.25
    return opt, rnd


def test_optimized_beats_random(setup):
    p, lib, d = setup
    res = evaluate_designs(p, {"optimized": d, "random": "random"}, runs=60, seed=2, primitives=lib)
    opt, rnd = _check_beats(res)
    for key in ("param_rmse_p50", "frac_param_rmse_below_1_5", "sim_rmse_p50", "frac_sim_rmse_below_0_15"):
        assert key in opt
    assert opt["runs"] == 60


def test_same_seed_same_numbers_regardless_of_chunking(setup):
    p, lib, d = setup
    designs = {"optimized": d.weights, "random": "random"}
    whole = evaluate_designs(p, designs, runs=12, seed=7, primitives=lib)
    parts = [evaluate_designs(p, designs, runs=12, seed=7, primitives=lib, run_slice=s) for s in ((5, 12), (0, 5))]
    merged = merge_results(parts)
    small_chunks = evaluate_designs(p, designs, runs=12, seed=7, primitives=lib, chunk_size=4)
    for k in designs:
        np.testing.assert_allclose(merged[k].param_rmse, whole[k].param_rmse, rtol=1e-9)
        np.testing.assert_allclose(merged[k].sim_norm, whole[k].sim_norm, rtol=1e-9)
        np.testing.assert_allclose(small_chunks[k].sim_norm, whole[k].sim_norm, rtol=1e-9)
    other = evaluate_designs(p, designs, runs=12, seed=8, primitives=lib)
    assert not np.allclose(other["random"].sim_norm, whole["random"].sim_norm)


def test_bad_monte_carlo_input(setup):
    p, lib, d = setup
    with pytest.raises(DesignError, match="unknown primitives"):
        evaluate_designs(p, {"x": {"tau42": 1.0}}, runs=2, primitives=lib)
    with pytest.raises(DesignError, match="run_slice"):
        evaluate_designs(p, {"x": d}, runs=4, primitives=lib, run_slice=(3, 9))
    with pytest.raises(DesignError, match="'random'"):
        evaluate_designs(p, {"x": "best"}, runs=2, primitives=lib)


@pytest.mark.slow
def test_thesis_scale_monte_carlo(setup):
    """500 runs as in section 9.1.2: the optimized design must clearly beat the random one."""
    p, lib, d = setup
    res = evaluate_designs(p, {"optimized": d, "random": "random"}, runs=500, seed=0, primitives=lib)
    opt, rnd = _check_beats(res)
    assert opt["frac_param_rmse_below_1_5"] > 0.8 and opt["frac_sim_rmse_below_0_15"] > 0.9
