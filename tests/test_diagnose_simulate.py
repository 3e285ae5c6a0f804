"""The augmented model's simulation (diagnose.model.AugmentedModel.simulate_many, the loops of
diagnose.openloop): the compiled loop, run recording by recording with inputs shared by the batch
members that do not shift them, gives the bits of the numpy loop over every recording padded to
the longest, for members that switch on each kind of candidate slot (issue 26: the speed of one
diagnosis case)."""

from __future__ import annotations

import numpy as np
import pytest

from diagnose.battery import scenario
from diagnose.candidates import build_library
from diagnose.model import AugmentedModel, prepare
from primitives import jitloop
from primitives.ship import load_profile

needs_numba = pytest.mark.skipif(not jitloop.AVAILABLE, reason="numba not installed or SHIPTRIAL_KERNEL=numpy")


def _members(model: AugmentedModel) -> np.ndarray:
    """The baseline, then one member per candidate kind with its slots set, then initial states."""
    rng = np.random.default_rng(3)
    rows = [model.p0()]
    for c in model.candidates:
        P = model.p0()
        for j in model.slot_of[c.key]:
            P[j] = 2.0 if model.slot(j).kind == "delay" else 1e-3 * rng.standard_normal()
        rows.append(P)
    P = model.p0()
    P[model.n_slots_end :] = 1e-3
    rows.append(P)
    return np.array(rows)


@needs_numba
def test_compiled_per_recording_loop_matches_padded_numpy_loop(monkeypatch):
    prof = load_profile("model-ship")
    sc = scenario(("current",), 5, profile=prof)
    recs = [sc.diagnose[0].window(0, 700), sc.validate[0].window(0, 450)]  # two lengths: padding in the numpy loop
    cands, _ = build_library(prof, recs)
    model = AugmentedModel(prof, prof.params(), cands, n_rec=2)
    preps = [prepare(prof, r, i) for i, r in enumerate(recs)]
    P = _members(model)
    kinds = {model.slot(j).kind for j in range(model.n_base, model.n_slots_end)}
    assert {"current", "delay", "offset", "bias", "term"} <= kinds
    monkeypatch.setattr(jitloop, "MIN_WORK", 0)
    ran, open_loop = [], jitloop.open_loop
    monkeypatch.setattr(jitloop, "open_loop", lambda *a: ran.append(open_loop(*a)) or ran[-1])
    compiled = model.simulate_many(preps, P)
    assert len(ran) == 2 and all(r is not None for r in ran)  # compiled, one call per recording
    monkeypatch.setattr(jitloop, "AVAILABLE", False)
    numpy_loop = model.simulate_many(preps, P)
    for a, b, p in zip(compiled, numpy_loop, preps):
        assert a.shape == (len(P), p.n + 1, 3)
        assert np.array_equal(a, b, equal_nan=True)
    # one member alone simulates as it does among the others (its inputs are its own)
    for k in (0, len(P) // 2, len(P) - 1):
        monkeypatch.setattr(jitloop, "AVAILABLE", True)
        alone = model.simulate_many(preps, P[k : k + 1])
        assert all(np.array_equal(a[0], b[k], equal_nan=True) for a, b in zip(alone, compiled))


@needs_numba
def test_open_loop_reads_inputs_shared_by_the_batch(monkeypatch):
    """Exogenous signals given once, (N, 1), step every member as the same signals given per member."""
    from primitives.simulate import VelocityStep
    from primitives.terms import TermSet

    monkeypatch.setattr(jitloop, "MIN_WORK", 0)
    rng = np.random.default_rng(1)
    terms = TermSet([["u_r", "tau_x", "v_r*r"], ["v_r", "tau_y", "psi"], ["r", "tau_n", "r*U^-1"]])
    batch, n = 4, 150
    step = VelocityStep(terms, rng.normal(0, 1e-3, (batch, terms.n_params)))
    once = {k: rng.normal(0, 0.1, (n, 1)) for k in ("tau_x", "tau_y", "tau_n", "psi")}
    each = {k: np.repeat(v, batch, axis=1) for k, v in once.items()}
    nu0 = np.tile([1.0, 0.05, 0.01], (batch, 1))
    forced = rng.normal(0, 1e-4, (n, batch, 3))
    a = jitloop.open_loop(step, sorted(once), once, nu0, None, None, forced)
    b = jitloop.open_loop(step, sorted(each), each, nu0, None, None, forced)
    assert a is not None and np.array_equal(a, b)


@needs_numba
def test_compiled_loop_chosen_on_the_whole_calls_work(monkeypatch):
    """Run by run, each recording's work may be under jitloop.MIN_WORK while the call's is over
    it: the call still runs compiled (as one padded call did), every recording of it."""
    prof = load_profile("model-ship")
    sc = scenario((), 6, profile=prof)
    recs = [sc.diagnose[0].window(0, 400), sc.validate[0].window(0, 300)]
    model = AugmentedModel(prof, prof.params(), [], n_rec=2)
    preps = [prepare(prof, r, i) for i, r in enumerate(recs)]
    P = np.repeat(model.p0()[None], 5, axis=0)
    monkeypatch.setattr(jitloop, "_LOADED", False)
    monkeypatch.setattr(jitloop, "MIN_WORK", 5 * sum(p.n for p in preps))  # the call's work; each run's is below it
    ran, open_loop = [], jitloop.open_loop
    monkeypatch.setattr(jitloop, "open_loop", lambda *a: ran.append(open_loop(*a)) or ran[-1])
    model.simulate_many(preps, P)
    assert len(ran) == 2 and all(r is not None for r in ran)


@needs_numba
def test_recordings_stepped_side_by_side_give_each_ones_bits(monkeypatch):
    """Recordings of similar length are stepped in one compiled call (their members side by side,
    the shorter padded): the bits of each recording stepped alone, for one batch on every recording
    and for a batch of its own per recording (a Jacobian's), every kind of slot switched on."""
    from diagnose import openloop

    prof = load_profile("model-ship")
    sc = scenario(("current",), 5, profile=prof)
    recs = [sc.diagnose[0].window(0, 500), sc.validate[0].window(0, 450), sc.diagnose[0].window(100, 520)]
    model = AugmentedModel(prof, prof.params(), build_library(prof, recs)[0], n_rec=3)
    preps = [prepare(prof, r, i) for i, r in enumerate(recs)]
    P = _members(model)
    assert openloop._groups([p.n for p in preps], [len(P)] * 3) == [[0, 1, 2]] or len(P) * 3 > openloop.MERGE_MEMBERS
    batches = [P[: len(P) // 2], P[1:4], P[len(P) // 2 :]]
    calls, open_loop = [], jitloop.open_loop
    monkeypatch.setattr(jitloop, "open_loop", lambda *a: calls.append(a[3].shape[0]) or open_loop(*a))
    together = [model.simulate_many(preps, P[:10]), model.simulate_many(preps, batches)]
    assert calls == [30, sum(len(b) for b in batches)]  # one call each: every member of every recording
    monkeypatch.setattr(openloop, "MERGE_MEMBERS", 1)  # each recording alone
    alone = [model.simulate_many(preps, P[:10]), model.simulate_many(preps, batches)]
    assert len(calls) == 2 + 6
    for a, b in zip(together, alone):
        assert all(x.shape == y.shape and np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))
    # a batch per recording simulates as the same members given to each recording on its own
    for p, q, got in zip(preps, batches, together[1]):
        assert np.array_equal(model.simulate_many([p], q)[0], got, equal_nan=True)
    monkeypatch.setattr(jitloop, "AVAILABLE", False)  # the numpy loop, recording by recording: the same bits
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(model.simulate_many(preps, batches), together[1]))
