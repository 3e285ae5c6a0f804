"""The basin truth family (tests/physics/basin_truth.py) against the mass estimator's model.

Without its structural effects the truth is the estimator's sway-roll-yaw model (so the
simulator is right); each variant moves it measurably away from that model."""

from __future__ import annotations

import numpy as np
import pytest

from identify.rollmass.model import Known, Load
from identify.rollmass.output_error import _simulate
from identify.rollmass.simulate import RollRecording
from tests.physics import basin_truth as bt

LOAD = (0.4, -0.268)
N = 1200


def _oe_values(sh: bt.Ship, j: int) -> dict[str, float]:
    """The truth's nominal-structure parameters in the estimator's parameterisation."""
    s = sh.U0[j] / bt.U_REF
    m33 = sh.Iz[j] - sh.Nrd[j]
    zg = -(bt.KG - bt.DRAFT) + sh.z_f[j]
    return dict(
        X_v=-sh.Yvd[j],
        Y_v=sh.Yv[j] * s,
        Y_r=sh.Yr[j] * s,
        Y_delta=sh.Yd[j] * s * s,
        A_x=sh.Ix[j] - sh.Kpd[j],
        d=-sh.Kp[j],
        k=bt.M0 * bt.G * (bt.GM0 - zg),
        K_vdot=sh.Kvd[j],
        K_ur=sh.Kr[j] * s / sh.U0[j],
        K_delta=sh.Kd[j] * s * s,
        n_v=sh.Nv[j] * s / m33,
        n_r=sh.Nr[j] * s / m33,
        n_delta=sh.Nd[j] * s * s / m33,
    )


def _mismatch(variant: str, mount: bool = False) -> np.ndarray:
    """Relative RMS misfit (p, a_s, r) of the estimator's model at the truth's nominal-structure
    parameters, noise and waves off, over two runs (worst of the two); ``mount``: the estimator told
    the IMU's x position and given the gyros' pitch misalignment (its ``e_y``)."""
    sh = bt.draw_ships(2, variant, 5)
    out = bt.simulate(sh, variant, LOAD, N, 11, quiet=True)
    worst = np.zeros(3)
    for j in range(2):
        kn = Known(M=bt.M0, zbar_g=-(bt.KG - bt.DRAFT), zbar_s=sh.z_imu[j], U=sh.U0[j], xbar_s=sh.x_imu[j] if mount else 0.0)
        values = {**_oe_values(sh, j), "e_y": sh.eps[j, 1] if mount else 0.0}
        rec = RollRecording("x", 0.02, out["delta"][j], out["p"][j], out["a_s"][j], out["r"][j])
        yhat, _ = _simulate(values, kn, sh.z_f[j], Load(*LOAD), rec)
        Y = np.column_stack([rec.p, rec.a_s, rec.r])[200:]
        e = (Y - Y.mean(0)) - (yhat[200:] - yhat[200:].mean(0))
        worst = np.maximum(worst, np.sqrt((e**2).mean(0)) / Y.std(0))
    return worst


@pytest.fixture(scope="module")
def base_mismatch() -> np.ndarray:
    return _mismatch("base")


def test_base_structure_is_the_estimators_model(base_mismatch):
    # what is left is the IMU's own low-pass and the Tustin vs RK4 discretisation (measured 6/4/3 %)
    assert np.all(base_mismatch < 0.09)


@pytest.mark.parametrize("variant", ["sway_roll", "restoring", "imu_mount", "speed_loss", "combined"])
def test_variant_moves_away_from_the_estimators_model(variant, base_mismatch):
    # measured worst channel: sway_roll 0.28 (a_s), restoring 0.099 (p: its non-wall-sided box and cubic
    # GZ), imu_mount 0.093 (p), speed_loss 0.54 (a_s), against 0.068 / 0.054 / 0.025 (p / a_s / r) for
    # the base structure. imu_mount is measured against the model without the IMU mounting: the oe
    # estimator now has the truth's x_s r' and gyro pitch e_y (the next test), so against the model it
    # fits imu_mount differs only by the surge acceleration the yaw misalignment leaks into a_s and is
    # no longer a structure the estimator lacks (its figures are not independent evidence)
    assert np.max(_mismatch(variant) - base_mismatch) > 0.015


def test_the_estimators_imu_mount_model_takes_the_truths_mounting(base_mismatch):
    """With the IMU's x position (header imu_x_m) and the gyros' pitch misalignment e_y the estimator's
    model follows the imu_mount variant as closely as the base structure (the yaw rate leaking into a
    roll gyro pitched by 1 deg is 2 % of the roll rate's signal at a 0.2 rad/s turn)."""
    assert np.max(_mismatch("imu_mount", mount=True) - base_mismatch) < 0.005


def _free_response_misfit(lag: float) -> np.ndarray:
    """Relative RMS misfit (p, a_s, r) of the estimator's model with IMU lag ``t_imu = lag`` at the
    base truth's parameters, noise and waves off, after projecting out each channel's free response
    and bias as the estimator does (what the fit can see), worst of two runs."""
    sh = bt.draw_ships(2, "base", 5)
    out = bt.simulate(sh, "base", LOAD, N, 11, quiet=True)
    worst = np.zeros(3)
    for j in range(2):
        kn = Known(M=bt.M0, zbar_g=-(bt.KG - bt.DRAFT), zbar_s=sh.z_imu[j], U=sh.U0[j])
        rec = RollRecording("x", 0.02, out["delta"][j], out["p"][j], out["a_s"][j], out["r"][j])
        yhat, basis = _simulate({**_oe_values(sh, j), "t_imu": lag}, kn, sh.z_f[j], Load(*LOAD), rec)
        Y = np.column_stack([rec.p, rec.a_s, rec.r])
        Q, _ = np.linalg.qr(basis)
        e = (Y - yhat) - Q @ (Q.T @ (Y - yhat))
        worst = np.maximum(worst, np.sqrt((e**2).mean(0)) / Y.std(0))
    return worst


def test_the_estimators_imu_lag_takes_the_truths_sensor_low_pass():
    """The truth's IMU low-pass (2nd-order Butterworth, 30 Hz at 100 Hz) delays the IMU channels
    against the rudder by its group delay, 5.1 ms below 5 Hz. The estimator's IMU lag ``t_imu`` at
    that value takes it (measured worst channel p: 0.0119 -> 0.0047, which is what is left with the
    truth's low-pass switched off, and r: 0.0039 -> 0.00004). Noise-free, that lag alone had biased
    the oe load by +5 % / +10 mm in cases 1 and 3 (base, run 0)."""
    none, lagged = _free_response_misfit(0.0), _free_response_misfit(0.0051)
    assert np.all(lagged < 0.5 * none)
    assert lagged[2] < 0.05 * none[2]


def test_a_loads_buoyancy_acts_at_the_waterline_not_at_the_roll_centre():
    """Ships with different roll centres have the same restoring with the same load (the hydrostatics
    do not know where the ship rolls about): the load's weight at its height less the added layer's
    buoyancy half its sinkage above the waterline. The paper's (3), buoyancy at the roll centre, biased
    an estimator with the hydrostatics by m g z_f."""
    sh = bt.draw_ships(6, "base", 1)
    assert np.ptp(sh.z_f) > 0.005
    m, zm = LOAD
    C, cubic = bt._restoring(sh, m, zm, ())
    C0, _ = bt._restoring(sh, 0.0, 0.0, ())
    sink = m / (bt.RHO * 0.9 * bt.LWL * bt.BEAM)
    np.testing.assert_allclose(C - C0, m * bt.G * (zm + sink / 2), rtol=1e-12)
    assert not cubic.any()


def test_waves_variant_has_another_spectrum():
    """JONSWAP plus a slow drift: 4-6 % of the sway force's power below 0.2 Hz (measured), where the
    reflected-wave model (a resonance at 1-1.4 Hz) puts 0.03 %."""
    rng = np.random.default_rng(0)
    sh = bt.draw_ships(3, "waves", 1)
    n = 6000

    def low_share(x: np.ndarray) -> float:
        P = np.abs(np.fft.rfft(x - x.mean())) ** 2
        f = np.fft.rfftfreq(len(x), 1 / bt.FS)
        return float(P[f < 0.2].sum() / P.sum())

    nb = bt._narrowband(n, rng, 3)
    js = bt._jonswap(n, sh, rng)
    assert max(low_share(nb[j, :, 0]) for j in range(3)) < 0.005
    assert min(low_share(js[j, :, 0]) for j in range(3)) > 0.02


def test_runs_are_reproducible_and_differ_between_runs():
    a = bt.simulate_runs("restoring", 2, 3, length=0.1)[1]["nominal-1"]["p"]
    b = bt.simulate_runs("restoring", 2, 3, length=0.1)[1]["nominal-1"]["p"]
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a[0], a[1])


def test_the_ahrs_roll_angle_carries_an_mti_g_level_error_and_nothing_else_changes(monkeypatch):
    """The recorded ``phi`` is the AHRS's: the true heel plus a per-recording error at the MTi-G's
    level (static 0.5 deg, so a constant of a few tenths of a degree and a slower drift), drawn from a stream of
    its own (every other channel bit for bit as without it); none with ``quiet``."""
    ship, with_err = bt.simulate_runs("base", 6, 11, length=0.5)
    monkeypatch.setattr(bt, "_ahrs_error", lambda R, n, s: np.zeros((R, n)))
    _, without = bt.simulate_runs("base", 6, 11, length=0.5)
    offsets = []
    for name in bt.DATASETS:
        for k in ("delta", "p", "a_s", "r", "u"):
            np.testing.assert_array_equal(with_err[name][k], without[name][k])
        e = np.rad2deg(with_err[name]["phi"] - without[name]["phi"])
        offsets += list(e.mean(axis=1))
        assert np.all(e.std(axis=1) < 0.5) and np.all(e.std(axis=1) > 0.005)
    assert 0.15 < np.std(offsets) < 0.8 and len(set(np.round(offsets, 6))) == len(offsets)
    _, q1 = bt.simulate_runs("base", 2, 11, length=0.2, quiet=True)
    monkeypatch.undo()
    _, q2 = bt.simulate_runs("base", 2, 11, length=0.2, quiet=True)
    np.testing.assert_array_equal(q1["nominal-1"]["phi"], q2["nominal-1"]["phi"])
