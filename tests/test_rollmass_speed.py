"""The oe model follows a recorded surge speed u(t): a ship that slows in turns (Linder et al. 2015,
Fig. 6) has velocity terms that scale with u(t) and rudder forces with u(t)^2, and holding one
speed per run biases the load. These tests use the model's own structure (they check the speed path,
they are not accuracy evidence: on the independent basin truth the bias remains, see README)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.signal import lfilter

from identify.rollmass.model import Load, load_profile
from identify.rollmass.output_error import _simulate, model_matrices, start_values
from identify.rollmass.simulate import RollRecording, joystick_rudder

PROF = load_profile()
KN = PROF.known
Z_F = -0.03
V = start_values(PROF)
T, SUB = 0.02, 8  # 50 Hz recording; RK4 at 400 Hz
TRUE = Load(0.4, -0.268)


def _speed_varying_run(load: Load, seed: int, n: int = 1500) -> RollRecording:
    """Noise-free rudder-driven run whose speed drops by up to 20 % in turns, integrated by RK4 with
    the model re-evaluated at the speed of each step (not the estimator's discretisation)."""
    rng = np.random.default_rng(seed)
    delta = joystick_rudder(n * SUB, 1 / (T / SUB), PROF.raw["experiment"], rng)
    turn = lfilter([0.002], [1, -0.998], np.abs(delta)) / np.deg2rad(20)  # speed lags the rudder (~2.5 s)
    u = KN.U * (1 - 0.2 * np.clip(turn, 0, 1))
    h = T / SUB
    x, ys = np.zeros(4), []

    # the model at each step's speed, from a table over the speeds that occur (1 mm/s apart)
    grid = np.round(u, 3)
    table = {s: model_matrices(V, KN, Z_F, load, s) for s in np.unique(grid)}

    def f(x, k):
        A, B, C, D = table[grid[k]]
        return A @ x + B[:, 0] * delta[k], C @ x + D[:, 0] * delta[k]

    for k in range(n * SUB):
        dx, y = f(x, k)
        ys.append(y)
        k2 = f(x + 0.5 * h * dx, k)[0]
        k3 = f(x + 0.5 * h * k2, k)[0]
        k4 = f(x + h * k3, min(k + 1, n * SUB - 1))[0]
        x = x + h / 6 * (dx + 2 * k2 + 2 * k3 + k4)
    y = np.array(ys)[::SUB]
    return RollRecording("speed-drop", T, delta[::SUB], y[:, 0], y[:, 1], y[:, 2], u=u[::SUB], U=float(u.mean()))


def _fit_load(rec: RollRecording) -> np.ndarray:
    """(m, zbar_m) fitted to ``rec``'s outputs with the ship's parameters at their true values."""

    def res(x):
        out, basis = _simulate(V, KN, Z_F, Load(*x), rec)
        e = np.column_stack([rec.p, rec.a_s, rec.r]) - out
        e -= basis @ np.linalg.lstsq(basis, e, rcond=None)[0]
        return (e / np.array([rec.p.std(), rec.a_s.std(), rec.r.std()])).ravel()

    return least_squares(res, [0.2, -0.256], x_scale=[0.1, 0.01]).x


@pytest.fixture(scope="module")
def run():
    return _speed_varying_run(TRUE, seed=4)


def test_the_model_with_u_reproduces_a_constant_speed_run_exactly(run):
    """u(t) = U everywhere gives the constant-speed model's outputs (the speed path adds nothing else)."""
    const = dataclasses.replace(run, u=np.full(run.n, KN.U), U=KN.U)
    a = _simulate(V, KN, Z_F, TRUE, const)[0]
    b = _simulate(V, KN, Z_F, TRUE, dataclasses.replace(const, u=None))[0]
    np.testing.assert_allclose(a, b, atol=1e-9 * np.abs(b).max())


def test_a_recorded_speed_drop_is_followed_and_removes_the_load_bias(run):
    """With the recorded u(t) the model follows the run and the load comes back; holding the run's
    mean speed, the same fit is biased well beyond it."""
    out, basis = _simulate(V, KN, Z_F, TRUE, run)
    y = np.column_stack([run.p, run.a_s, run.r])
    e = y - out
    e -= basis @ np.linalg.lstsq(basis, e, rcond=None)[0]
    assert np.all(np.sqrt((e**2).mean(axis=0)) < 0.01 * y.std(axis=0))
    m_u, z_u = _fit_load(run)
    m_c, z_c = _fit_load(dataclasses.replace(run, u=None))
    assert abs(m_u / TRUE.m - 1) < 0.02 and abs(z_u - TRUE.zbar) < 0.005  # measured: -0.5 %, -1.4 mm (Tustin at 50 Hz)
    assert abs(m_c / TRUE.m - 1) > 5 * abs(m_u / TRUE.m - 1) + 0.02  # measured: 0.212 kg, -0.451 m
