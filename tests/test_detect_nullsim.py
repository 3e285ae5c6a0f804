"""The no-change records' two paths (identify/detect/nullsim.py): the noise filtered once per job where
the recording's input derivation is linear (the pod yaw moment measured), filtered with the signals
otherwise; chosen from the recording, the same decisions where both apply."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from diagnose.recording import write_csv
from identify.detect import nullsim
from identify.detect.api import detect, fit_prior, hull_inertia, simulated_recording
from identify.detect.batch import detect_all
from identify.detect.inputs import Deriver, signals
from identify.detect.vessel import Vessel

HULL = dict(zip(("i_z", "n_rdot"), hull_inertia("naval-vessel")))


@pytest.fixture(scope="module")
def prior(tmp_path_factory):
    path = tmp_path_factory.mktemp("nullsim") / "nominal.csv"
    write_csv(simulated_recording(Vessel(), 400, seed=21, measured_moment=True), path)
    return fit_prior([path], "full")


def _direct(derive: Deriver):
    """The same derivation without its ``linear`` mark: null_records filters signal and noise together."""
    return lambda sig, r: derive(sig, r)


def _records(prior, rec, derive, runs=24):
    sig, r = signals(rec, prior.kind)
    return nullsim.null_records(prior, sig, runs, seed=4, derive=derive, r0=float(np.mean(r[:5])))


def test_the_derivation_is_linear_exactly_when_the_pod_moment_is_measured(prior):
    """Deriver.linear says what the derivation does: with the measured tau_n, derive(s + e) is
    derive(s) + derive(e) to rounding whatever r is; from the pod inputs (the pods' moment (2.12),
    nonlinear in the drift angle and the inflow speed, and read from r) it is not, by far."""
    rng = np.random.default_rng(7)
    for measured, linear in ((True, True), (False, False)):
        rec = simulated_recording(Vessel(), 200, seed=43, measured_moment=measured)
        d = Deriver.of(rec, prior.kind)
        assert d.linear is linear
        sig, r = signals(rec, prior.kind)
        s = {k: x[:, None] for k, x in sig.items()}
        e = {k: 0.3 * np.std(x) * rng.standard_normal((len(x), 3)) for k, x in sig.items()}
        er = 0.3 * np.std(r) * rng.standard_normal((len(r), 3))
        whole = d({k: s[k] + e[k] for k in s}, r[:, None] + er)
        parts = d(s, r[:, None]), d(e, er)
        worst = max(np.abs(whole[k] - parts[0][k] - parts[1][k]).max() / np.abs(whole[k]).max() for k in whole)
        assert (worst < 1e-12) if linear else (worst > 1e-3), (measured, worst)


def test_a_recording_without_the_measured_moment_takes_the_direct_path(prior, monkeypatch):
    """From the pod inputs the derivation is not linear: its no-change records are those of filtering
    signal and noise together, to the bit, and the noise is never filtered alone."""

    def linear(*a):
        raise AssertionError("the noise filtered alone for a derivation that is not linear")

    monkeypatch.setattr(nullsim, "_linear_inputs", linear)
    rec = simulated_recording(Vessel(), 200, seed=43)
    d = Deriver.of(rec, prior.kind)
    np.testing.assert_array_equal(_records(prior, rec, d), _records(prior, rec, _direct(d)))


def test_both_paths_give_the_same_records_and_decisions_where_both_apply(prior, monkeypatch):
    """With the measured moment the noise is filtered alone (the linear path is taken) and the records,
    thresholds and decisions are those of filtering signal and noise together: records within 1e-10 of
    their rms, thresholds within 1e-10 relative (rounding only; 40 strong-roll recordings: 8.7e-13),
    the same verdict, property and alarm time."""
    rec = simulated_recording(Vessel(), 300, seed=41, measured_moment=True, change_at_s=60.0, changed=Vessel(inertia=1.3))
    d = Deriver.of(rec, prior.kind)
    taken = []
    linear = nullsim._linear_inputs
    monkeypatch.setattr(nullsim, "_linear_inputs", lambda *a: taken.append(1) or linear(*a))
    a, b = _records(prior, rec, d), _records(prior, rec, _direct(d))
    assert taken == [1]
    assert np.abs(a - b).max() <= 1e-10 * np.sqrt(np.mean(b**2))
    lin = detect(rec, prior, null_runs=100, **HULL)
    monkeypatch.setattr(Deriver, "linear", property(lambda self: False))
    direct = detect(rec, prior, null_runs=100, **HULL)
    assert lin.changed and (lin.changed, lin.property, lin.alarm_s) == (direct.changed, direct.property, direct.alarm_s)
    np.testing.assert_allclose(lin.threshold, direct.threshold, rtol=1e-10, atol=0)
    np.testing.assert_allclose(lin.dead_zone_h, direct.dead_zone_h, rtol=1e-10, atol=0)


def test_a_job_keeps_the_filtered_noise_per_derivation(prior):
    """Recordings of one length share their noise draws in a job; its filtered share is kept per
    derivation: a recording without the measured v' (v' the rate of the noisy v) between two with it
    gets the numbers ``detect`` gives it alone, to the bit, as do the others and a pod-input one."""
    recs = [
        simulated_recording(Vessel(), 250, seed=s, measured_moment=m)
        for s, m in ((52, True), (53, True), (54, True), (55, False))
    ]
    recs[1] = replace(recs[1], channels={k: x for k, x in recs[1].channels.items() if k != "v_dot"})
    assert Deriver.of(recs[1], prior.kind).form != Deriver.of(recs[0], prior.kind).form
    for a, b in zip(
        detect_all(recs, prior, null_runs=60, **HULL), [detect(r, prior, null_runs=60, **HULL) for r in recs], strict=True
    ):
        for k in ("statistic", "dead_zone", "threshold"):
            assert np.array_equal(getattr(a, k), getattr(b, k), equal_nan=True), k


@pytest.mark.parametrize("kernel", ["numpy", "default"])
@pytest.mark.parametrize("cols", [3, 40])
def test_signals_added_by_blocks_simulate_the_sums_to_the_bit(prior, cols, kernel, monkeypatch):
    """``simulate_r(..., extra=e)`` (the no-change records' noise share added a block of samples at a time
    inside numpy's loop, no (n, runs) sums held) is ``simulate_r`` on ``sig + e``, to the bit: on Python
    floats (3 columns) and by array steps (40), the clean signals one broadcast column as in
    ``null_records``; with an actuator gain other than 1 tau_r's sum is formed first and the other signals
    still added in the loop (the same bits too). ``numpy``: the compiled loop switched off, so numpy's loop
    must be the one that adds (checked through a spy: with numba loaded it would otherwise sum first);
    ``default``: whichever loop this environment takes (with numba, the compiled one on the sums)."""
    from identify.detect.yawmodel import simulate_r
    from identify.yawid import yawloop
    from primitives import jitloop

    added = []
    if kernel == "numpy":
        monkeypatch.setattr(jitloop, "AVAILABLE", False)
        real = yawloop.simulate_numpy

        def spy(*args):
            added.append(sorted(args[7] or {}))  # extra: the signals this call adds inside its loop
            return real(*args)

        monkeypatch.setattr(yawloop, "simulate_numpy", spy)
    rec = simulated_recording(Vessel(), 300, seed=45, measured_moment=True)
    sig, _ = signals(rec, prior.kind)
    clean = prior.inputs({k: s[:, None] for k, s in sig.items()})
    rng = np.random.default_rng(11)
    noise = {k: 0.2 * np.std(s) * rng.standard_normal((len(s), cols)) for k, s in clean.items()}
    whole = {k: clean[k] + noise[k] for k in clean}
    for gain in (1.0, np.linspace(0.9, 1.1, cols)):
        ref = simulate_r(prior.kind, prior.values, whole, prior.dt, gain=gain, r0=0.01)
        got = simulate_r(prior.kind, prior.values, clean, prior.dt, gain=gain, r0=0.01, extra=noise)
        np.testing.assert_array_equal(got, ref)
    assert np.all(np.isfinite(ref)) and np.std(ref) > 0
    if kernel == "numpy":  # ref, got; ref, got: the extra calls add every signal, then all but tau_r (the gain's)
        rest = sorted(k for k in clean if k != "tau_r")
        assert added == [[], sorted(clean), [], rest], added


def test_a_unit_gain_makes_tau_r_float64_as_before(prior):
    """A float32 (or integer) tau_r is made float64 by the gain even when it is 1 (``1.0 * tau_r``), so it runs
    the same loop, to the bit, as the float64 signal: only a float64 tau_r skips the multiply. (Where numba is
    installed a float32 tau_r kept as it is would run numpy's loop, the float64 one the compiled loop: not the same bits.)"""
    from identify.detect.yawmodel import simulate_r

    rec = simulated_recording(Vessel(), 300, seed=45, measured_moment=True)
    sig, _ = signals(rec, prior.kind)
    cols = prior.inputs({k: s[:, None] for k, s in sig.items()})
    th = {k: v * np.linspace(0.98, 1.02, 40) for k, v in prior.values.items()}
    low = cols | {"tau_r": cols["tau_r"].astype(np.float32)}
    want = simulate_r(prior.kind, th, low | {"tau_r": low["tau_r"].astype(float)}, prior.dt, r0=0.01)
    np.testing.assert_array_equal(simulate_r(prior.kind, th, low, prior.dt, r0=0.01), want)


@pytest.mark.parametrize("order", ["C", "F"])
def test_the_misfit_added_in_place_is_the_offsets_added(prior, order):
    """``add_misfit`` (each block's offset written through a view of the records) is ``out +
    misfit_offsets(...)`` to the bit, a partial last block and -0.0 samples included, in either layout;
    and without a misfit (``model_error`` 0) the records plus the offsets' zeros."""
    rng = np.random.default_rng(5)
    n, runs = 7 * prior.block + 3, 6
    z = rng.standard_normal((n // prior.block, runs))
    x = np.asarray(rng.standard_normal((n, runs)), order=order)
    x[-1, 0] = x[0, 1] = -0.0
    for p in (replace(prior, model_error=0.003, ar=np.array([0.5, -0.2])), replace(prior, model_error=0.0)):
        want = x + nullsim.misfit_offsets(p, n, runs, None, z)
        got = nullsim.add_misfit(x.copy(order=order), p, z)
        assert got.tobytes() == want.tobytes()
        assert p.model_error == 0 or np.abs(got - x).max() > 1e-4  # the offsets are there
