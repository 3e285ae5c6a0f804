"""The smallest change a recording could show (identify/detect/power.py): the detector's own statistics on the
no-change records with the change added, the scaling with the signature and the null's spread, and the report."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from identify.detect import power
from identify.detect.glr import SignatureCusum, calibrate, structural_draws
from identify.detect.power import (
    BLIND,
    LATER,
    POWER,
    RESOLUTION,
    SMALLEST,
    _from_block,
    _increment_sums,
    _peak,
    _records,
    _smallest,
    change_figure,
    detectable,
    detectable_changes,
    null_sums,
)
from identify.detect.yawmodel import CANDIDATES, block_mean

THETA1 = np.array([0.09, 0.05, 0.05])


@pytest.fixture(scope="module")
def structured(detect_screening):
    """The shared screening's prior with a structural apparent change per candidate, its thresholds
    calibrated on the shared no-change records as screen calibrates them."""
    prior, _, sc = detect_screening
    prior = replace(prior, structure=np.array([0.02, 0.01, 0.01]))
    det = calibrate(prior, sc.S, sc.null_blocks, theta1=THETA1, false_alarm=0.02, seed=0)
    return prior, sc, det


def _share(prior, S, null, h, j, theta, seed=0, onset=0):
    """Share of the no-change records on which the detector's own statistics (SignatureCusum, candidate k with
    null_peaks' structural draw along S_k) alarm once ``theta * S_j`` is added from block ``onset`` on (zero
    before), at or after that block and not before it: the brute-force reference."""
    det = SignatureCusum(prior, THETA1, h)
    Sb = block_mean(S, prior.block)[: len(null)]
    xi = structural_draws(prior, null.shape[1], seed)
    step = Sb[:, j : j + 1].copy()
    step[:onset] = 0.0
    changed = null + theta * step
    stats = [
        det.statistics(changed + prior.structure[k] * xi[k][None, :] * Sb[:, k : k + 1], S, only=k)[..., 0] for k in range(3)
    ]
    before = np.column_stack([g[:onset].max(axis=0, initial=0.0) for g in stats]) > h
    after = np.column_stack([g[onset:].max(axis=0) for g in stats]) > h
    return np.mean(after.any(axis=1) & ~before.any(axis=1))


def test_the_detectable_change_is_the_smallest_the_detectors_own_statistics_alarm_on_in_90_percent(structured):
    prior, sc, det = structured
    got = detectable_changes(prior, sc.S, sc.null_blocks, det.h, THETA1, seed=0)
    assert np.all(np.isfinite(got)) and np.all(got > 0)
    for j, theta in enumerate(got):
        assert _share(prior, sc.S, sc.null_blocks, det.h, j, theta) >= POWER
        assert _share(prior, sc.S, sc.null_blocks, det.h, j, theta / RESOLUTION**1.01) < POWER


def test_twice_as_strong_a_signature_halves_the_detectable_change(structured):
    """The same detector (theta1 halved along a doubled signature: the same statistic and thresholds) sees a
    change theta along 2 S as one of 2 theta along S."""
    prior, sc, det = structured
    one = detectable_changes(prior, sc.S, sc.null_blocks, det.h, THETA1)
    two = detectable_changes(replace(prior, structure=prior.structure / 2), 2 * sc.S, sc.null_blocks, det.h, THETA1 / 2)
    assert two == pytest.approx(one / 2, rel=1e-4)


def test_more_no_change_spread_needs_a_larger_change(structured):
    """No-change records 1.5 times wider, thresholds calibrated on them: every candidate needs a larger change."""
    prior, sc, det = structured
    wide = 1.5 * sc.null_blocks
    h = calibrate(prior, sc.S, wide, theta1=THETA1, false_alarm=0.02, seed=0).h
    base = detectable_changes(prior, sc.S, sc.null_blocks, det.h, THETA1)
    more = detectable_changes(prior, sc.S, wide, h, THETA1)
    assert np.all(more > 1.15 * base)


def test_the_report_warns_by_name_when_min_change_is_below_what_the_recording_can_show(structured):
    prior, sc, det = structured
    sc = replace(sc, h=det.h)
    can = detectable(sc, prior, THETA1, 0.02, 0.05, i_z=3.37e7, n_rdot=-2.87e7)
    x = can["yaw_inertia"]["relative_change"]
    assert can["yaw_inertia"]["of"] == "I_z" and x is not None
    below = detectable(sc, prior, THETA1, 0.02, 0.5 * x, i_z=3.37e7, n_rdot=-2.87e7)
    above = detectable(
        sc, prior, THETA1, 0.02, 1.01 * max(can[c]["relative_change"] for c in ("yaw_inertia", "yaw_damping", "pod_gain"))
    )
    assert "yaw_inertia" in below["blind_to_min_change"] and below["warning"]["name"] == BLIND
    assert "cannot show a change" in below["warning"]["message"] and "record longer" in below["warning"]["message"]
    # true on a recording that alarmed too (the README example prints it beside CHANGED)
    assert "a verdict of no change here is no evidence" in below["warning"]["message"]
    assert above["warning"] is None and above["blind_to_min_change"] == []
    json.dumps(below, allow_nan=False)  # the JSON field: plain numbers, never NaN


def test_the_inertia_figure_is_of_i_z_on_the_hulls_basis(structured):
    """A change theta of I_r is theta (I_z - N_rdot) / I_z of I_z (verdict.physical_change): the hull's values
    convert the figure; the other candidates' are as searched."""
    prior, sc, det = structured
    sc = replace(sc, h=det.h)
    i_z, n_rdot = 3.37e7, -2.87e7
    of_ir = detectable(sc, prior, THETA1, 0.02, 0.05)
    of_iz = detectable(sc, prior, THETA1, 0.02, 0.05, i_z=i_z, n_rdot=n_rdot)
    assert of_ir["yaw_inertia"]["of"] == "I_r" and of_iz["yaw_inertia"]["of"] == "I_z"
    ratio = of_iz["yaw_inertia"]["relative_change"] / of_ir["yaw_inertia"]["relative_change"]
    assert ratio == pytest.approx((i_z - n_rdot) / i_z, rel=1e-9)
    assert of_iz["pod_gain"] == of_ir["pod_gain"]


def test_a_recording_that_cannot_alarm_even_at_the_largest_change_is_blind_to_any(structured):
    prior, sc, det = structured
    can = detectable(replace(sc, h=1e6 * det.h), prior, THETA1, 0.02, 0.05)
    assert all(can[c]["relative_change"] is None for c in ("yaw_inertia", "yaw_damping", "pod_gain"))
    assert len(can["blind_to_min_change"]) == 3 and "over 100 %" in can["warning"]["message"]
    json.dumps(can, allow_nan=False)


def test_a_first_guess_that_is_not_a_number_still_finds_the_change():
    """The search from a NaN guess (a non-finite record or signature) ends, at the same change as from SMALLEST: 10
    like records whose upward CUSUM climbs 5 theta (running sums 0..5 theta) alarm over h = 1 from theta 0.2."""
    cb = np.zeros((6, 2, 1, 1), np.float32)
    cb[:, 0, 0, 0], cb[:, 1, 0, 0] = np.arange(6), -np.arange(6)
    ca, h = np.zeros((6, 2, 10, 1), np.float32), np.ones(1, np.float32)
    got = _smallest(ca, cb, h, POWER, float("nan"))
    assert got == _smallest(ca, cb, h, POWER, SMALLEST)
    assert 0.2 < got <= 0.2 * RESOLUTION


def test_a_later_change_is_the_smallest_the_detectors_own_statistics_alarm_on_after_it(structured):
    """At a third of the record, the figure is where the detector's own statistics on the records with the
    masked signature added, alarming after the onset and not before, reach 90 %."""
    prior, sc, det = structured
    sums = null_sums(prior, sc.S, sc.null_blocks, THETA1, seed=0)
    onset = sums.blocks // 3
    for j in range(3):
        theta = change_figure(sums, j, onset, det.h)
        assert np.isfinite(theta)
        assert _share(prior, sc.S, sc.null_blocks, det.h, j, theta, onset=onset) >= POWER
        assert _share(prior, sc.S, sc.null_blocks, det.h, j, theta / RESOLUTION**1.01, onset=onset) < POWER


def test_the_figure_grows_as_the_change_starts_later_and_the_start_figure_is_as_before(structured):
    """The report's later onsets (LATER of the 300 s record) need more than the start and more the later they are;
    the start's figures are those of the search before later onsets were reported (the same bits, computed at
    b280863), whatever later onsets are asked for."""
    prior, sc, det = structured
    sc = replace(sc, h=det.h)
    can = detectable(sc, prior, THETA1, 0.02, 0.05)
    block_s = prior.block * prior.dt
    assert [x["onset_s"] for x in can["later"]] == [round(f * len(sc.null_blocks)) * block_s for f in LATER]
    sizes = [can["yaw_inertia"]["relative_change"]] + [x["yaw_inertia"]["relative_change"] for x in can["later"]]
    assert all(b > a * RESOLUTION for a, b in zip(sizes, sizes[1:]))
    # The figures computed at b280863 (start) and df5deae (later onsets, before stop 60's row-wise CUSUM peaks and
    # running sums) on an Intel Xeon; an AMD EPYC's numpy sums in another order and differs in the last bits
    # (0.10355082180862052 there): the same figures to 1e-12, not the same bits on every CPU.
    start = [can[c]["relative_change"] for c in CANDIDATES]
    assert start == pytest.approx([0.10355082180862064, 0.04164487980982664, 0.03144387703935598], rel=1e-12)
    later = [x["yaw_inertia"]["relative_change"] for x in can["later"]]
    assert later == pytest.approx([0.1390486859903234, 0.17094134438193923, 0.4252468761500347], rel=1e-12)
    other = detectable(sc, prior, THETA1, 0.02, 0.05, later_s=[10.0, 250.0])
    assert all(other[c] == can[c] for c in CANDIDATES)
    assert [x["onset_s"] for x in other["later"]] == [10.0, 250.0]
    json.dumps(can, allow_nan=False)


def test_the_masked_signature_is_close_to_the_true_sensitivity_of_a_step_at_mid_record(detect_screening, structured):
    """The approximation change_figure documents: the figure with the true sensitivity of a step at half
    the record (the prior's simulation from its own state there, parameters up by 5 %) within 3 % of the one
    with the from-start signature masked before it, each candidate; both from the start's search (zero before the
    onset)."""
    prior, rec, sc = detect_screening
    _, _, det = structured
    prior = replace(prior, structure=np.array([0.02, 0.01, 0.01]))
    i0 = (len(sc.S) // prior.block // 2) * prior.block
    masked = sc.S.copy()
    masked[:i0] = 0.0
    true = np.zeros_like(sc.S)
    true[i0:] = _sensitivity_from(prior, rec, i0)
    a = detectable_changes(prior, masked, sc.null_blocks, det.h, THETA1)
    b = detectable_changes(prior, true, sc.null_blocks, det.h, THETA1)
    assert b == pytest.approx(a, rel=RESOLUTION - 1)
    assert np.max(np.abs(true[i0:] - masked[i0:])[:, 0]) > 0.02 * np.max(np.abs(masked[:, 0]))  # not the same


def _sensitivity_from(prior, rec, i0):
    """(n - i0, 3) the prediction's change per relative change of each candidate from sample ``i0`` on, each
    simulated from the prior's state at ``i0`` (as screen predicts the recording)."""
    from identify.detect.checks import MOMENT
    from identify.detect.inputs import signals
    from identify.detect.yawmodel import _signature_columns, predict_with_signatures, shift_moment, simulate_r

    sig, r = signals(rec, prior.kind)
    sig = shift_moment(sig, prior.moment_shift_s, prior.dt) if MOMENT in rec.channels else sig
    w = prior.inputs(sig)
    r_hat, _ = predict_with_signatures(prior, w, float(np.mean(r[:5])))
    cols, gain = _signature_columns(prior, 0.05)
    out = simulate_r(prior.kind, cols, {k: x[i0:, None] for k, x in w.items()}, prior.dt, gain=gain, r0=r_hat[i0])
    return (out[:, 1:] - out[:, :1]) / 0.05


def test_a_later_change_starts_from_the_cusum_at_its_onset_and_an_earlier_alarm_is_a_miss():
    """Two records, one candidate, h = 1, a change from row 2 adding theta per row (running sums 0, 0, 0, 1, 2):
    the first's CUSUM stands at 0.9 there (sums 0, 0.5, 0.9, 0.9, 0.9), so it alarms from theta 0.05, not from
    0.5 as a CUSUM restarted at the onset would; the second alarmed at row 1 (sums 0, 1.5, 0, 0, 0), before the
    change, and never counts, though its sums after the onset alarm from theta 0.5."""
    ca = np.zeros((5, 2, 2, 1), np.float32)
    ca[:, 0, 0, 0] = [0, 0.5, 0.9, 0.9, 0.9]
    ca[:, 0, 1, 0] = [0, 1.5, 0, 0, 0]
    cb = np.zeros((5, 2, 1, 1), np.float32)
    cb[:, 0, 0, 0] = [0, 0, 0, 1, 2]
    h = np.ones(1, np.float32)
    d, c, early = _from_block(ca, cb, 2, h)
    assert early.tolist() == [False, True]
    assert _smallest(d, c, h, 0.5, 0.01, early) == pytest.approx(0.05, rel=RESOLUTION - 1)
    assert np.isnan(_smallest(d, c, h, 1.0, 0.01, early))


def _sums(rows=60, runs=130, k=3, seed=1):
    """Running sums like the search's (float32, a leading 0 row), with a NaN record, a -inf and a +inf entry."""
    rng = np.random.default_rng(seed)
    ca = np.zeros((rows, 2, runs, k), np.float32)
    ca[1:] = np.cumsum(rng.standard_normal((rows - 1, 2, runs, k)), axis=0)
    ca[5:, 0, 3, 1] = np.nan
    ca[7, 1, 4, 2] = -np.inf
    ca[9, 0, 5, 0] = np.inf
    cb = np.zeros((rows, 2, 1, k), np.float32)
    cb[1:] = np.cumsum(rng.standard_normal((rows - 1, 2, 1, k)), axis=0)
    return ca, cb


def _whole(ca, cb=None, theta=np.float32(0)):
    """The search's CUSUM peak and last term as numpy forms them on whole arrays (before stop 60)."""
    c = ca + theta * cb if cb is not None else ca.copy()
    g = c - np.minimum.accumulate(c, axis=0)
    return g.max(axis=0), g[-1]


@pytest.mark.parametrize("runs", [130, 20])
def test_the_cusum_peak_by_block_rows_is_the_whole_array_forms(runs):
    """_peak by rows (from ROWS_FROM records) and by numpy's running minimum give the same numbers, with and
    without the change's sums, NaN and infinities carried alike; a subset of records in either layout too."""
    ca, cb = _sums(runs=runs)
    theta = np.float32(0.37)
    for args in ((ca, cb, theta), (ca,)):
        peak, last = _peak(*args)
        ref_peak, ref_last = _whole(*args)
        np.testing.assert_array_equal(peak, ref_peak)
        np.testing.assert_array_equal(last, ref_last)
    todo = np.arange(0, runs, 3)
    sub = _records(ca, todo)
    np.testing.assert_array_equal(sub, ca[:, :, todo])
    np.testing.assert_array_equal(_peak(sub, cb, theta)[0], _whole(ca[:, :, todo], cb, theta)[0])


def test_a_search_by_block_rows_finds_the_change_the_whole_array_search_finds(structured, monkeypatch):
    """The README-sized search takes the rows (200 records here); forced onto numpy's whole-array running minimum
    for every record count it gives the same figures to the bit, at the start and at a later onset."""
    prior, sc, det = structured
    sums = null_sums(prior, sc.S, sc.null_blocks, THETA1, seed=0)
    rows = [change_figure(sums, j, onset, det.h) for j in range(3) for onset in (0, sums.blocks // 2)]
    monkeypatch.setattr(power, "ROWS_FROM", 10**9)
    assert [change_figure(sums, j, onset, det.h) for j in range(3) for onset in (0, sums.blocks // 2)] == rows


def test_the_increments_running_sums_by_block_rows_are_the_whole_arrays(structured):
    """null_sums' float32 running sums equal forming the (nb, 2, runs, k) increments whole, summing along axis 0
    and rounding (the form before stop 60), to the bit."""
    prior, sc, _ = structured
    sums = null_sums(prior, sc.S, sc.null_blocks, THETA1, seed=0)
    m, e, s2 = sums.m, sums.e, sums.s2
    half = (0.5 * m * m)[:, None, :]
    a = np.stack([m[:, None, :] * e - half, -m[:, None, :] * e - half], axis=1) / s2
    ref = np.zeros((len(a) + 1, *a.shape[1:]))
    np.cumsum(a, axis=0, out=ref[1:])
    got = _increment_sums(m, e, s2)
    assert got.dtype == np.float32 and got.shape == ref.shape
    assert got.tobytes() == ref.astype(np.float32).tobytes()
    assert sums.ca.tobytes() == got.tobytes()
