"""The oe estimator's sway-roll-yaw model against physics it must hold: hydrostatics of a load on a
wall-sided hull, sway-roll couplings, each run's own speed (Linder et al. 2015 eqs. (3)-(8))."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from identify.rollmass.model import Known, Load, load_profile
from identify.rollmass.output_error import model_matrices, start_values

PROF = load_profile()
RHO, G = 1000.0, 9.81


def _box_restoring(L: float, B: float, T0: float, KG: float, load: Load) -> float:
    """(M + m) g GM of a box barge after adding ``load`` (z down from the waterline): KB = T/2,
    BM = B^2 / (12 T), the load's CoG at T0 - zbar above the keel."""
    M = RHO * L * B * T0
    T = T0 + load.m / (RHO * L * B)
    KG_new = (M * KG + load.m * (T0 - load.zbar)) / (M + load.m)
    return (M + load.m) * G * (T / 2 + B**2 / (12 * T) - KG_new)


def _model_restoring(kn: Known, load: Load) -> float:
    """The model's roll restoring C of (3): with no p-couplings the p and phi columns of the roll
    row share the inverse mass matrix, so C = d * A[1, 3] / A[1, 1]."""
    v = {**start_values(PROF), "Y_p": 0.0, "n_p": 0.0}
    A, *_ = model_matrices(v, kn, -0.03, load)
    return v["d"] * A[1, 3] / A[1, 1]


@pytest.mark.parametrize("load", [Load(0.2, -0.256), Load(0.4, -0.268), Load(0.4, 0.05)])
def test_a_loads_restoring_is_its_weight_less_its_buoyancy_at_the_waterline(load):
    """A load changes the roll stiffness by its weight at its height less the added displacement's
    buoyancy, which acts at the waterline of a wall-sided hull, not at the roll centre (the paper's
    (3)): on the basin truth's restoring variant the roll-centre version biased the mass by -11 % and
    the height by -61 mm (case 1, noise-free)."""
    L, B, T0, KG = 0.8, 0.3, 0.144, 0.146
    kn = dataclasses.replace(PROF.known, M=RHO * L * B * T0, zbar_g=T0 - KG)
    expect = _box_restoring(L, B, T0, KG, load) - _box_restoring(L, B, T0, KG, Load(0.0, 0.0))
    got = _model_restoring(kn, load) - _model_restoring(kn, Load(0.0, 0.0))
    assert got == pytest.approx(expect, rel=0.02)


def test_sway_roll_couplings_enter_the_model():
    """Y_p, Y_phi, K_v, n_p and an unequal Y_pdot change the rudder response (the fit frees K_v, n_p, Y_pdot)."""
    v = start_values(PROF)
    base = model_matrices(v, PROF.known, -0.03, Load(0.0, 0.0))[0]
    for k, val in (("Y_p", 0.6), ("Y_phi", -0.5), ("K_v", 0.6), ("n_p", 0.05), ("Y_pdot", 0.5)):
        moved = model_matrices({**v, k: val}, PROF.known, -0.03, Load(0.0, 0.0))[0]
        assert np.max(np.abs(moved - base)) > 1e-3, k


def test_each_run_has_its_own_speed():
    """The U r terms of (3) and (8) use the run's speed, not one speed for all three runs."""
    v = start_values(PROF)
    a, b = (model_matrices(v, PROF.known, -0.03, Load(0.0, 0.0), U=u) for u in (0.45, 0.55))
    assert abs(a[0][1, 2] - b[0][1, 2]) > 1e-3 and abs(a[2][1, 2] - b[2][1, 2]) > 1e-3


def test_the_rudder_force_scales_with_the_runs_speed_squared():
    """A run 10 % faster feels 21 % more rudder force and 10 % more sway damping (rho U^2 L^2 scaling)
    at the same derivatives: runs at different speeds share one ship, not one set of coefficients."""
    v = start_values(PROF)
    kn = dataclasses.replace(PROF.known, U=0.5)
    slow = model_matrices({**v, "n_v": 0.0}, kn, -0.03, Load(0.0, 0.0), U=0.5)
    fast = model_matrices({**v, "n_v": 0.0}, kn, -0.03, Load(0.0, 0.0), U=0.55)
    assert fast[1][2, 0] / slow[1][2, 0] == pytest.approx(1.21, rel=1e-9)  # r' per rudder: n_delta U^2
    assert fast[0][2, 2] / slow[0][2, 2] == pytest.approx(1.1, rel=1e-9)  # r' per r: n_r U (n_v = 0)


def test_the_imu_mounting_enters_the_outputs():
    """An accelerometer 0.1 m forward of midship reads 0.1 r' more (a_s is the negated specific force,
    so 0.1 r' less), and a gyro pitched by e_y reads p - e_y r and r + e_y p."""
    v = start_values(PROF)
    kn = dataclasses.replace(PROF.known, xbar_s=0.1)
    A, B, C0, D0 = model_matrices(v, PROF.known, -0.03, Load(0.0, 0.0))
    _, _, C1, D1 = model_matrices({**v, "e_y": 0.01}, kn, -0.03, Load(0.0, 0.0))
    np.testing.assert_allclose(C1[1] - C0[1], -0.1 * A[2], atol=1e-12)
    assert D1[1, 0] - D0[1, 0] == pytest.approx(-0.1 * B[2, 0], abs=1e-12)
    np.testing.assert_allclose(C1[0] - C0[0], [0.0, 0.0, -0.01, 0.0], atol=1e-12)
    np.testing.assert_allclose(C1[2] - C0[2], [0.0, 0.01, 0.0, 0.0], atol=1e-12)


def test_the_imu_lag_delays_the_rudder_as_the_imu_sees_it():
    """``delayed`` is x(t - lag) to second order for a signal as smooth as the paper's FIR leaves it
    (below 5 Hz at 50 Hz): a 2 Hz sine delayed 10 ms, off by under 1e-3 of its amplitude."""
    from identify.rollmass.output_error import delayed

    T, w = 0.02, 2 * np.pi * 2.0
    t = np.arange(500) * T
    got = delayed(np.sin(w * t), 0.01, T)
    assert np.max(np.abs(got - np.sin(w * (t - 0.01)))[2:-2]) < 1e-3
    np.testing.assert_array_equal(delayed(np.sin(w * t), 0.0, T), np.sin(w * t))
