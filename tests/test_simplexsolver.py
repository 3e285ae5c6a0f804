"""The dedicated simplex solver of the convex design gives cvxpy's answer wherever it is used."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from expdesign.api import run_design
from expdesign.dopt import DEDICATED, Constraints, InfoSet, _sym_matrices, _sym_value, solve_convex
from expdesign.simplexsolver import solve_simplex
from maps.trialdesign import SOLVERS, ship_library
from primitives.information import library_information
from primitives.ship import load_profile

PLANAR = ["full-scale", "kvlcc2-linear", "kvlcc2", "model-ship"]  # naval-vessel (4-DOF pods) has no planner library


@functools.cache
def _library(name: str):
    p = load_profile(name)
    lib = [x for x in ship_library(p) if x.kind == "informative"]
    return p, lib, library_information(p, lib)


@pytest.fixture(scope="module", params=PLANAR)
def library(request):
    return _library(request.param)


@pytest.mark.parametrize("criterion", ["D", "A"])
@pytest.mark.parametrize("ms", ["none", "batchwise", "complete"])
def test_same_convex_weights_as_cvxpy(library, criterion, ms):
    p, lib, infos = library
    info = InfoSet.from_infos(infos)
    ref = solve_convex(info, criterion, ms)
    fast = solve_convex(info, criterion, ms, solvers=SOLVERS)
    assert ref.solver == "CLARABEL"
    np.testing.assert_allclose(fast.weights, ref.weights, atol=5e-5)
    if fast.solver == DEDICATED and ref.efficiency_bound is not None:
        assert fast.efficiency_bound >= ref.efficiency_bound - 1e-9  # certified at least as tightly


@pytest.mark.parametrize(("criterion", "ms"), [("D", "complete"), ("A", "complete"), ("D", "batchwise")])
@pytest.mark.parametrize("name", [pytest.param(n, marks=[] if n == "full-scale" else pytest.mark.slow) for n in PLANAR])
def test_same_design_and_counts_as_cvxpy(name, criterion, ms):
    p, lib, infos = _library(name)
    ref = run_design(p, lib, criterion=criterion, mean_subtraction=ms, infos=infos, n_random_starts=1)
    fast = run_design(p, lib, criterion=criterion, mean_subtraction=ms, infos=infos, n_random_starts=1, convex_solvers=SOLVERS)
    for name, w in ref.weights.items():
        assert fast.weights[name] == pytest.approx(w, abs=5e-5)
    assert fast.rounded == ref.rounded


def test_used_where_it_applies_and_certifies():
    info = InfoSet.from_infos(_library("full-scale")[2])
    r = solve_convex(info, "D", "complete", solvers=(DEDICATED,))
    assert r.solver == DEDICATED
    assert r.efficiency_bound > 1 - 1e-8  # the equivalence theorem: max_q tr(M^-1 M_q) = p at the optimum
    # M(uniform) is indefinite for this library (IV moments): the solver had to find a positive definite start
    mq, m0 = _sym_matrices(info, "batchwise")
    assert np.linalg.eigvalsh(mq.mean(axis=0))[0] < 0
    # E-criterion and constrained fractions are not its problem: it says so and the next solver runs
    e = solve_convex(info, "E", "complete", solvers=(DEDICATED, "CLARABEL"))
    assert e.solver == "CLARABEL" and any(f"{DEDICATED} does not apply" in n for n in e.notes)
    cons = Constraints.build(info.names, max_frac=0.4)
    c = solve_convex(info, "D", "complete", cons, solvers=(DEDICATED, "CLARABEL"))
    assert c.solver == "CLARABEL" and c.weights.max() <= 0.4 + 1e-6


def test_non_unique_optimum_is_left_to_the_conic_solver():
    """kvlcc2's library has flat directions (same M(w) for different w): the dedicated solver
    finds an optimum but does not pick among them; the interior-point solver's central one is kept."""
    info = InfoSet.from_infos(_library("kvlcc2")[2])
    mq, m0 = _sym_matrices(info, "batchwise")
    r = solve_simplex(mq, m0, "D")
    assert r is not None and not r.unique
    ref = solve_convex(info, "D", "batchwise")
    assert r.value == pytest.approx(_sym_value(m0 + np.einsum("q,qij->ij", ref.weights, mq), "D"), abs=1e-6)
    s = solve_convex(info, "D", "batchwise", solvers=(DEDICATED, "CLARABEL"))
    assert s.solver == "CLARABEL" and any("not unique" in n for n in s.notes)


def test_random_problems_match_a_brute_force_check():
    """Random positive semi-definite moments: the certified optimum beats every random mix and
    the gap certificate holds (max_q g_q = p for D)."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, p = 7, 4
        vecs = rng.normal(size=(q, p, 2))
        mq = np.einsum("qik,qjk->qij", vecs, vecs)
        r = solve_simplex(mq, np.zeros((p, p)), "D", tol=1e-12)
        assert r is not None and r.weights.min() >= 0 and r.weights.sum() == pytest.approx(1.0)
        minv = np.linalg.inv(np.einsum("q,qij->ij", r.weights, mq))
        assert np.einsum("ij,qji->q", minv, mq).max() == pytest.approx(p, rel=1e-9)
        for w in rng.dirichlet(np.ones(q), size=200):
            assert np.linalg.slogdet(np.einsum("q,qij->ij", w, mq))[1] <= r.value + 1e-9
