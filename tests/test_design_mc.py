"""Monte Carlo evaluation of designs (section 9.1.2): the optimized design beats the random one."""

from __future__ import annotations

import numpy as np
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
    """With the thesis's IV estimator (the reference of an output-error evaluation) the optimized
    design beats the random one by the margins of section 9.1.2; with the output-error estimate
    it still beats it, by less (the better estimator helps the random design more)."""
    opt, rnd = res["optimized"].summary(), res["random"].summary()
    iv_opt, iv_rnd = opt.get("reference", opt), rnd.get("reference", rnd)
    assert iv_opt["estimator"] == iv_rnd["estimator"] == "iv"
    assert iv_opt["param_rmse_p50"] < 0.7 * iv_rnd["param_rmse_p50"]
    assert iv_opt["frac_param_rmse_below_1_5"] > iv_rnd["frac_param_rmse_below_1_5"] + 0.3
    assert iv_opt["sim_rmse_p50"] < 0.8 * iv_rnd["sim_rmse_p50"]
    assert iv_opt["frac_sim_rmse_below_0_15"] > iv_rnd["frac_sim_rmse_below_0_15"] + 0.2
    if opt["estimator"] == "oe":
        assert opt["param_rmse_p50"] < 0.7 * rnd["param_rmse_p50"]
        assert opt["frac_param_rmse_below_1_5"] > rnd["frac_param_rmse_below_1_5"] + 0.15
        assert opt["sim_rmse_p50"] < rnd["sim_rmse_p50"]
        assert opt["frac_sim_rmse_below_0_15"] > rnd["frac_sim_rmse_below_0_15"] + 0.1
    return opt, rnd


def test_optimized_beats_random(setup):
    p, lib, d = setup
    res = evaluate_designs(p, {"optimized": d, "random": "random"}, runs=60, seed=2, primitives=lib)
    opt, rnd = _check_beats(res)
    assert opt["runs"] == 60 and not opt["partial"] and opt["estimator"] == "oe"
    assert len(res["optimized"].parameter_table()) == 10


def test_output_error_refines_the_iv_estimate_of_the_same_runs(setup):
    """The default estimator refines each run's IV estimate (kept as the reference) by output
    error: smaller parameter and simulation errors on the same data, most of all for Yur, whose
    IV estimate suffers from the sway measurement noise in its regressors."""
    p, lib, d = setup
    r = evaluate_designs(p, {"optimized": d}, runs=40, seed=3, primitives=lib)["optimized"]
    ref = r.reference
    assert r.estimator == "oe" and ref.estimator == "iv" and np.array_equal(r.runs, ref.runs)
    assert np.median(r.param_rmse) < 0.8 * np.median(ref.param_rmse)
    assert np.median(r.sim_norm) < 0.8 * np.median(ref.sim_norm)
    spread = {t["parameter"]: t["spread"] for t in r.parameter_table()}
    ref_spread = {t["parameter"]: t["spread"] for t in ref.parameter_table()}
    assert spread["Yur"] < 0.7 * ref_spread["Yur"]
    iv = evaluate_designs(p, {"optimized": d}, runs=40, seed=3, primitives=lib, estimator="iv")["optimized"]
    assert iv.reference is None and iv.digest() == ref.digest()  # the reference is exactly the IV evaluation


def test_bad_run_slice(setup):
    p, lib, d = setup
    with pytest.raises(DesignError, match="run_slice"):
        evaluate_designs(p, {"x": d}, runs=4, primitives=lib, run_slice=(3, 9))


@pytest.mark.slow
def test_thesis_scale_monte_carlo(setup):
    """500 runs as in section 9.1.2 with a continuous experiment per run, the optimized design one
    sequence in library order; the thesis reports 99 / 99 against 46 / 69. Measured, seeds 0-9,
    with the design of the converged-IV information model: output error optimized 99.4-100 % below
    1.5 and 99.4-100 % below 0.15 (one run of 5,000 diverged, seed 6), random 65-72 % and 77-80 %;
    the IV reference (the thesis's estimator) optimized 91.8-94.2 % and 99.0-100 %, random
    35.8-43.0 % and 60.6-66.6 % (Yur limits the IV parameter error). The design from the profile's
    instrument set gave 92.4-94.8 % for the IV, about half a point more (the one information model
    costs it; README)."""
    p, lib, d = setup
    res = evaluate_designs(p, {"optimized": d, "random": "random"}, runs=500, seed=0, primitives=lib)
    opt, rnd = _check_beats(res)
    assert opt["frac_param_rmse_below_1_5"] >= 0.99 and opt["frac_sim_rmse_below_0_15"] >= 0.99 and opt["diverged"] == 0
    iv_opt, iv_rnd = opt["reference"], rnd["reference"]
    assert iv_opt["frac_param_rmse_below_1_5"] >= 0.91 and iv_opt["frac_sim_rmse_below_0_15"] >= 0.97
    assert iv_rnd["frac_param_rmse_below_1_5"] <= 0.65 and iv_rnd["frac_sim_rmse_below_0_15"] <= 0.75


def test_report_gives_both_estimators_beside_the_thesis(setup):
    """The design report names the estimator, gives the IV figures of the same runs (the thesis's
    estimator) beside the output-error ones and the thesis's, and the per-parameter spreads of both."""
    from expdesign.mc_parallel import evaluate_designs_parallel
    from expdesign.report import markdown, report_dict

    p, lib, d = setup
    ev = evaluate_designs_parallel(
        p, {"optimized": d, "random": "random"}, runs=6, seed=1, scheduler="inline", progress=False, primitives=lib, n_samples=400
    )
    doc = report_dict(d, ev)
    opt = doc["monte_carlo"]["optimized"]
    assert opt["estimator"] == "oe" and opt["reference"]["estimator"] == "iv"
    assert opt["reference"]["limiting_parameter"] in p.predictor_param_names and len(opt["reference"]["parameters"]) == 10
    assert doc["monte_carlo_config"]["estimator"] == "oe"
    text = markdown(doc, {})
    assert "| optimized (oe) | 6 |" in text and "| optimized (iv, thesis's estimator) | 6 |" in text
    assert "| random (iv, thesis's estimator) | 6 |" in text and "iv: spread" in text
    assert any(c["choice"] == "estimator" and "output error" in c["value"] for c in doc["monte_carlo_config"]["open_choices"])
    iv = report_dict(
        d,
        evaluate_designs_parallel(
            p, {"optimized": d}, runs=6, seed=1, scheduler="inline", progress=False, primitives=lib, n_samples=400, estimator="iv"
        ),
    )
    assert "reference" not in iv["monte_carlo"]["optimized"] and "| optimized (iv) | 6 |" in markdown(iv, {})
