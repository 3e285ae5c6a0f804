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
