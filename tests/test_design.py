"""Design solvers (7.18)/(7.53)/(7.57), certificate, rounding, API and bad input."""

from __future__ import annotations

import numpy as np
import pytest

from expdesign.api import run_design
from expdesign.dopt import Constraints, InfoSet, solve_convex
from expdesign.errors import DesignError
from expdesign.nonconvex import _objective, solve_nonconvex
from expdesign.rounding import efficient_rounding, round_design
from primitives.information import library_information
from primitives.library import by_name, model_ship_thesis
from primitives.ship import load_profile


@pytest.fixture(scope="module")
def ship():
    p = load_profile("model-ship")
    lib = model_ship_thesis(p)
    infos = library_information(p, lib)
    return p, lib, infos, InfoSet.from_infos(infos)


@pytest.mark.parametrize("ms", ["none", "batchwise", "complete"])
def test_convex_d_optimal_certificate(ship, ms):
    p, lib, infos, info = ship
    r = solve_convex(info, "D", ms)
    assert r.solver in ("CLARABEL", "SCS", "scipy-SLSQP")
    assert abs(r.weights.sum() - 1) < 1e-8 and r.weights.min() >= 0
    # equivalence theorem: max_q tr(M^-1 M_q) = p at the optimum
    assert r.max_gradient == pytest.approx(10.0, rel=2e-3)
    assert r.gradient.max() == pytest.approx(r.max_gradient)
    assert 0.998 <= r.efficiency_bound <= 1.0

    # no other design beats the certified bound
    def mq_val(w):
        g = info.scaled(info.gamma(w, "batchwise" if ms == "complete" else ms))
        sign, ld = np.linalg.slogdet(0.5 * (g + g.T))
        return ld if sign > 0 and np.linalg.eigvalsh(0.5 * (g + g.T)).min() > 0 else -np.inf

    rng = np.random.default_rng(0)
    best = mq_val(r.weights)
    for _ in range(30):
        assert mq_val(rng.dirichlet(np.ones(11))) <= best + 1e-6


def test_certificate_bound_is_below_one_for_a_poor_design(ship):
    from expdesign.dopt import certificate

    p, lib, infos, info = ship
    w = np.full(11, 1 / 11)
    g, mx, bound = certificate(info, w, Constraints.simplex(11), "D", "batchwise")
    assert mx > 10 and bound < 0.99
    opt = solve_convex(info, "D", "batchwise")
    # the bound is a guarantee: the uniform design's true efficiency is at least the bound
    m = lambda w: np.linalg.slogdet(0.5 * (h := info.scaled(info.gamma(w, "batchwise"))) + 0.5 * h.T)[1]
    assert np.exp((m(w) - m(opt.weights)) / 10) >= bound - 1e-9


@pytest.mark.parametrize("criterion", ["A", "E"])
def test_a_and_e_criteria(ship, criterion):
    p, lib, infos, info = ship
    r = solve_convex(info, criterion, "batchwise")
    assert abs(r.weights.sum() - 1) < 1e-6
    u = np.full(11, 1 / 11)
    assert info.value(r.weights, "batchwise", criterion) >= info.value(u, "batchwise", criterion)
    if criterion == "A":
        assert r.efficiency_bound > 0.99


def test_constraints_respected_and_infeasible_reported(ship):
    p, lib, infos, info = ship
    names = info.names
    cons = Constraints.build(names, min_frac=0.02, max_frac=0.2)
    r = solve_convex(info, "D", "batchwise", cons)
    assert r.weights.min() >= 0.02 - 1e-6 and r.weights.max() <= 0.2 + 1e-6
    assert r.efficiency_bound is not None and r.efficiency_bound > 0.99
    with pytest.raises(DesignError, match="infeasible constraints: the minimum fractions add up to 2.2"):
        Constraints.build(names, min_frac=0.2)
    with pytest.raises(DesignError, match="infeasible constraints: the maximum"):
        Constraints.build(names, max_frac=0.05)
    with pytest.raises(DesignError, match="infeasible constraints: no mix meets the budgets .*distance_m"):
        Constraints.build(names, costs={"distance_m": {n: 1.0 for n in names}}, budgets={"distance_m": 10.0}, trial_length_s=100)
    # a budget that binds: little time on the expensive tau8
    cons = Constraints.build(names, costs={"fuel": {"tau8": 1.0}}, budgets={"fuel": 5.0}, trial_length_s=100)
    r = solve_convex(info, "D", "batchwise", cons)
    assert 100 * r.weights[names.index("tau8")] <= 5.0 + 1e-4


def test_nonconvex_at_least_as_good_as_every_start(ship):
    p, lib, infos, info = ship
    cvx = solve_convex(info, "D", "complete")
    r = solve_nonconvex(info, convex_start=cvx.weights, n_random=3, seed=4)
    assert [s["start"] for s in r.starts] == ["convex", "equal", "random-1", "random-2", "random-3"]
    for s in r.starts:
        assert r.objective >= s["start_objective"] - 1e-9
        assert r.objective >= s["end_objective"] - 1e-9
    assert r.objective == pytest.approx(info.logdet(r.weights, "complete"))
    assert r.objective > info.logdet(cvx.weights, "complete")  # (7.57) improves on its relaxation


def test_nonconvex_gradient_matches_finite_differences(ship):
    p, lib, infos, info = ship
    fg = _objective(info, "D", "complete")
    w = np.random.default_rng(1).dirichlet(np.ones(11))
    f, g = fg(w)
    eps = 1e-7
    num = np.array([(fg(w + eps * e)[0] - f) / eps for e in np.eye(11)])
    np.testing.assert_allclose(g, num, rtol=1e-4, atol=1e-4)


def test_prior_data_are_complemented(ship):
    p, lib, infos, info = ship
    base = run_design(p, lib, infos=infos, mean_subtraction="batchwise")
    tau8 = infos[[i.name for i in infos].index("tau8")]
    with_prior = run_design(p, lib, infos=infos, mean_subtraction="batchwise", prior=tau8, prior_samples=3000)
    assert with_prior.weights["tau8"] < 0.5 * base.weights["tau8"]


def test_efficient_rounding_sums_to_n():
    w = np.array([0.16, 0.04, 0.09, 0.42, 0.04, 0.25])
    for n in (1, 7, 20, 33, 1000):
        c = efficient_rounding(w, n)
        assert c.sum() == n and c.min() >= 0
    assert list(efficient_rounding(np.array([0.5, 0.5, 0.0]), 3)) in ([2, 1, 0], [1, 2, 0])


def test_round_design_reports_efficiency(ship):
    p, lib, infos, info = ship
    r = solve_nonconvex(info, n_random=0)
    units = np.full(11, 100)
    total = 2000
    rd = round_design(r.weights, units, total, lambda s: info.value(s / total, "complete"), 10)
    assert rd.counts.sum() == 20
    assert 0.9 < rd.efficiency <= 1.0 + 1e-9 and rd.efficiency_loss == pytest.approx(max(0, 1 - rd.efficiency))
    # unequal units never exceed the trial length
    rd2 = round_design(
        r.weights,
        np.array([300, 300, 43, 43, 43, 27, 27, 27, 150, 150, 150]),
        1000,
        lambda s: info.value(s / 1000, "complete"),
        10,
    )
    assert rd2.samples.sum() <= 1000 and rd2.efficiency > 0.8


def test_run_design_model_ship(ship):
    p, lib, infos, info = ship
    d = run_design(p, lib, infos=infos, trial_length_s=125.0)
    assert set(d.weights) == {f"tau{i}" for i in range(1, 12)}
    assert sum(d.weights.values()) == pytest.approx(1.0)
    # section 9.1.1: decelerations, slow steep zig-zags and fast spirals carry the design
    for k in ("tau1", "tau6", "tau11"):
        assert d.weights[k] > 0.1
    assert d.efficiency_vs_uniform > 1.2 and d.efficiency_bound > 0.99
    assert sum(d.rounded[k] * d.unit_s[k] for k in d.rounded) <= 125.0 + 1e-9
    doc = d.to_dict()
    for key in ("weights", "logdet", "efficiency_vs_uniform", "efficiency_bound", "rounded", "solver_notes"):
        assert key in doc


def test_run_design_full_scale():
    d = run_design("full-scale", criterion="D")
    assert set(d.weights) == {f"tau{i}" for i in range(12, 21)}
    assert sum(d.weights.values()) == pytest.approx(1.0)
    assert d.n_params == 10 and np.isfinite(d.logdet)


def test_unidentifiable_library_names_parameters(ship):
    p, lib, infos, info = ship
    with pytest.raises(DesignError) as exc:
        run_design(p, by_name(lib, ["tau1", "tau2"]))
    msg = str(exc.value)
    assert "cannot identify" in msg and "Yv" in msg and "Ntau" in msg and "Xu'" not in msg
    assert "manoeuvre" in msg


def test_bad_options(ship):
    p, lib, infos, info = ship
    with pytest.raises(DesignError, match="criterion"):
        run_design(p, lib, infos=infos, criterion="G")
    with pytest.raises(DesignError, match="mean subtraction"):
        run_design(p, lib, infos=infos, mean_subtraction="half")
    with pytest.raises(DesignError, match="min_frac names unknown primitives"):
        run_design(p, lib, infos=infos, min_frac={"tau99": 0.1})


def test_solver_failure_falls_back_and_says_so(ship):
    p, lib, infos, info = ship
    ref = solve_convex(info, "D", "batchwise")
    r = solve_convex(info, "D", "batchwise", solvers=("NO_SUCH_SOLVER", "SCS"))
    assert r.solver == "SCS" and any("NO_SUCH_SOLVER failed" in n for n in r.notes)
    r2 = solve_convex(info, "D", "batchwise", solvers=("NO_SUCH_SOLVER",))
    assert r2.solver == "scipy-SLSQP" and any("all conic solvers failed" in n for n in r2.notes)
    for alt in (r, r2):  # the fallbacks reach (nearly) the same optimum
        assert alt.efficiency_bound > 0.99
        assert alt.objective == pytest.approx(ref.objective, abs=0.05)


def test_prior_from_collected_data_matches_library_moments(ship):
    from expdesign.estimators import Segment, data_information

    p, lib, infos, info = ship
    (tau8,) = by_name(lib, ["tau8"])
    got = data_information(p, [Segment(tau8.inputs, tau8.nu[None], tau8.nu0, tau8.track[None, :, 2])])
    ref = infos[[i.name for i in infos].index("tau8")]
    np.testing.assert_allclose(got.X, ref.X, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(got.Y, ref.Y, rtol=1e-9, atol=1e-14)
    assert got.n_samples == 300
    d = run_design(p, lib, infos=infos, prior=got, prior_samples=got.n_samples * 10)
    assert sum(d.weights.values()) == pytest.approx(1.0)
