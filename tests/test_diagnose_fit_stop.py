"""The stopping of the diagnosis's Levenberg-Marquardt refits (diagnose.fitting.fit), issue 30's
diagnosis time: a fit whose caller reads no covariance skips the Jacobian at its final point when
it ends at its iteration cap (the same P and rss, bit for bit, one Jacobian fewer)."""

from __future__ import annotations

import numpy as np

from diagnose import fitting
from diagnose.battery import scenario
from diagnose.candidates import build_library
from diagnose.model import AugmentedModel, prepare
from primitives.ship import load_profile


def _setup():
    """A model-ship run with a current the baseline lacks; the current's slots and the initial
    state free, started at no current (so that a short fit stops at its cap, not converged)."""
    prof = load_profile("model-ship")
    sc = scenario(("current",), 5, profile=prof)
    recs = [sc.diagnose[0].window(0, 400)]
    cands, _ = build_library(prof, recs)
    model = AugmentedModel(prof, prof.params(), cands, n_rec=1)
    preps = [prepare(prof, r, i) for i, r in enumerate(recs)]
    cur = model.slot_of[next(c.key for c in cands if c.effect == "current")]
    return model, preps, [0, *cur, *model.x0_params()]


def _counted(monkeypatch) -> list[int]:
    calls = [0]
    real = fitting.jacobian

    def counting(*a, **k):
        calls[0] += 1
        return real(*a, **k)

    monkeypatch.setattr(fitting, "jacobian", counting)
    return calls


def test_no_covariance_skips_the_last_jacobian_and_changes_nothing(monkeypatch):
    model, preps, free = _setup()
    w = np.array([10.0, 20.0, 300.0])
    calls = _counted(monkeypatch)
    for cap in (1, 2, 3):
        calls[0] = 0
        P1, cov1, rss1 = fitting.fit(model, preps, model.p0(), free, w, max_iter=cap, tol=0.0)
        with_cov = calls[0]
        calls[0] = 0
        P2, cov2, rss2 = fitting.fit(model, preps, model.p0(), free, w, max_iter=cap, tol=0.0, need_cov=False)
        assert np.array_equal(P1, P2) and rss1 == rss2  # bit for bit
        assert np.all(np.isfinite(cov1)) and np.all(np.isnan(cov2))
        assert with_cov == cap + 1 and calls[0] == cap  # ended at the cap: its final Jacobian skipped
        assert not np.array_equal(P1, model.p0()) and np.isfinite(rss1)


def test_held_at_bound_is_the_active_set():
    bounds = {1: (-0.5, 0.5), 2: (0.0, np.inf), 3: (-1.0, 1.0)}
    P = np.array([9.0, -0.5, 0.0, 0.2])
    free = [0, 1, 2, 3]
    # at its lower bound with the descent (-g) pushing down: held; pushing up, or inside: free
    assert fitting._held_at_bound(P, free, bounds, np.array([1.0, 1.0, -1.0, 1.0])).tolist() == [False, True, False, False]
    assert fitting._held_at_bound(P, free, bounds, np.array([1.0, -1.0, 1.0, -1.0])).tolist() == [False, False, True, False]


def test_bounds_never_reached_give_the_unconstrained_fit_bit_for_bit():
    model, preps, free = _setup()
    w = np.array([10.0, 20.0, 300.0])
    wide = {j: (-1e3, 1e3) for j in free[1:3]}
    got = fitting.fit(model, preps, model.p0(), free, w, max_iter=4, bounds=wide)
    ref = fitting.fit(model, preps, model.p0(), free, w, max_iter=4, bounds=wide, project=False)
    assert np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1]) and got[2] == ref[2]


def test_a_parameter_pushed_past_its_bound_stays_there_and_the_rest_converge(monkeypatch):
    """The current's first component bounded below its fitted value: the projected fit ends at the
    bound with the other parameters at their optimum given it: a lower objective than the clipped
    unconstrained steps reach, in fewer Jacobians (3 against 7 when written; the clipped steps crawl)."""
    model, preps, free = _setup()
    w = np.array([10.0, 20.0, 300.0])
    P_free, _c, _r = fitting.fit(model, preps, model.p0(), free, w, max_iter=20)
    j = free[1]
    cap = 0.5 * P_free[j]
    bounds = {j: (min(0.0, cap), max(0.0, cap))}
    calls = _counted(monkeypatch)
    P_on, _c, rss_on = fitting.fit(model, preps, model.p0(), free, w, max_iter=20, bounds=bounds)
    n_on = calls[0]
    calls[0] = 0
    P_off, _c, rss_off = fitting.fit(model, preps, model.p0(), free, w, max_iter=20, bounds=bounds, project=False)
    assert P_on[j] == cap and P_off[j] == cap
    assert rss_on < rss_off and n_on < calls[0]
