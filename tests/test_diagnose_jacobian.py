"""The output-error Jacobian of the diagnosis's refits (diagnose.model.jacobian), issue 26's speed:
a recording's initial-state parameters are stepped on that recording only, and the result is the
bits of forward differences over one batch of every member on every recording."""

from __future__ import annotations

import numpy as np
import pytest

from diagnose import model as dm
from diagnose.battery import scenario
from diagnose.candidates import build_library
from diagnose.model import AugmentedModel, prepare, residuals, stack
from primitives.ship import load_profile


def _one_batch(model, preps, P, free, w, masks=None):
    """Forward differences with every member simulated on every recording (the reference)."""
    h = model.steps(preps, P)
    Pb = np.repeat(P[None], len(free) + 1, axis=0)
    for k, j in enumerate(free):
        Pb[k + 1, j] += h[j]
    R = stack(residuals(model, preps, Pb), w, masks)
    return R[0], (R[1:] - R[0]).T / h[free]


def _setup():
    prof = load_profile("model-ship")
    sc = scenario(("current",), 5, profile=prof)
    recs = [sc.diagnose[0].window(0, 400), sc.validate[0].window(0, 300)]
    cands, _ = build_library(prof, recs)
    model = AugmentedModel(prof, prof.params(), cands, n_rec=2)
    preps = [prepare(prof, r, i) for i, r in enumerate(recs)]
    P = model.p0()
    cur = model.slot_of[next(c.key for c in cands if c.effect == "current")]
    P[cur] = [0.05, -0.03]
    free = [0, 3, *cur, *model.x0_params()]
    return model, preps, P, free


def _members(ps, Pb) -> int:
    """Members simulated by one simulate_many call (one batch for every recording, or one each)."""
    return sum(len(q) for q in Pb) if isinstance(Pb, list) else len(ps) * len(Pb)


def test_split_jacobian_is_the_one_batch_forward_difference():
    model, preps, P, free = _setup()
    w = np.array([10.0, 20.0, 300.0])
    masks = [np.arange(p.n + 1) % 3 != 1 for p in preps]
    for ww, mm in ((w, None), ([w, 2 * w], masks)):
        r_ref, J_ref = _one_batch(model, preps, P, free, ww, mm)
        r, J = dm.jacobian(model, preps, P, free, ww, mm)
        assert np.array_equal(r, r_ref) and np.array_equal(J, J_ref)
        n0 = (preps[0].n) * 3 if mm is None else int(mm[0][1:].sum()) * 3
        x0 = model.x0_params()
        # a recording's initial state moves it alone
        assert not np.any(J[n0:, [free.index(j) for j in x0[:3]]]) and np.any(J[:n0, free.index(x0[0])])


def test_initial_states_are_simulated_on_their_own_recording_only(monkeypatch):
    model, preps, P, free = _setup()
    members = []
    sim = model.simulate_many
    monkeypatch.setattr(model, "simulate_many", lambda ps, Pb: members.append(_members(ps, Pb)) or sim(ps, Pb))
    dm.jacobian(model, preps, P, free, np.ones(3))
    shared = 1 + 4  # the point and the four parameters that move both recordings
    assert sum(members) == 2 * (shared + 3)  # not 2 * (1 + len(free)) = 22: each initial state on one recording
    assert len(members) == 1  # every recording's batch in one simulation (the compiled loop steps them side by side)


def test_residuals_at_the_point_given_are_not_simulated_again(monkeypatch):
    """A refit's accepted trial was simulated already: given, the Jacobian reuses it (the same bits)."""
    model, preps, P, free = _setup()
    w = np.ones(3)
    r_ref, J_ref = _one_batch(model, preps, P, free, w)
    at_P = residuals(model, preps, P[None])
    members = []
    sim = model.simulate_many
    monkeypatch.setattr(model, "simulate_many", lambda ps, Pb: members.append(_members(ps, Pb)) or sim(ps, Pb))
    r, J = dm.jacobian(model, preps, P, free, w, at_P=at_P)
    assert np.array_equal(r, r_ref) and np.array_equal(J, J_ref)
    assert sum(members) == 2 * (4 + 3)  # the point itself not simulated


def test_an_initial_state_two_recordings_share_is_stepped_on_both():
    """Two recordings prepared with one index (a run given twice) both move with its initial state."""
    model, preps, P, free = _setup()
    twice = [preps[0], prepare(model.profile, preps[1].rec, 0)]
    w = np.ones(3)
    r_ref, J_ref = _one_batch(model, twice, P, free, w)
    r, J = dm.jacobian(model, twice, P, free, w)
    assert np.array_equal(r, r_ref) and np.array_equal(J, J_ref)
    assert np.any(J[preps[0].n * 3 :, free.index(model.x0_params()[0])])


def test_a_batch_list_must_have_one_batch_per_recording():
    """simulate_many's list of batches is one per recording: a list of another length is refused,
    not zipped short (a recording's outputs silently missing)."""
    model, preps, P, _free = _setup()
    with pytest.raises(ValueError, match="one batch per recording"):
        model.simulate_many(preps, [P[None]])


def test_rows_given_below_are_stacked_under_the_same_bits():
    """A fit's prior rows (``tail``) come back below the Jacobian in one array (no vstack of J a
    step), the Jacobian's rows the bits of forward differences, by runs of adjacent columns when the
    free parameters are not in order either."""
    model, preps, P, free = _setup()
    w = np.array([10.0, 20.0, 300.0])
    shuffled = [free[2], free[0], *free[3:], free[1]]  # the columns' runs broken up
    tail = np.arange(2.0 * len(shuffled)).reshape(2, -1)
    for cols in (free, shuffled):
        r_ref, J_ref = _one_batch(model, preps, P, cols, w)
        r, J = dm.jacobian(model, preps, P, cols, w, tail=tail)
        assert np.array_equal(r, r_ref) and J.flags.c_contiguous
        assert np.array_equal(J, np.vstack([J_ref, tail]))


def test_column_runs():
    from diagnose.fitting import _column_runs

    assert _column_runs([0, 1, 2, 7, 8, 4]) == [(0, 0, 3), (3, 7, 2), (5, 4, 1)]
    assert _column_runs([]) == []
