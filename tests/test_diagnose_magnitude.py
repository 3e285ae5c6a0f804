"""The maximum-likelihood refit of the findings' magnitudes (diagnose/magnitude.py, issue 13):
a diverged refit keeps the search's estimate and says so, the search's bounds hold, and the
prior towards the profile keeps its weight relative to the data whatever the weights' scale."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import diagnose.magnitude as magnitude
from diagnose.battery import scenario
from diagnose.candidates import build_library
from diagnose.model import AugmentedModel, prepare
from primitives.ship import load_profile


@pytest.fixture(scope="module")
def setup():
    """A model-ship run whose outputs are the augmented model's own simulation (plus white
    noise of a known level per channel) with the yaw inertia scale ``true`` and the first
    yaw baseline parameter 20 % off; the model, the run and the inertia slot."""
    ship = load_profile("model-ship")
    sc = scenario((), 3, n_prims=3)
    cands, _ = build_library(ship, sc.diagnose)
    model = AugmentedModel(ship, ship.params(None), cands, n_rec=1)
    prep = prepare(ship, sc.diagnose[0], 0)
    inertia = next(c for c in cands if c.key == "inertia_change:yaw")
    return model, prep, inertia


def _data(model, prep, P_true, seed=0):
    y = model.simulate(prep, P_true)[0]
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal(y.shape) * 0.01 * np.std(y, axis=0)
    return dataclasses.replace(prep, y=y + noise)


def _free(model, c):
    return model.slot_of[c.key] + model.x0_params()


def test_diverged_refit_keeps_the_search_estimate_and_says_so(setup, monkeypatch):
    model, prep, c = setup
    P = model.p0()
    P[model.slot_of[c.key]] = -0.1
    w = np.array([1.0, 2.0, 3.0])
    monkeypatch.setattr(magnitude, "fit", lambda *a, **k: (a[2] + 1.0, None, float("inf")))
    Pn, wn, sd, note = magnitude.ml_refit(model, [prep], P, _free(model, c), [c], [], w, None)
    assert np.array_equal(Pn, P) and np.array_equal(wn, w) and sd is None
    assert "diverged" in note and "search's estimate is reported" in note


def test_refit_stays_within_the_search_bounds(setup):
    """The data want a yaw inertia scale of -0.6 (a factor 2.5): the refit stops at the
    plausible bound 1/2 - 1 = -0.5 (unbounded it would go to -0.6)."""
    model, prep, c = setup
    j = model.slot_of[c.key][0]
    P_true = model.p0()
    P_true[j] = -0.6
    run = _data(model, prep, P_true)
    P = model.p0()
    P[j] = -0.3
    Pn, _w, _sd, note = magnitude.ml_refit(model, [run], P, _free(model, c), [c], [], np.ones(3), None)
    assert note == ""
    assert Pn[j] >= -0.5 - 1e-9
    assert Pn[j] == pytest.approx(-0.5, abs=0.02)


def test_prior_keeps_its_weight_whatever_the_scale_of_the_search_weights(setup):
    """(w, prior std s) and (10 w, s / 10) are the same search criterion scaled by 100: the ML
    refit must give the same estimate and the same prior std for both. Without the prior's
    rescaling by the residual level the second prior would weigh 100 times more."""
    model, prep, c = setup
    j = model.slot_of[c.key][0]
    b = 0  # a surge baseline parameter, refitted with a prior towards the profile
    P_true = model.p0()
    P_true[j] = -0.2
    P_true[b] *= 1.5
    run = _data(model, prep, P_true, seed=1)
    P = model.p0()
    P[j] = -0.15
    free = [b] + _free(model, c)
    sd = np.full(len(P), np.inf)
    sd[b] = 0.2 * abs(model.p0()[b])
    w = np.array([1.0, 3.0, 10.0])
    P1, w1, sd1, _ = magnitude.ml_refit(model, [run], P, free, [c], [b], w, sd)
    P2, w2, sd2, _ = magnitude.ml_refit(model, [run], P, free, [c], [b], 10 * w, sd / 10)
    assert np.allclose(w1, w2)
    assert P1[b] == pytest.approx(P2[b], rel=1e-3) and P1[j] == pytest.approx(P2[j], abs=1e-4)
    assert sd1[b] == pytest.approx(sd2[b], rel=1e-6)
    # the prior pulls: the estimate is between the profile's value and the truth
    assert abs(P1[b] - model.p0()[b]) > 0.05 * abs(model.p0()[b])


def test_heldout_gate_keeps_an_equal_fit_and_refuses_a_worse_one(setup):
    """The ML estimate is refused when a validation run fits worse than with the search's
    estimate beyond the guard's slack, and kept when it fits as well."""
    model, prep, c = setup
    j = model.slot_of[c.key][0]
    P_true = model.p0()
    P_true[j] = -0.2
    val = dataclasses.replace(_data(model, prep, P_true, seed=2), index=None)
    w = np.ones(3)
    free = _free(model, c)
    assert magnitude.heldout_worse(model, [prep], [val], w, P_true, P_true.copy(), w, free) == ""
    P_bad = P_true.copy()
    P_bad[j] = 0.2
    why = magnitude.heldout_worse(model, [prep], [val], w, P_true, P_bad, w, free)
    assert "validation runs, simulated" in why and "points, at most -1" in why
    # no validation run: each diagnosed run left out in turn (linearised refit)
    runs = [dataclasses.replace(_data(model, prep, P_true, seed=k), index=0) for k in (3, 4)]
    why = magnitude.heldout_worse(model, runs, [], w, P_true, P_bad, w, free)
    assert "leave one run out" in why
    # one run, nothing held out: in-sample misfit is no evidence against the ML estimate
    assert magnitude.heldout_worse(model, [val], [], w, P_true, P_bad, w, free) == ""


def test_implausible_names_a_refitted_magnitude_on_the_bound(setup):
    model, _prep, c = setup
    P = model.p0()
    free = _free(model, c)
    P[model.slot_of[c.key][0]] = -0.5  # inertia x 0.5: on the plausible bound, absorbing another misfit
    [(cand, why)] = magnitude.implausible(model, [c], P, free, None)
    assert cand is c and "within a factor 2" in why
    P[model.slot_of[c.key][0]] = -0.2
    assert magnitude.implausible(model, [c], P, free, None) == []
