"""The 4-DOF podded naval vessel of seed 000 in the shared kernel: the digest's simulation checks
(section 2.4 of notes/seed000.md) and the profile's validation."""

import tomllib

import numpy as np
import pytest

from identify.yawid.experiment import turn_pulse
from primitives.pods import pod_body_forces
from primitives.profile_document import profile_from_dict
from primitives.ship import PROFILE_DIR, ProfileError, load_profile
from primitives.simulate import simulate


@pytest.fixture(scope="module")
def nv():
    return load_profile("naval-vessel")


@pytest.fixture(scope="module")
def turn(nv):
    return simulate(nv, turn_pulse(nv.sample_time))


def test_pod_force_at_rest_and_fig_2_4_envelope(nv):
    """Fig. 2.4 at n = 60 rev/s ("3600 s^-1" read as 3600 rpm), v = 0, sigma = 0."""
    pod = nv.pods[0]
    fx, fy = pod_body_forces(nv.pod_model, pod, 60.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert fx == pytest.approx(5.56e4, rel=2e-3) and fy == 0.0
    delta = np.radians(np.linspace(-90, 90, 361))
    fx, fy = pod_body_forces(nv.pod_model, pod, 60.0, delta, 10.0, 0.0, 0.0, 0.0)
    # at u = 10 the thrust at delta = 0 is 5.18e4 N (the J term); 5.56e4 N is the u = 0 value above
    assert fx.min() == pytest.approx(-3.11e5, rel=5e-3) and fx.max() == pytest.approx(5.18e4, rel=5e-3)
    assert fy.max() == pytest.approx(1.98e5, rel=5e-3) and abs(np.degrees(delta[np.argmax(fy)]) - 49) <= 1.0
    # at rest the side force is largest with the pod across (thruster), at speed near 45 deg (rudder)
    _, fy0 = pod_body_forces(nv.pod_model, pod, 60.0, delta, 0.0, 0.0, 0.0, 0.0)
    assert abs(np.degrees(delta[np.argmax(fy0)])) == pytest.approx(90.0)


def test_surge_at_n80_reaches_9_69_not_the_thesis_8_6(nv, turn):
    """Both pods at n = 80 rev/s from rest: 9.69 m/s at 50 s from Appendix A and Table 2.1; the
    thesis's 8.6 m/s (L952-953) does not follow from its own parameters."""
    u50 = turn.nu[0, int(round(50 / nv.sample_time)), 0]
    assert u50 == pytest.approx(9.69, abs=0.01)
    assert abs(u50 - 8.6) > 1.0
    assert turn.nu.shape[-1] == 4 and turn.eta.shape[-1] == 4  # (u, v, r, p), (x, y, psi, phi)


def test_minus_10_deg_turn(turn):
    """A low-pass filtered -10 deg pod pulse at ~9.7 m/s: r ~ 0.035 rad/s, roll ~ 6.3 deg, v ~ 0.9 m/s."""
    r, v, phi = turn.nu[0, :, 2], turn.nu[0, :, 1], turn.eta[0, :, 3]
    assert np.abs(r).max() == pytest.approx(0.035, rel=0.03)
    assert np.degrees(np.abs(phi).max()) == pytest.approx(6.3, abs=0.2)
    assert np.abs(v).max() == pytest.approx(0.9, abs=0.05)
    assert r.max() > 0.03  # pods to port (-10 deg) push the stern to port: the ship turns to starboard


def test_euler_step_matches_a_fine_step_and_roll_period():
    doc = tomllib.loads((PROFILE_DIR / "naval-vessel.toml").read_text())
    out = {}
    for ts in (0.1, 0.02):
        prof = profile_from_dict(doc | {"sample_time": ts})
        res = simulate(prof, turn_pulse(ts))
        out[ts] = (np.abs(res.nu[0, :, 2]).max(), np.abs(res.eta[0, :, 3]).max())
    np.testing.assert_allclose(out[0.1], out[0.02], rtol=0.01)
    prof = load_profile("naval-vessel")
    res = simulate(prof, np.zeros((600, 4)), eta0=(0.0, 0.0, 0.0, 0.1))  # free roll decay from 0.1 rad
    phi = res.eta[0, :, 3]
    crossings = res.t[1:][(phi[:-1] > 0) & (phi[1:] <= 0)]
    assert 7.0 < np.median(np.diff(crossings)) < 7.8  # 2 pi sqrt(4.174e6 / 2.734e6) = 7.8 s without coupling
    assert abs(phi[-1]) < 0.02  # damped


def test_roll_needs_a_rigid_body_and_roll_signals_need_roll():
    doc = tomllib.loads((PROFILE_DIR / "naval-vessel.toml").read_text())
    with pytest.raises(ProfileError, match="rigid_body"):
        profile_from_dict({k: v for k, v in doc.items() if k != "rigid_body"}, "x.toml")
    planar = tomllib.loads((PROFILE_DIR / "model-ship.toml").read_text())
    planar["model"]["yaw"] = planar["model"]["yaw"][:-1] + ["phi"]
    with pytest.raises(ProfileError, match="roll DOF"):
        profile_from_dict(planar, "y.toml")
    bad = doc | {"inputs": ["n1", "delta1"]}
    with pytest.raises(ProfileError, match="inputs"):
        profile_from_dict(bad, "z.toml")
    pm = dict(doc["pod_model"])
    del pm["c_ry"]
    with pytest.raises(ProfileError, match="pod_model.c_ry"):
        profile_from_dict(doc | {"pod_model": pm}, "w.toml")


def test_profile_round_trips_through_its_dict(nv):
    again = profile_from_dict(nv.to_dict(), "roundtrip")
    assert again.pods == nv.pods and again.pod_model == nv.pod_model and again.dofs == nv.dofs
    np.testing.assert_array_equal(again.rigid_body.mass_matrix, nv.rigid_body.mass_matrix)
    np.testing.assert_array_equal(again.params(), nv.params())


def test_planar_commands_refuse_the_podded_ship(nv):
    assert not nv.planar and load_profile("model-ship").planar
    with pytest.raises(ProfileError, match="supports 3-DOF ships only"):
        nv.require_planar("shiptrial design")
