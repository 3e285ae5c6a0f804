"""What a diagnosis keeps per recording between its hundreds of simulations (issue 26, speed):
the recorded inputs' signals, the still air's and recent air velocities' wind loads, the range a
simulation escapes: the same bits as computed afresh every time."""

from __future__ import annotations

import numpy as np

from diagnose import fitting, windload
from diagnose.battery import scenario
from diagnose.candidates import build_library
from diagnose.model import AugmentedModel, prepare
from primitives.ship import load_profile


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint64)


def test_steady_wind_memo_gives_each_calls_loads_bit_for_bit():
    """A refit's calls in turn (trials, then a Jacobian at the accepted trial's wind), more air
    velocities than the memo keeps, and 0.0 beside -0.0: every call's increments as without a memo."""
    prof = load_profile("kvlcc2")
    rng = np.random.default_rng(3)
    n = 60
    y = np.column_stack([rng.normal(7.0, 1.0, n), rng.normal(0.0, 0.1, n), rng.normal(0.0, 0.01, n)])
    y[::4, 1] = -0.0
    psi = np.where(np.arange(n) % 2, 0.0, np.pi)
    memo: dict = {}
    calls = []
    for k in range(windload.MEMO_AIR + 6):
        trial = np.array([[3.0 + 0.1 * k, -0.0, 0.1, 0.0], [3.0 + 0.1 * k, 0.0, 0.1, 0.0], [0.0, 2.0 + k, 0.2, 0.1]])
        jac = np.repeat(trial[1:2], 5, axis=0)
        jac[1, 0] += 1e-3
        jac[2, 2] += 1e-3  # the arm's column: the same air velocity
        jac[3, 1] = -0.0
        calls += [trial, jac]
    for wind in calls + calls[:4]:  # the first ones again after the memo dropped them
        got = windload.steady_increments(prof, y, psi, wind, 1.0, memo)
        assert np.array_equal(_bits(got), _bits(windload.steady_increments(prof, y, psi, wind, 1.0)))
    assert len(memo["air"]) <= windload.MEMO_AIR


def _model():
    prof = load_profile("model-ship")
    sc = scenario(("actuator_delay",), 5, profile=prof)
    recs = [sc.diagnose[0].window(0, 400), sc.validate[0].window(0, 300)]
    cands = build_library(prof, recs)[0]
    model = AugmentedModel(prof, prof.params(), cands, n_rec=len(recs))
    return model, recs


def test_a_recordings_kept_signals_give_a_fresh_recordings_simulation():
    """Simulations that delay or offset the inputs, switch on a steady wind, or none of these, in
    turn on the same prepared recordings: each the same bits as on recordings prepared afresh."""
    model, recs = _model()
    kept = [prepare(model.profile, r, i) for i, r in enumerate(recs)]
    P0 = model.p0()
    batches = []
    for key in ("actuator_delay", "input_offset", "wind:not-recorded", None):
        P = np.repeat(P0[None], 2, axis=0)
        cand = next((c for c in model.candidates if key and (c.effect == key or c.key == key)), None)
        assert (cand is None) == (key is None), key  # each kind is in the library
        if cand is not None:
            j = model.slot_of[cand.key][0]
            P[1, j] = 1.0 if cand.effect != "input_offset" else 0.01
        batches.append(P)
    for P in batches + batches[::-1]:
        fresh = [prepare(model.profile, r, i) for i, r in enumerate(recs)]
        for a, b in zip(model.simulate_many(kept, P), model.simulate_many(fresh, P)):
            assert np.array_equal(_bits(a), _bits(b))


def test_residuals_mark_a_non_finite_or_huge_simulation_as_before(monkeypatch):
    """Residuals skip the clip only where it would change nothing: a NaN, an infinite and a
    blown-up member still read 1e6 (either sign), a sound member its own difference."""
    model, recs = _model()
    p = prepare(model.profile, recs[0], 0)
    yh = np.repeat(model.simulate(p, model.p0()), 4, axis=0)
    yh[1, 10, 2] = np.nan
    yh[2, 20, 0] = -np.inf
    yh[3, 30, 1] = 3e6
    monkeypatch.setattr(type(model), "simulate_many", lambda self, preps, P: [yh.copy()])
    r = fitting.residuals(model, [p], np.zeros((4, model.n_params)))[0]
    want = p.y[None] - yh
    bad = ~np.isfinite(want)
    want = np.clip(want, -1e6, 1e6)
    want[bad] = 1e6
    assert np.array_equal(_bits(r), _bits(want))
    assert r[1, 10, 2] == 1e6 and r[2, 20, 0] == 1e6 and r[3, 30, 1] == -1e6
    sound = yh[:1].copy()
    monkeypatch.setattr(type(model), "simulate_many", lambda self, preps, P: [sound.copy()])
    assert np.array_equal(_bits(fitting.residuals(model, [p], np.zeros((1, model.n_params)))[0]), _bits(p.y[None] - sound))


def _current_runs():
    """model-ship runs with a current (the --fit-on runs of the tests below: a finding they show
    too) and the current candidate's slots."""
    prof = load_profile("model-ship")
    sc = scenario(("current",), 5, profile=prof)
    recs = [sc.diagnose[0].window(0, 400), sc.validate[0].window(0, 300)]
    cands = build_library(prof, recs)[0]
    model = AugmentedModel(prof, prof.params(), cands, n_rec=len(recs))
    calm = [prepare(prof, r, i) for i, r in enumerate(recs)]
    own = model.slot_of[next(c.key for c in cands if c.effect == "current")]
    return model, calm, own, next(c.key for c in cands if c.effect == "current")


def _differenced(monkeypatch, module):
    """``module.sensitivities`` by finite differences wherever it was asked for forward sensitivities."""
    from diagnose import uncertainty

    real = uncertainty.sensitivities

    def fd(*a, **k):
        k["analytic"] = False
        return real(*a, **k)

    monkeypatch.setattr(module, "sensitivities", fd)


def test_reference_misfit_by_sensitivities_within_tolerance_of_differences(monkeypatch):
    """The --fit-on misfit term reads the baseline's columns by forward sensitivities: the term
    as finite differences of every column give it, within 1e-3 of its largest entry."""
    from diagnose import uncertainty

    model, calm, own, _key = _current_runs()
    w = np.array([10.0, 20.0, 300.0])
    base = list(range(model.n_base))
    got = uncertainty.reference_misfit(model, calm, w, model.p0(), own, base)
    _differenced(monkeypatch, uncertainty)
    want = uncertainty.reference_misfit(model, calm, w, model.p0(), own, base)
    assert got is not None and want is not None and np.any(want != 0)
    assert np.max(np.abs(got - want)) <= 1e-3 * np.max(np.abs(want))


def test_structural_by_sensitivities_within_tolerance_of_differences(monkeypatch):
    """A finding the --fit-on runs show too (a current in them): its reference-fit gain with the
    baseline's columns by forward sensitivities as with finite differences, within 1e-3."""
    from diagnose import evidence

    model, calm, own, key = _current_runs()
    w = np.array([10.0, 20.0, 300.0])
    gains = {}
    for how in ("sensitivities", "differences"):
        if how == "differences":
            _differenced(monkeypatch, evidence)
        for sign in (1.0, -1.0):
            P = model.p0()
            P[own] = sign * 0.05
            got = evidence.structural(model, calm, w, P, [{"key": key}])
            gains[how, sign] = got[0]["reference_fit_gain"] if got else None
    assert [gains["sensitivities", s] is None for s in (1.0, -1.0)] == [gains["differences", s] is None for s in (1.0, -1.0)]
    shown = [s for s in (1.0, -1.0) if gains["differences", s] is not None]
    assert shown  # the current is shown on the runs that hold it
    for s in shown:
        assert abs(gains["sensitivities", s] - gains["differences", s]) <= 1e-3 * gains["differences", s]


def test_a_recordings_kept_loads_follow_the_model_that_simulates_it():
    """One prepared recording simulated with a steady wind by a model of the ship, then by a model
    of a broader one (other wind loads): the second reads its own loads, not the first's kept ones."""
    import dataclasses

    model, recs = _model()
    broad = dataclasses.replace(model.profile, beam_m=2.0 * model.profile.beam_m)
    other = AugmentedModel(broad, model.theta0, model.candidates, n_rec=len(recs))
    P = model.p0()[None].copy()
    P[0, model.slot_of["wind:not-recorded"][0]] = 3.0
    kept = [prepare(model.profile, r, i) for i, r in enumerate(recs)]
    first = model.simulate_many(kept, P)
    second = other.simulate_many(kept, P)
    fresh = other.simulate_many([prepare(broad, r, i) for i, r in enumerate(recs)], P)
    assert not np.array_equal(first[0], second[0])  # the broader ship's loads do move it otherwise
    for a, b in zip(second, fresh):
        assert np.array_equal(_bits(a), _bits(b))


def test_steady_wind_memo_of_a_long_recording_keeps_fewer_loads(monkeypatch):
    """The memo holds at most MEMO_BYTES of loads a recording (a long run keeps fewer air
    velocities), and what it dropped is computed again to the same bits."""
    prof = load_profile("kvlcc2")
    n = 50
    y = np.column_stack([np.full(n, 7.0), np.linspace(-0.1, 0.1, n), np.zeros(n)])
    psi = np.linspace(0.0, 3.0, n)
    monkeypatch.setattr(windload, "MEMO_BYTES", 3 * n * 4 * 8)  # three air velocities' loads
    memo: dict = {}
    winds = [np.array([[2.0 + k, 1.0, 0.1, 0.0]]) for k in range(6)]
    for wind in winds + winds[:2]:
        got = windload.steady_increments(prof, y, psi, wind, 1.0, memo)
        assert len(memo["air"]) <= 3
        assert np.array_equal(_bits(got), _bits(windload.steady_increments(prof, y, psi, wind, 1.0)))
