"""The test-side MMG KVLCC2 (tests/physics): the yardstick the diagnosis is judged by (issue 13)
must itself be right - steady speed, turning, Froude scaling, and the concealed effects of the
battery present with the size the ground truth says."""

from __future__ import annotations

import numpy as np
import pytest

from tests.physics import mmg_battery as bat
from tests.physics.mmg_kvlcc2 import MODEL_SCALE, Environment, kvlcc2, self_propulsion_rps, with_effects
from tests.physics.mmg_sim import Manoeuvre, simulate_runs, straight_speed, tactical_diameter

FULL = kvlcc2(1.0)
N0 = self_propulsion_rps(FULL)


def test_straight_run_at_the_approach_rps_holds_the_approach_speed():
    run = simulate_runs(FULL, [Manoeuvre("straight", duration_s=200)], N0, lead_in_s=0.0, pre_s=0.0)[0]
    assert np.allclose(run.u, 7.97, atol=1e-6)
    assert np.max(np.abs(run.v)) < 1e-9 and np.max(np.abs(run.r)) < 1e-12
    assert 1.6 < N0 < 1.9  # rev/s at full scale (MARIN ran 1.53 with a skin-friction correction we do not model)


def test_35_deg_turning_circle_has_the_published_tactical_diameter_on_both_sides():
    runs = simulate_runs(
        FULL, [Manoeuvre("turn", 35, 0, 1, 560), Manoeuvre("turn", 35, 0, -1, 560)], N0, lead_in_s=0.0, pre_s=0.0
    )
    td = [tactical_diameter(r) / FULL.L for r in runs]
    assert all(2.9 < x < 3.4 for x in td), td  # MARIN free-running: 3.07 and 3.33 L
    assert runs[0].r[-1] > 0 > runs[1].r[-1]  # positive MMG rudder turns to starboard
    assert runs[0].delta[-1] < 0  # ... which the recordings write as negative (MARIN convention)


def test_model_scale_run_is_the_froude_scaled_full_scale_run():
    man = [Manoeuvre("zigzag", 10, 10, 1, 250)]
    f = simulate_runs(FULL, man, N0, lead_in_s=20.0, pre_s=10.0)[0]
    model = kvlcc2(MODEL_SCALE)
    m = simulate_runs(model, man, self_propulsion_rps(model), lead_in_s=20.0, pre_s=10.0)[0]
    sq = np.sqrt(MODEL_SCALE)
    assert np.allclose(m.t * sq, f.t, rtol=1e-9)
    assert np.allclose(m.x * MODEL_SCALE, f.x, rtol=1e-7, atol=1e-6)
    assert np.allclose(m.u * sq, f.u, rtol=1e-7)
    assert np.allclose(m.r / sq, f.r, rtol=1e-6, atol=1e-12)
    assert np.allclose(m.psi, f.psi, atol=1e-9) and np.allclose(m.delta, f.delta)


def test_rk4_step_is_converged():
    import tests.physics.mmg_sim as sim

    man = [Manoeuvre("turn", 35, 0, 1, 150)]
    coarse = simulate_runs(FULL, man, N0, lead_in_s=0.0, pre_s=0.0)[0]
    old = sim.SUBSTEPS
    try:
        sim.SUBSTEPS = 4 * old
        fine = simulate_runs(FULL, man, N0, lead_in_s=0.0, pre_s=0.0)[0]
    finally:
        sim.SUBSTEPS = old
    assert np.max(np.abs(coarse.psi - fine.psi)) < 2e-3  # rad, after a 150 s turn
    assert np.max(np.abs(coarse.u - fine.u)) < 2e-3


def test_current_shifts_the_track_by_the_drift_and_the_velocity_over_ground():
    man = [Manoeuvre("turn", 35, 0, 1, 200)]
    cur = (0.35, -0.6)
    # exact for the hull in water only: the still air drags the superstructure at the velocity
    # over ground, which the current changes
    from dataclasses import replace

    wet_only = replace(FULL, A_F=0.0, A_L=0.0)
    calm = simulate_runs(wet_only, man, N0, lead_in_s=0.0, pre_s=0.0)[0]
    wet = simulate_runs(wet_only, man, N0, env=Environment(current_ne=cur), lead_in_s=0.0, pre_s=0.0)[0]
    assert np.allclose(wet.x - calm.x, cur[0] * wet.t, atol=1e-6)
    assert np.allclose(wet.y - calm.y, cur[1] * wet.t, atol=1e-6)
    c, s = np.cos(wet.psi), np.sin(wet.psi)
    assert np.allclose(wet.u - calm.u, c * cur[0] + s * cur[1], atol=1e-9)
    assert np.allclose(wet.v - calm.v, -s * cur[0] + c * cur[1], atol=1e-9)


def test_actuator_delay_shifts_the_response_and_offset_and_thrust_loss_show_on_the_approach():
    man = [Manoeuvre("turn", 35, 0, 1, 150)]
    base = simulate_runs(FULL, man, N0, lead_in_s=10.0, pre_s=10.0)[0]
    late = simulate_runs(FULL, man, N0, lead_in_s=10.0, pre_s=10.0, delay_s=3.0)[0]
    assert np.allclose(late.r[3:], base.r[:-3], atol=1e-12) and np.allclose(late.delta, base.delta)
    off = simulate_runs(FULL, [Manoeuvre("zigzag", 10, 10, 1, 120)], N0, offset_rad=np.radians(1.5), lead_in_s=600.0, pre_s=20.0)[
        0
    ]
    assert np.degrees(np.mean(off.delta[:20])) == pytest.approx(1.5, abs=0.05)  # helm holds the course against it
    assert np.degrees(off.delta.min()) == pytest.approx(-10.0) and np.degrees(off.delta.max()) == pytest.approx(10.0)
    slow = with_effects(FULL, thrust_factor=0.8)
    assert straight_speed(slow, N0) < 7.97 - 0.3


@pytest.fixture(scope="module")
def short_battery():
    """The battery's runs shortened (the generator is otherwise the real one)."""
    saved = bat.CALM, bat.DIAGNOSE, bat.VALIDATE, bat.LEAD_IN_S
    bat.LEAD_IN_S = 60.0
    bat.CALM = [Manoeuvre("zigzag", 15, 15, 1, 120)]
    bat.DIAGNOSE = [Manoeuvre("zigzag", 10, 10, 1, 120)]
    bat.VALIDATE = [Manoeuvre("zigzag", 10, 10, -1, 120)]
    yield bat
    bat.CALM, bat.DIAGNOSE, bat.VALIDATE, bat.LEAD_IN_S = saved


def test_battery_is_reproducible_per_seed_and_writes_the_recording_format(short_battery, tmp_path):
    from dataclasses import replace

    from diagnose.recording import load_recording

    c = replace(bat.case("wind-18"), noise="ar1")
    a, b = bat.generate(c), bat.generate(c)
    other = bat.generate(replace(c, seed=c.seed + 1))
    for k in ("u", "r", "psi"):
        assert np.array_equal(a.noisy["diagnose"][0][k], b.noisy["diagnose"][0][k])
        assert not np.array_equal(a.noisy["diagnose"][0][k], other.noisy["diagnose"][0][k])
    noise = a.noisy["diagnose"][0]["u"] - a.diagnose[0].u
    assert np.corrcoef(noise[1:], noise[:-1])[0, 1] > 0.7  # coloured (AR(1), 0.9)
    paths = bat.write_case(a, tmp_path)
    rec = load_recording(paths["diagnose"][0])[0]
    assert rec.meta["ship"] == "kvlcc2" and rec.meta["scale"] == "full" and rec.sample_time == pytest.approx(1.0)
    assert rec.meta["wind_reference"] == "true" and rec.meta["rudder_sign"] == "starboard-positive"
    # the anemometer reads the wind through the ship's flow (bat.flow_distortion): its noise-free
    # reading, not the 18 m/s blowing, plus 0.3 m/s noise
    reading = bat._anemometer(a.diagnose[0], bat._setup(c)[2].wind_ne, relative=False)
    n = rec.n_samples
    assert np.mean(rec.channels["wind_speed"]) == pytest.approx(np.mean(reading[0][:n]), abs=0.05)
    assert abs(np.mean(reading[0]) - 18.0) > 0.3  # the flow distortion is in it
    assert np.degrees(np.median(rec.channels["wind_dir"])) == pytest.approx(45.0, abs=4.0)
    np.testing.assert_allclose(rec.channels["delta"], a.diagnose[0].delta_mmg)  # MMG's convention, as written
    assert set(a.truth["checks"]["wind"]["wind"][0]) == {"wind_accel_surge", "wind_accel_sway", "wind_accel_yaw"}


def test_battery_effects_have_the_size_the_truth_says(short_battery, tmp_path):
    g = bat.generate(bat.case("model-current-0.6"))
    t = g.truth["checks"]["current"]
    assert t["speed_mps"][0] == pytest.approx(0.6 / np.sqrt(MODEL_SCALE))
    r = g.diagnose[0]
    cn, ce = (t["speed_mps"][0] * f(np.radians(300.0)) for f in (np.cos, np.sin))
    c, s = np.cos(r.psi), np.sin(r.psi)
    xd = np.gradient(r.x, r.t)
    assert np.allclose(xd, c * r.u - s * r.v, atol=2e-3)  # u, v are body-frame velocities over ground
    calm_u = straight_speed(kvlcc2(MODEL_SCALE), self_propulsion_rps(kvlcc2(MODEL_SCALE)))
    assert r.u[0] == pytest.approx(calm_u + c[0] * cn + s[0] * ce, abs=2e-3)  # drift before the manoeuvre
    paths = bat.write_case(g, tmp_path)
    text = paths["diagnose"][0].read_text().splitlines()[:6]
    assert "# scale: model" in text and "# scale_factor: 45.7" in text
    bias = bat.generate(bat.case("gyro-bias"))
    d = bias.noisy["diagnose"][0]["r"] - bias.diagnose[0].r
    assert np.mean(d) == pytest.approx(5e-4, abs=4 * 2e-4 / np.sqrt(len(d)))


def test_still_air_drags_the_hull_in_calm_water_and_the_wind_truth_is_the_excess(short_battery):
    """A calm-water run is in still air, not in no air: the superstructure is dragged through it at
    the ship's own speed (Fossen (10.8): relative wind = -ship velocity), as on a real ship's
    trials; the MMG hull resistance (captive tank tests) holds none of it. A baseline fitted on the
    calm runs holds that drag, so the battery's wind truth is the load beyond it."""
    from dataclasses import replace

    from tests.physics.mmg_kvlcc2 import RHO_AIR, _wind_curves, derivative, wind_forces

    Minv = np.linalg.inv(FULL.mass_matrix())
    s = np.array([0.0, 0.0, 0.3, 7.97, 0.0, 0.0])
    still = derivative(FULL, Minv, s, 0.0, N0, Environment())[3]
    airless = derivative(replace(FULL, A_F=0.0), Minv, s, 0.0, N0, Environment())[3]
    drag = -0.5 * RHO_AIR * 7.97**2 * FULL.A_F * _wind_curves(FULL)[0, 0]  # N, Isherwood's C_X(0) = -1.02: about 45 kN
    assert still == pytest.approx(0.0, abs=1e-9)  # the self-propulsion rpm balances it
    assert airless - still == pytest.approx(drag * Minv[0, 0], rel=1e-9)
    assert np.array_equal(
        derivative(FULL, Minv, s, 0.0, N0, Environment(wind_ne=(0.0, 0.0))), derivative(FULL, Minv, s, 0.0, N0, Environment())
    )
    # the truth of a wind case: the mean acceleration of the excess loads (zero for still air),
    # from the truth's own loads and mass matrix alone (no estimator code)
    runs = simulate_runs(FULL, bat.DIAGNOSE, N0, lead_in_s=60.0)
    assert all(c == 0.0 for c in bat._wind_truth(FULL, runs, (0.0, 0.0))["coefficients"].values())
    head = bat._wind_truth(FULL, runs, (-15.0, 0.0))["coefficients"]  # 15 m/s from ahead
    acc = []
    for r in runs:
        wn, we = r.wind_ne((-15.0, 0.0))
        f = np.stack(wind_forces(FULL, r.u, r.v, r.psi, np.stack([wn, we])), -1)
        f0 = np.stack(wind_forces(FULL, r.u, r.v, r.psi, np.zeros(2)), -1)
        acc.append(((f - f0) @ Minv.T)[:-1])
    mean = np.concatenate(acc).mean(axis=0)
    assert [head[k] for k in ("wind_accel_surge", "wind_accel_sway", "wind_accel_yaw")] == pytest.approx(mean.tolist())
    # a head wind pushes the ship astern: the excess surge load of 15 m/s from ahead at ~8 m/s,
    # about -1.02 q A_F (Isherwood's C_X(0)) less the still air's, over the surge mass
    q = 0.5 * RHO_AIR * ((7.97 + 15.0) ** 2 - 7.97**2) * FULL.A_F
    assert head["wind_accel_surge"] == pytest.approx(-1.02 * q * Minv[0, 0], rel=0.2)


def test_gusty_wind_is_recorded_as_the_anemometer_reads_it(short_battery, tmp_path):
    """The gusty wind case (issue 26): the wind speed varies with the gusts (15 % turbulence) and
    the anemometer records it; the relative-wind variant, read back, is the same true wind."""
    from diagnose.recording import load_recording

    g = bat.generate(bat.case("wind-18-gusty"))
    gain = g.diagnose[0].wind_gain
    assert gain is not None and 0.05 < np.std(gain) < 0.3 and abs(np.mean(gain) - 1.0) < 0.2
    rel = bat.generate(bat.case("wind-18-gusty-relative"))
    np.testing.assert_array_equal(rel.diagnose[0].wind_gain, gain)  # the same gusts, seeded
    paths = bat.write_case(rel, tmp_path)
    rec = load_recording(paths["diagnose"][0])[0]
    assert rec.meta["wind_reference"] == "true" and any("relative wind" in n for n in rec.notes)
    turn = g.diagnose[0].wind_turn  # direction gusts (0.8 of the speed's intensity, rad)
    assert turn is not None and 0.04 < np.std(turn) < 0.3
    # the relative record read back is the true record the ship's wind system would have written
    spd, frm = bat._anemometer(rel.diagnose[0], bat._setup(bat.case("wind-18-gusty"))[2].wind_ne, relative=False)
    n = rec.n_samples
    assert np.sqrt(np.mean((rec.channels["wind_speed"] - spd[:n]) ** 2)) < 0.6  # anemometer noise 0.3 m/s, u/v noise
    err = (np.degrees(rec.channels["wind_dir"] - frm[:n]) + 180.0) % 360.0 - 180.0
    assert abs(np.median(err)) < 1.0
