"""Robust design over parameter draws: the prior, the information at each draw, bayes-D and
maximin-D (expdesign.prior, expdesign.robust, expdesign.api.run_design)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from expdesign.api import run_design
from expdesign.dopt import Constraints, InfoSet
from expdesign.errors import DesignError
from expdesign.prior import file_prior, spread_prior
from expdesign.robust import draw_information, solve_robust
from primitives.information import library_information
from primitives.library import design_dictionary
from primitives.ship import load_profile


@pytest.fixture(scope="module")
def model_ship():
    p = load_profile("model-ship")
    lib = [x for x in design_dictionary(p) if x.kind == "informative"]
    return p, lib, draw_information(p, lib, spread_prior(p, 0.3, 40, seed=3), "batchwise")


def test_spread_prior_draws_within_the_spread_seeded(model_ship):
    p = model_ship[0]
    a, b = spread_prior(p, 0.3, 50, seed=1), spread_prior(p, 0.3, 50, seed=1)
    theta0 = p.params(p.simulation_set)
    assert a.draws.shape == (50, theta0.size) and np.array_equal(a.draws, b.draws)
    rel = (a.draws - theta0) / theta0
    assert np.all(np.abs(rel) <= 0.3 + 1e-12) and np.abs(rel).max() > 0.25  # fills the box, never beyond it
    assert not np.array_equal(a.draws, spread_prior(p, 0.3, 50, seed=2).draws)


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.5, float("nan")])
def test_spread_outside_0_1_is_refused(model_ship, bad):
    with pytest.raises(DesignError, match=r"--prior-spread .*\(0, 1\]"):
        spread_prior(model_ship[0], bad)


def test_prior_file_draws_and_covariance_follow_the_parameter_names(tmp_path, model_ship):
    p = model_ship[0]
    names, theta0 = p.param_names, p.params(p.simulation_set)
    rev = names[::-1]
    f = tmp_path / "draws.json"
    draws = np.vstack([theta0 * 1.1, theta0 * 0.9])
    f.write_text(json.dumps({"parameter_names": rev, "draws": draws[:, ::-1].tolist()}))
    assert np.allclose(file_prior(p, f).draws, draws)  # columns put back in the profile's order
    sd = np.abs(theta0) * 0.1 + 1e-9
    g = tmp_path / "cov.json"
    g.write_text(json.dumps({"parameter_names": rev, "covariance": np.diag(sd[::-1] ** 2).tolist()}))
    pr = file_prior(p, g, n_draws=4000, seed=0)
    assert np.allclose(pr.draws.mean(axis=0), theta0, atol=5 * sd / np.sqrt(4000) + 1e-12)  # 5 sigma of 10 means
    assert np.array_equal(pr.centre, theta0)  # the centre stays the profile's values (the mean only draws)
    assert np.allclose(pr.draws.std(axis=0), sd, rtol=0.1)


@pytest.mark.parametrize(
    "doc, match",
    [
        ("{not json", "not a readable prior file"),
        ({"parameter_names": ["Xu"], "covariance": [[1.0]]}, "'parameter_names' does not match .*missing"),
        ({"draws": [[1.0]]}, "'parameter_names' must list"),
        ({"diagnosed_model": {"format": "x"}}, "holds no parameter covariance"),
        ({"parameter_names": "NAMES", "covariance": [[-1.0] * 10] * 10}, "not positive semi-definite"),
    ],
)
def test_bad_prior_file_is_refused_naming_file_and_field(tmp_path, model_ship, doc, match):
    p = model_ship[0]
    f = tmp_path / "prior.json"
    if isinstance(doc, dict) and doc.get("parameter_names") == "NAMES":
        doc = doc | {"parameter_names": p.param_names}
    f.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    with pytest.raises(DesignError, match=match) as e:
        file_prior(p, f)
    assert str(f) in str(e.value) and "\n" not in str(e.value)


def test_information_at_the_profile_values_is_the_library_information():
    """kvlcc2's instruments are its simulation set, so at theta_0 the draws' matrices are the
    library's batchwise IV information (up to the scaling, a constant in log det)."""
    p = load_profile("kvlcc2")
    lib = [x for x in design_dictionary(p) if x.kind == "informative"]
    dinfo = draw_information(p, lib, spread_prior(p, 0.3, 4, seed=0), "batchwise")
    info = InfoSet.from_infos(library_information(p, lib))
    rng = np.random.default_rng(0)
    ws = rng.dirichlet(np.ones(len(lib)), 5)
    shift = [info.logdet(w, "batchwise") - dinfo.value(w, criterion="D") for w in ws]
    assert np.ptp(shift) < 1e-6
    # and the draws differ from it: the information does depend on the parameters
    assert np.ptp([dinfo.logdets(w) - dinfo.value(w, criterion="D") for w in ws[:1]]) > 1e-3


def test_each_draws_optimum_is_certified_and_nothing_beats_it(model_ship):
    _, lib, dinfo = model_ship
    assert dinfo.optimum_bound >= 1 - 1e-4
    rng = np.random.default_rng(1)
    for w in rng.dirichlet(np.ones(len(lib)), 20):
        assert np.all(dinfo.efficiencies(w) <= 1 + 1e-9)


def test_robust_designs_beat_the_local_one_where_they_promise(model_ship):
    """A smaller version of benchmarks/bench_robust_design.py (40 draws at 30 %): bayes-D
    raises the mean log-efficiency and the model ship's 10th percentile, maximin-D the worst draw."""
    _, lib, dinfo = model_ship
    cons = Constraints.simplex(len(lib))
    local = run_design(model_ship[0], lib, criterion="D").weights  # the mix --criterion D sails
    local = np.array([local[x.name] for x in lib])
    bayes = solve_robust(dinfo, "bayes-D", cons, local)
    maximin = solve_robust(dinfo, "maximin-D", cons, local)
    eff = {k: dinfo.efficiencies(w) for k, w in (("local", local), ("bayes", bayes.weights), ("maximin", maximin.weights))}
    assert np.log(eff["bayes"]).mean() > np.log(eff["local"]).mean()
    assert bayes.efficiency_bound > 0.9999
    assert np.percentile(eff["bayes"], 10) > np.percentile(eff["local"], 10) + 0.01
    assert eff["maximin"].min() > eff["local"].min() + 0.02 and eff["maximin"].min() >= eff["bayes"].min()


def test_run_design_robust_criteria_report_both_designs():
    p = load_profile("model-ship")
    d = run_design(p, criterion="maximin-D", parameter_prior=spread_prior(p, 0.3, 30, seed=0))
    r = d.to_dict()["robust"]
    # the local mix reported is the one --criterion D designs with the same options (the review's
    # B1: it was a local-D optimum of the draws' relaxed matrices, 0.994 median vs 0.892 sailed)
    assert r["local_weights"] == pytest.approx(run_design(p, criterion="D").weights, abs=1e-9)
    assert r["draws_used"] == 30 and set(r["d_efficiency"]) == {"local-D", "maximin-D", "local-D rounded", "rounded"}
    assert r["d_efficiency"]["maximin-D"]["min"] > r["d_efficiency"]["local-D"]["min"]
    assert sum(d.rounded.values()) > 0 and 0 < d.rounding_efficiency <= 1 + 1e-9
    with pytest.raises(DesignError, match="--prior-spread"):
        run_design(p, criterion="bayes-D")
    with pytest.raises(DesignError, match="bayes-D or maximin-D"):
        run_design(p, criterion="A", parameter_prior=spread_prior(p, 0.3, 10))
    info = library_information(p, [x for x in design_dictionary(p) if x.kind == "informative"])[0]
    with pytest.raises(DesignError, match=r"data already collected \(prior\) is not used by --criterion bayes-D"):
        run_design(p, criterion="bayes-D", parameter_prior=spread_prior(p, 0.3, 10), prior=info, prior_samples=100)


def test_planner_design_step_keeps_the_robust_criterion_when_a_manoeuvre_fits_nowhere():
    """plan's design step (maps.trialdesign): whole manoeuvres by the robust criterion, and a
    redesign without a primitive the map cannot hold, still over the same draws."""
    from maps.trialdesign import design_for_map, first_design

    p = load_profile("kvlcc2")
    prior = spread_prior(p, 0.3, 20, seed=0)
    first = first_design(p, criterion="maximin-D", parameter_prior=prior)
    assert first.design.record["criterion"] == "maximin-D" and first.draws.n_draws == 20
    big = max(first.design.counts, key=first.design.counts.get)
    calls = []

    def fits_nowhere(prims, counts):
        calls.append(dict(counts))
        return {big: (20000.0, 2000.0)} if big in counts else {}

    td = design_for_map(p, fits_nowhere, criterion="maximin-D", parameter_prior=prior, first=first)
    # the support, the short forms of the one that fits nowhere (issue 28: offered, each counted once), the redesign
    assert big not in td.counts and len(calls) == 3
    assert calls[1] and all(n.startswith(big + "_e") and c == 1 for n, c in calls[1].items())
    r = td.record["robust"]
    assert r["criterion"] == "maximin-D" and set(r["d_efficiency"]) == {"local-D", "maximin-D", "rounded"}
    # against the whole library's optimum at each draw: losing the main manoeuvre costs efficiency
    assert r["d_efficiency"]["rounded"]["median"] < first.design.record["robust"]["d_efficiency"]["rounded"]["median"]
    assert td.record["dropped"][0]["primitive"] == big and 0 < td.record["dropped"][0]["efficiency_loss"] < 1


def test_draws_restricted_to_the_parameters_estimated_are_principal_submatrices_with_their_own_optima(model_ship):
    """Parameters held at known values: each draw's information for the rest is its matrix's
    principal submatrix, and each draw's optimum is found again over those (a mix's efficiency
    against the whole model's optimum would be meaningless); the robust mixes keep their promise."""
    p, lib, dinfo = model_ship
    keep = np.ones(dinfo.n_params, bool)
    keep[[0, 4, 9]] = False
    sub = dinfo.restrict(keep)
    assert sub.n_draws == dinfo.n_draws and sub.n_params == keep.sum() and sub.names == dinfo.names
    assert np.array_equal(sub.M, dinfo.M[:, :, keep][:, :, :, keep])
    assert np.array_equal(sub.centre, dinfo.centre[:, keep][:, :, keep])
    assert sub.optimum_bound >= 1 - 1e-4
    w = np.random.default_rng(2).dirichlet(np.ones(len(lib)), 20)
    eff = np.array([sub.efficiencies(x) for x in w])
    assert np.all(eff <= 1 + 1e-9) and not np.allclose(eff, [dinfo.efficiencies(x) for x in w])
    cons = Constraints.simplex(len(lib))
    start = np.full(len(lib), 1.0 / len(lib))
    bayes, maximin = (solve_robust(sub, c, cons, start).weights for c in ("bayes-D", "maximin-D"))
    assert np.log(sub.efficiencies(bayes)).mean() >= np.log(sub.efficiencies(start)).mean()
    assert sub.efficiencies(maximin).min() >= sub.efficiencies(bayes).min() - 1e-9


@pytest.mark.parametrize("criterion", ["bayes-D", "maximin-D"])
def test_robust_criteria_design_what_fits_with_the_parameters_it_cannot_identify_held(criterion):
    """Water that holds only the speed changes: before, a robust criterion was refused there
    ('holding parameters is built for the local criteria only'); now it designs the parameters
    what fits can identify over the draws, the same parameters held as --criterion D holds."""
    from maps.trialdesign import design_for_map, ship_library
    from primitives.library import by_name

    p = load_profile("kvlcc2")
    names = ["zigzag_10_10_s", "turning_circle_35_s", "pull_out_20_s", "stopping", "acceleration", "deceleration"]
    lib = by_name(ship_library(p), names)

    def fits_nowhere(prims, counts):  # every turning manoeuvre and its short forms
        return {q.name: (20000.0, 3000.0) for q in prims if q.name.startswith(("zigzag", "turning", "pull"))}

    local = design_for_map(p, fits_nowhere, lib)
    td = design_for_map(p, fits_nowhere, lib, criterion=criterion, parameter_prior=spread_prior(p, 0.3, 20, seed=0))
    held = [h["parameter"] for h in td.record["held_parameters"]]
    assert held == [h["parameter"] for h in local.record["held_parameters"]] and 0 < len(held) < len(p.predictor_param_names)
    assert td.counts and set(td.counts) <= {"stopping", "acceleration", "deceleration"}
    r = td.record["robust"]
    assert r["criterion"] == criterion and r["draws_used"] == 20
    for s in r["d_efficiency"].values():  # against each draw's optimum over the parameters estimated
        assert 0 < s["min"] <= s["p10"] <= s["median"] <= 1 + 1e-9
    assert any("held at the profile's values" in n for n in td.notes)


def test_local_d_alias_is_d_in_the_map_design_and_unknown_criteria_raise():
    """'local-D' names the D design everywhere (the map's whole-manoeuvre design scored it as A
    and its efficiency as E before); a criterion no design knows is refused, never scored as another."""
    from maps.trialdesign import first_design

    p = load_profile("model-ship")
    a = first_design(p, criterion="D").design
    b = first_design(p, criterion="local-D").design
    assert a.counts == b.counts and a.design.weights == pytest.approx(b.design.weights)
    assert a.record["d_efficiency"] == pytest.approx(b.record["d_efficiency"]) and b.record["d_efficiency"] > 0.9
    with pytest.raises(DesignError, match="criterion must be one of"):
        first_design(p, criterion="G")
    info = InfoSet.from_infos(library_information(p, [x for x in design_dictionary(p) if x.kind == "informative"]))
    with pytest.raises(DesignError, match="criterion must be one of"):
        info.value(np.full(len(info.names), 1.0 / len(info.names)), "batchwise", "local-D")


def test_prior_monte_carlo_counts_only_diverged_runs_as_failed():
    """A parameter error that is not defined (the predictor's structure differs from the truth's,
    NaN) is not a failed run: the summary says so in the engine's note; inf (diverged) is a failure."""
    from expdesign.prior_mc import _summary

    note = "predictor structure differs from the true model: parameter error not defined"
    s = _summary(np.array([np.nan, np.nan]), np.ones((2, 3)), 1, [note])
    assert s["failed"] == 0 and s["param_error_p50"] is None and s["notes"] == [note]
    assert s["validation_rmse_p50"] == [1.0, 1.0, 1.0]
    s = _summary(np.array([0.1, 0.2, np.inf]), np.array([[1.0] * 3, [2.0] * 3, [np.inf] * 3]), 1, [])
    assert s["failed"] == 1 and s["param_error_p50"] == pytest.approx(0.2) and s["validation_rmse_p50"] == [1.5] * 3


def test_mixes_are_scored_on_held_out_draws_and_a_draws_file_is_called_in_sample(tmp_path):
    """The report's efficiencies come from fresh draws of an independent stream, not the draws the
    robust mix was optimised on (review B3); a file's fixed draws can only be scored in-sample."""
    p = load_profile("model-ship")
    prior = spread_prior(p, 0.3, 20, seed=0)
    held = prior.held_out()
    assert held.n_draws == 20 and not np.isin(held.draws, prior.draws).any()
    assert np.array_equal(held.draws, spread_prior(p, 0.3, 20, seed=0).held_out().draws)  # seeded
    d = run_design(p, criterion="bayes-D", parameter_prior=prior)
    r = d.robust
    assert r["evaluated_on"].startswith("held out: 20 fresh draws")
    lib = [x for x in design_dictionary(p) if x.kind == "informative"]
    ev = draw_information(p, lib, held, "batchwise")
    w = np.array([d.weights[x.name] for x in lib])
    assert r["d_efficiency"]["bayes-D"]["p10"] == pytest.approx(ev.summary(w)["p10"], rel=1e-9)
    f = tmp_path / "draws.json"
    f.write_text(json.dumps({"parameter_names": p.param_names, "draws": prior.draws.tolist()}))
    r = run_design(p, criterion="bayes-D", parameter_prior=file_prior(p, f)).robust
    assert r["evaluated_on"].startswith("in-sample")


def test_bayes_d_and_each_draws_optimum_agree_with_cvxpy(model_ship):
    """An independent solver (cvxpy, Clarabel: max sum_k log_det M(w; theta_k) on the simplex) on
    5 draws gives bayes-D's value, and each draw's own optimum, within p * 1e-4 of ours (review N10)."""
    import cvxpy as cp

    _, lib, dinfo = model_ship
    m = dinfo.M[:5]
    q, p = m.shape[1], m.shape[-1]

    def cvx(mats: np.ndarray) -> float:
        w = cp.Variable(q, nonneg=True)
        obj = sum(cp.log_det(sum(w[j] * mk[j] for j in range(q))) for mk in mats)
        prob = cp.Problem(cp.Maximize(obj), [cp.sum(w) == 1])
        prob.solve(solver="CLARABEL")
        return float(prob.value) / len(mats)

    sub = type(dinfo)(dinfo.names, dinfo.centre, m, dinfo.optimum[:5], dinfo.optimum_bound)
    ours = solve_robust(sub, "bayes-D", Constraints.simplex(q))
    assert sub.value(ours.weights, criterion="bayes-D") == pytest.approx(cvx(m), abs=p * 1e-4)
    for k in range(2):  # each draw's own optimum (the maximin-D reference)
        assert dinfo.optimum[k] == pytest.approx(cvx(m[k : k + 1]), abs=p * 1e-4)
