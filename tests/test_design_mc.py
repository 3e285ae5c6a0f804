"""Monte Carlo evaluation of designs (section 9.1.2): the optimized design beats the random one."""

from __future__ import annotations

import pytest

from expdesign.api import run_design
from expdesign.errors import DesignError
from expdesign.montecarlo import evaluate_designs
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
    assert opt["param_rmse_p50"] < 0.7 * rnd["param_rmse_p50"]
    assert opt["frac_param_rmse_below_1_5"] > rnd["frac_param_rmse_below_1_5"] + 0.3
    assert opt["sim_rmse_p50"] < 0.8 * rnd["sim_rmse_p50"]
    assert opt["frac_sim_rmse_below_0_15"] > rnd["frac_sim_rmse_below_0_15"] + 0.2
    return opt, rnd


def test_optimized_beats_random(setup):
    p, lib, d = setup
    res = evaluate_designs(p, {"optimized": d, "random": "random"}, runs=60, seed=2, primitives=lib)
    opt, rnd = _check_beats(res)
    assert opt["runs"] == 60 and not opt["partial"]
    assert len(res["optimized"].parameter_table()) == 10


def test_bad_run_slice(setup):
    p, lib, d = setup
    with pytest.raises(DesignError, match="run_slice"):
        evaluate_designs(p, {"x": d}, runs=4, primitives=lib, run_slice=(3, 9))


@pytest.mark.slow
def test_thesis_scale_monte_carlo(setup):
    """500 runs as in section 9.1.2 with a continuous experiment per run, the optimized design one
    sequence in library order. Measured (seeds 0-4): optimized 92.4-94.8 % below 1.5 and 99.8-100 %
    below 0.15, none diverged; random 35.8-43.0 % and 60.8-66.6 %; the thesis reports 99 / 99
    against 46 / 69 (Yur limits the parameter error: benchmarks/mc_identifiability.py)."""
    p, lib, d = setup
    res = evaluate_designs(p, {"optimized": d, "random": "random"}, runs=500, seed=0, primitives=lib)
    opt, rnd = _check_beats(res)
    assert opt["frac_param_rmse_below_1_5"] >= 0.92 and opt["frac_sim_rmse_below_0_15"] >= 0.97 and opt["diverged"] == 0
    assert rnd["frac_param_rmse_below_1_5"] <= 0.65 and rnd["frac_sim_rmse_below_0_15"] <= 0.75
