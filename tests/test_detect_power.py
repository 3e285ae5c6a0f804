"""The smallest change a recording could show (identify/detect/power.py): the detector's own statistics on the
no-change records with the change added, the scaling with the signature and the null's spread, and the report."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from identify.detect.glr import SignatureCusum, calibrate, structural_draws
from identify.detect.power import BLIND, POWER, RESOLUTION, SMALLEST, _smallest, detectable, detectable_changes
from identify.detect.yawmodel import block_mean

THETA1 = np.array([0.09, 0.05, 0.05])


@pytest.fixture(scope="module")
def structured(detect_screening):
    """The shared screening's prior with a structural apparent change per candidate, its thresholds
    calibrated on the shared no-change records as screen calibrates them."""
    prior, _, sc = detect_screening
    prior = replace(prior, structure=np.array([0.02, 0.01, 0.01]))
    det = calibrate(prior, sc.S, sc.null_blocks, theta1=THETA1, false_alarm=0.02, seed=0)
    return prior, sc, det


def _share(prior, S, null, h, j, theta, seed=0):
    """Share of the no-change records on which the detector's own statistics (SignatureCusum, candidate k with
    null_peaks' structural draw along S_k) alarm once ``theta * S_j`` is added: the brute-force reference."""
    det = SignatureCusum(prior, THETA1, h)
    Sb = block_mean(S, prior.block)[: len(null)]
    xi = structural_draws(prior, null.shape[1], seed)
    changed = null + theta * Sb[:, j : j + 1]
    peaks = np.column_stack(
        [
            det.statistics(changed + prior.structure[k] * xi[k][None, :] * Sb[:, k : k + 1], S, only=k)[..., 0].max(axis=0)
            for k in range(3)
        ]
    )
    return np.mean((peaks > h).any(axis=1))


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
