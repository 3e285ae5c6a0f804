"""The yaw row's roll terms as a tested run's nuisance along inertia (identify.detect.yawmodel.signatures)."""

from __future__ import annotations

import numpy as np
import pytest

from diagnose.recording import write_csv
from identify.detect.api import fit_prior, simulated_recording
from identify.detect.inputs import signals
from identify.detect.verdict import Whitened
from identify.detect.vessel import Vessel
from identify.detect.yawmodel import ROLL_TERMS, signatures, simulate_r


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    path = tmp_path_factory.mktemp("rollnuisance") / "nominal.csv"
    write_csv(simulated_recording(Vessel(), 300, seed=21, measured_moment=True), path)
    prior = fit_prior([path], "full", bootstrap=0)
    rec = simulated_recording(Vessel(), 300, seed=33, measured_moment=True)
    sig, r = signals(rec, prior.kind)
    return prior, sig, float(np.mean(r[:5]))


def _reading(prior, sig, r0, changed: dict, roll_nuisance: bool) -> float:
    """The inertia reading of a noise-free residual made by the prior with ``changed`` values."""
    w = prior.inputs(sig)
    eps = simulate_r(prior.kind, prior.values | changed, w, prior.dt, r0=r0) - simulate_r(
        prior.kind, prior.values, w, prior.dt, r0=r0
    )
    S = signatures(prior, sig, inputs=w, roll_nuisance=roll_nuisance)
    return Whitened.of(eps, S, prior).attribute(len(eps))["candidates"]["yaw_inertia"]["relative_change"]


def test_a_misfit_of_the_roll_terms_is_not_read_as_an_inertia_change(case):
    # the prior fits its roll terms at the nominal run's one roll level; a run that rolls more or less
    # sees them off, and (podded truth, strong-roll ship 100) read that as -0.65 % of I_r per degree
    prior, sig, r0 = case
    roll = {k: 1.3 * prior.values[k] for k in ROLL_TERMS if k in prior.values}
    assert len(roll) == 3  # (2.17)'s phi terms (no p recorded)
    with_nuisance = _reading(prior, sig, r0, roll, True)
    without = _reading(prior, sig, r0, roll, False)
    assert abs(with_nuisance) < 0.002 < abs(without), (with_nuisance, without)


def test_an_inertia_change_still_reads_its_size(case):
    prior, sig, r0 = case
    read = _reading(prior, sig, r0, {"I_r": 1.05 * prior.values["I_r"]}, True)
    assert read == pytest.approx(0.05, abs=0.005)
