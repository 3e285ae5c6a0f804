"""Källström's optional structure terms on the simulated Sea Splendour (tests/physics/sea_splendour.py, which
shares no code with the estimator): the heading-dependent wind (theta_9, theta_9 theta_10 of (3.1); phi_3 of (4.1))
and the Doppler log's lever arm (v1 = v + L1 r)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from identify.steering.api import fit_model, nomoto_parameters
from identify.steering.estimate import SteeringData
from identify.steering.mappings import SSPA_DERIVATIVES
from tests.physics import sea_splendour as ss

DERIVATIVES = ("Yv", "Yr", "Nv", "Nr", "Yd", "Nd")


def _record(run: dict, channels: tuple[str, ...]) -> SteeringData:
    return SteeringData(run["t"], run["delta"], np.column_stack([run[c] for c in channels]), channels)


def test_a_log_forward_of_midship_gives_the_midship_derivatives_when_its_lever_arm_is_given(estimator="oe"):
    """The log 147.6 m forward (Källström's fore Doppler) reads v + 147.6 r. Given the lever arm, the state-space
    fit recovers Table 3.1's midship derivatives within three standard errors; without it, the same data are fitted
    as well (the sway reference point is a change of state coordinates) but the derivatives are those of the log's
    position, the rudder's sway force more than five standard errors off. K' is the same either way."""
    run = ss.simulate(dataclasses.replace(ss.EXPERIMENT_2, log_x=147.6), 1)
    d = _record(run, ("v", "r", "psi"))
    f = fit_model(d, ss.L, ss.V, "state-space", estimator, log_x=147.6)
    assert f.ok, f.undetermined
    for k in DERIVATIVES:
        assert abs(f.p[k] - SSPA_DERIVATIVES[k]) < 3 * f.std[k], k
    g = fit_model(d, ss.L, ss.V, "state-space", estimator)
    assert abs(g.p["Yd"] - SSPA_DERIVATIVES["Yd"]) > 5 * g.std["Yd"]
    assert nomoto_parameters(g)["K'"].value == pytest.approx(nomoto_parameters(f)["K'"].value, rel=0.05)


def _wind_truth(speed: float) -> tuple[np.ndarray, float]:
    """The simulator's wind force and moment per radian of heading about the 140 deg course (prime, central
    differences of its own wind model) and the phi_3 they give: the constant of the prime characteristic
    polynomial s^3 + phi_1 s^2 + phi_2 s + phi_3 of the linear sway-yaw-heading model."""
    psi, e = np.radians(140.0), 1e-6
    w = (ss._wind(psi + e, speed) - ss._wind(psi - e, speed)) / (2 * e)
    A = np.zeros((3, 3))
    Mi = np.linalg.inv(ss.M_PRIME)
    A[:2, :2], A[:2, 2], A[2, 1] = Mi @ ss.N_PRIME, Mi @ w, 1.0
    return w, float(np.poly(A).real[3])


@pytest.mark.parametrize("model", ["state-space", "nomoto2"])
def test_a_strong_steady_wind_is_recovered_as_a_heading_spring(model):
    """A 25 m/s wind from starboard on a steady course (no course change, 50 min read every 15 s): with the wind
    terms the fit recovers the simulator's wind moment per radian of heading (N_psi, 1.1e-4 prime; its force is
    flat at a beam wind) or phi_3 (-0.08) within three standard errors, and AIC prefers it to the fit without."""
    exp = dataclasses.replace(ss.EXPERIMENT_2, wind_speed=25.0, course_change_s=1e9, duration_s=3000.0)
    run = ss.simulate(exp, 1)
    d = _record(run, ("v", "r", "psi") if model == "state-space" else ("r", "psi"))
    f = fit_model(d, ss.L, ss.V, model, "oe", wind=True)
    assert f.ok, f.undetermined
    w, phi_3 = _wind_truth(25.0)
    truth = {"Y_psi": w[0], "N_psi": w[1]} if model == "state-space" else {"phi_3": phi_3}
    for k, v in truth.items():
        assert abs(f.p[k] - v) < 3 * f.std[k], (k, f.p[k], f.std[k], v)
    key = "N_psi" if model == "state-space" else "phi_3"
    assert abs(f.p[key]) > 2 * f.std[key]  # determined, not merely consistent with zero
    assert f.aic < fit_model(d, ss.L, ss.V, model, "oe").aic - 10


def test_wind_terms_are_per_record_when_records_are_pooled():
    """Pooled records share the dynamics but each has its own wind (its direction relative to the course differs)."""
    from identify.steering.estimate import free_names
    from identify.steering.models import Structure

    st = Structure("nomoto2", ss.L, ss.V, ("r", "psi"), wind=True)
    names = free_names(st, 2, "oe")
    assert "phi_3@0" in names and "phi_3@1" in names and "phi_1" in names
    with pytest.raises(ValueError, match="nomoto2 and state-space"):
        Structure("nomoto1", ss.L, ss.V, ("r", "psi"), wind=True)


def test_split_cross_validation_refits_the_wind_with_the_dynamics_held():
    """--split with --wind (Källström's Table 3.8 refits the nuisance, wind included): on the simulated experiment 2
    (the 20 deg course change turns the wind relative to the ship) each cross row holds the other part's dynamics,
    delay and noise and refits the wind phi_3 with the biases and initial state; without --wind there is no phi_3."""
    from identify.steering.api import SteeringResult, add_cross_validation
    from identify.steering.report import _cross_document

    run = ss.simulate(dataclasses.replace(ss.EXPERIMENT_2, wind_speed=25.0), 2)
    d = _record(run, ("r", "psi"))
    res = SteeringResult("sea splendour", ss.L, ss.V, "", 0.0, [""], "nomoto2", "oe", [], [], [], [])
    add_cross_validation(res, [d], (840.0, 960.0), wind=True)
    assert len(res.cross_rows) == 4
    moved = 0
    for r in res.cross_rows:
        assert r.fit is not None and r.fit.converged, r.failure
        src = res.part_fits[(r.model_part, r.estimator)]
        assert "phi_3" in src.free and "phi_3" in r.fit.free
        assert set(r.fit.free) == {"delta_0", "phi_3", "rdot_0", "r_0", "psi_0", "b_r"}
        for k in ("phi_1", "phi_2", "phi_4", "phi_5", "T_D"):
            assert r.fit.p[k] == src.p[k]
        moved += r.fit.p["phi_3"] != src.p["phi_3"]
    assert moved == 4  # refitted on the other part, not carried over
    doc = _cross_document(res)
    assert all("phi_3" in row["refitted"] for row in doc["cross"])
