"""Ship profiles, the batch simulator and the regressors (issue 2)."""

import json

import numpy as np
import pytest

from primitives.profile_document import profile_from_dict
from primitives.regressors import instruments, predictor_regressors
from primitives.ship import PROFILE_DIR, ProfileError, builtin_profiles, load_profile
from primitives.simulate import Disturbances, simulate
from primitives.steady_forces import steady_forces, steady_forces_many


@pytest.fixture(scope="module")
def ms():
    return load_profile("model-ship")


def test_model_ship_one_step_by_hand(ms):
    # (9.1) with Table 9.1 "true": u=0.5, v=0.1, r=0.2, tau=(1000, 200, 50), no current.
    u, v, r = 0.5, 0.1, 0.2
    res = simulate(ms, np.array([[1000.0, 200.0, 50.0]]), nu0=(u, v, r))
    u1 = u - 0.06 * u + 0.08 * v * r - 0.01 * u * abs(u) + 1.4e-5 * 1000
    v1 = v - 0.1 * v - 0.006 * u * r + 1.4e-5 * 200
    r1 = r - 0.35 * r - 0.03 * u * v + 3e-4 * 50
    np.testing.assert_allclose(res.nu[0, 1], [u1, v1, r1], rtol=1e-12)


def test_kinematics_euler(ms):
    # eta(k+1) = eta(k) + Ts R(psi) nu: from psi = 30 deg, u = 1, v = 0.5 (no forces).
    psi = np.radians(30)
    res = simulate(ms, np.zeros((1, 3)), nu0=(1.0, 0.5, 0.1), eta0=(10.0, -5.0, psi))
    ts = ms.sample_time
    np.testing.assert_allclose(
        res.eta[0, 1],
        [10 + ts * (np.cos(psi) - 0.5 * np.sin(psi)), -5 + ts * (np.sin(psi) + 0.5 * np.cos(psi)), psi + ts * 0.1],
    )


def test_current_enters_through_relative_velocities(ms):
    # An unpowered ship in a current drifts with it: its velocity over ground tends to the
    # current, seen in the body frame through the heading (BRIEF section 2).
    psi = np.radians(60)
    cur = np.array([0.3, -0.2])  # flowing north 0.3, east -0.2
    res = simulate(ms, np.zeros((400, 3)), eta0=(0, 0, psi), disturbances=Disturbances(current_ne=tuple(cur)))
    # the transient yaws the ship a little (N_uv u_r v_r), so rotate with the final heading
    pf = res.eta[0, -1, 2]
    np.testing.assert_allclose(
        res.nu[0, -1, :2], [np.cos(pf) * cur[0] + np.sin(pf) * cur[1], -np.sin(pf) * cur[0] + np.cos(pf) * cur[1]], atol=1e-6
    )
    uc = np.cos(psi) * cur[0] + np.sin(psi) * cur[1]
    # and the ground track follows the current direction
    d = res.eta[0, -1, :2] - res.eta[0, -200, :2]
    assert np.degrees(np.arctan2(d[1], d[0])) == pytest.approx(np.degrees(np.arctan2(cur[1], cur[0])), abs=0.5)
    # one step by hand with relative velocities
    r1 = simulate(
        ms, np.array([[0.0, 0.0, 0.0]]), nu0=(1.0, 0.0, 0.0), eta0=(0, 0, psi), disturbances=Disturbances(current_ne=tuple(cur))
    )
    ur = 1.0 - uc
    assert r1.nu[0, 1, 0] == pytest.approx(1.0 - 0.06 * ur - 0.01 * ur * abs(ur))


def test_batch_is_reproducible_and_independent(ms):
    dist = Disturbances.from_profile(ms)
    a = simulate(ms, np.ones((50, 3)) * 100, disturbances=dist, batch=8, seed=3)
    b = simulate(ms, np.ones((50, 3)) * 100, disturbances=dist, batch=8, seed=3)
    c = simulate(ms, np.ones((50, 3)) * 100, disturbances=dist, batch=8, seed=4)
    np.testing.assert_array_equal(a.y, b.y)
    assert not np.allclose(a.y, c.y)
    assert not np.allclose(a.nu[0], a.nu[1])  # realisations differ


def test_full_scale_thrusters_and_steady_state():
    fs = load_profile("full-scale")
    assert len(fs.param_names) == 18
    # (3.55): both thrusters at pi/5, n = 10 -> tau_x = 20 cos(pi/5), tau_n = 0
    sig = fs.generalized_forces(np.array([10.0, np.pi / 5, 10.0, np.pi / 5]))
    assert sig["tau_x"] == pytest.approx(20 * np.cos(np.pi / 5))
    assert sig["tau_n"] == pytest.approx(0.0, abs=1e-12)
    # allocation is the inverse of (3.55)
    inp = fs.allocate(10.0, 3.0, 20.0)
    sig = fs.generalized_forces(inp[0])
    assert (sig["tau_x"], sig["tau_y"], sig["tau_n"]) == pytest.approx((10.0, 3.0, 20.0))
    # holding the steady forces keeps the state
    f = steady_forces(fs, 3.0, 0.2, 0.01)
    res = simulate(fs, fs.allocate(*f).repeat(5, axis=0), nu0=(3.0, 0.2, 0.01))
    np.testing.assert_allclose(res.nu[0, -1], [3.0, 0.2, 0.01], atol=1e-9)


def test_instruments_are_noise_free_regressors(ms):
    inputs = np.tile([3000.0, 300.0, 100.0], (200, 1))
    res = simulate(ms, inputs, "nominal")
    z = instruments(ms, inputs)  # nominal set by default
    phi, target = predictor_regressors(ms, res.nu[0], inputs, res.eta[0, :, 2])
    np.testing.assert_allclose(z, phi)
    # the regressors explain the increments exactly with the simulating parameters
    theta = ms.params("nominal")
    for i in range(3):
        s = ms.predictor.dof_slice(i)
        np.testing.assert_allclose(phi[:, s] @ theta[s], target[:, i], atol=1e-12)


def test_profile_files_roundtrip_and_errors(tmp_path, ms):
    p = tmp_path / "ship.json"
    p.write_text(json.dumps(ms.to_dict()))
    again = load_profile(p)
    np.testing.assert_array_equal(again.params("true"), ms.params("true"))
    bad = ms.to_dict()
    bad["parameters"]["true"]["sway"] = [1.0, 2.0]
    with pytest.raises(ProfileError, match=r"parameters\.true\.sway"):
        profile_from_dict(bad, "ship.json")
    bad = ms.to_dict()
    del bad["sample_time"]
    with pytest.raises(ProfileError, match="sample_time"):
        profile_from_dict(bad, "ship.json")
    bad = ms.to_dict()
    bad["model"]["yaw"] = ["r", "u_r*w_q", "tau_n"]
    with pytest.raises(ProfileError, match="unknown signals"):
        profile_from_dict(bad, "ship.json")
    t = tmp_path / "ship.toml"
    t.write_text("name = 'x'\nsample_time = [")
    with pytest.raises(ProfileError, match="not valid TOML"):
        load_profile(t)
    with pytest.raises(ProfileError, match="unknown ship"):
        load_profile("no-such-ship")


def _with_line(text: str, header: str, line: str, nth: int = 1) -> str:
    """The TOML ``text`` with ``line`` added as the first key of the ``nth`` table ``header``
    ("" for the top level)."""
    if not header:
        return line + "\n" + text
    at = -1
    for _ in range(nth):
        at = text.index(header + "\n", at + 1)
    at += len(header) + 1
    return text[:at] + line + "\n" + text[at:]


# (bundled profile, table header, its n-th occurrence, a key no model reads, the table the message names)
STRAY_KEYS = [
    ("naval-vessel", "[rigid_body]", 1, "yaw_moment = 1.0", "[rigid_body]"),
    ("naval-vessel", "[[pods]]", 2, "w = 0.0", "[[pods]] number 2"),
    ("naval-vessel", "[pod_model]", 1, "c_rx3 = 0.0", "[pod_model]"),
    ("kvlcc2", "[helm]", 1, "rudder_rate = 3.0", "[helm]"),
    ("kvlcc2", "[engine]", 1, "max_rpm = 90.0", "[engine]"),
    ("model-ship", "[model]", 1, 'yaww = ["r"]', "[model]"),
    ("model-ship", "[parameters.true]", 1, "roll = [0.1]", "[parameters.true]"),
    ("model-ship", "[input_limits]", 1, "delta = [-0.6, 0.6]", "[input_limits]"),
    ("model-ship", "[disturbances]", 1, "wind_std = 0.1", "[disturbances]"),
    ("full-scale", "[[thrusters]]", 1, "z = 1.0", "[[thrusters]] number 1"),
    ("full-scale", "[predictor_names]", 1, 'heave = ["Z"]', "[predictor_names]"),
    ("model-ship", "", 1, "yaw_moment = 1.0", "the top level"),
    ("kvlcc2", "[diagnosis]", 1, "structure_priors = 0.5", "[diagnosis]"),
]


@pytest.mark.parametrize("ship,header,nth,line,table", STRAY_KEYS, ids=[f"{c[0]}-{c[4]}" for c in STRAY_KEYS])
def test_cli_refuses_a_stray_key_in_any_profile_table(ship, header, nth, line, table, tmp_path, capsys):
    """`shiptrial primitives --ship FILE.toml` with a key no model reads: exit 2 and one line
    naming the file, the table, the key and the keys the table accepts (before: silently ignored
    in every table but the top level, [disturbances] and the 4-DOF numeric tables, and there
    [rigid_body] let yaw_moment through)."""
    from cli.app import _run

    key = line.split(" = ")[0]
    path = tmp_path / "ship.toml"
    path.write_text(_with_line((PROFILE_DIR / f"{ship}.toml").read_text(), header, line, nth))
    assert _run(["primitives", "--ship", str(path)]) == 2
    out = capsys.readouterr()
    assert out.out == ""
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in out.err
    assert lines[0].startswith(f"error: {path}: unknown key '{key}' in {table}")
    assert "accepted keys: " in lines[0]


def test_cli_stray_key_exit_code_from_the_installed_command(tmp_path):
    """The same refusal from a fresh process: exit status 2, one line on stderr, no traceback."""
    import subprocess
    import sys

    text = _with_line((PROFILE_DIR / "naval-vessel.toml").read_text(), "[rigid_body]", "yaw_moment = 1.0")
    path = tmp_path / "stray.toml"
    path.write_text(text)
    proc = subprocess.run(
        [sys.executable, "-c", "from cli.app import main; main()", "primitives", "--ship", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip() == (
        f"error: {path}: unknown key 'yaw_moment' in [rigid_body]; accepted keys: mass, I_x, "
        "I_z, x_g, z_g, X_udot, Y_vdot, Y_pdot, Y_rdot, K_vdot, K_pdot, N_vdot, N_rdot"
    )


def test_every_bundled_profile_loads():
    for name in builtin_profiles():
        assert load_profile(name).name


# (bundled profile, its actuator, a whole table only another actuator's ships read, the table as named)
FOREIGN_TABLES = [
    ("full-scale", "azimuth", "[helm]\nmax_rudder_deg = 35.0", "[helm]", "rudder_propeller"),
    ("model-ship", "generalized", "[engine]\nrps_limits = [0.0, 2.0]", "[engine]", "rudder_propeller"),
    ("full-scale", "azimuth", "[engine]\nrps_limits = [0.0, 2.0]", "[engine]", "rudder_propeller"),
    ("kvlcc2", "rudder_propeller", "[[pods]]\nx = -100.0\ny = 0.0\nz = 5.0", "[[pods]]", "pods"),
    ("model-ship", "generalized", "[pod_model]\nrho = 1025.0", "[pod_model]", "pods"),
    ("kvlcc2", "rudder_propeller", "[[thrusters]]\nx = -100.0", "[[thrusters]]", "azimuth"),
]


@pytest.mark.parametrize("ship,actuator,table_text,table,reader", FOREIGN_TABLES, ids=[f"{c[0]}-{c[3]}" for c in FOREIGN_TABLES])
def test_cli_refuses_a_table_the_ships_actuator_does_not_read(ship, actuator, table_text, table, reader, tmp_path, capsys):
    """A whole [helm] or [engine] table in an azimuth or generalized-force profile (or [[pods]],
    [pod_model], [[thrusters]] in another ship's) is read by no model: exit 2 and one line naming
    the file, the table and the fix (before: silently ignored)."""
    from cli.app import _run

    path = tmp_path / "ship.toml"
    path.write_text((PROFILE_DIR / f"{ship}.toml").read_text() + "\n" + table_text + "\n")
    assert _run(["primitives", "--ship", str(path)]) == 2
    out = capsys.readouterr()
    lines = out.err.strip().splitlines()
    assert out.out == "" and len(lines) == 1 and "Traceback" not in out.err
    assert lines[0].startswith(f"error: {path}: table {table} is read only in an actuator = '{reader}' profile")
    assert f"actuator is '{actuator}': remove {table}" in lines[0]


def test_an_empty_foreign_table_is_no_error(ms):
    """An empty table says nothing a model could ignore: a JSON profile with "thrusters": [] loads."""
    again = profile_from_dict(ms.to_dict() | {"thrusters": [], "helm": {}}, "ship.json")
    assert again.actuator == "generalized" and again.thrusters == ()


@pytest.mark.parametrize("name", ["model-ship", "full-scale"])
def test_steady_forces_of_many_states_are_each_states_own(name):
    """The batched solve (the Monte Carlo's validation input: a thousand states) gives every state
    the numbers of a call for it alone, and those forces hold it steady."""
    p = load_profile(name)
    rng = np.random.default_rng(3)
    c = p.cruise_speed_mps
    u, v, r = c * rng.uniform(0.3, 1.2, 50), 0.1 * c * rng.normal(size=50), 0.3 * c / p.length_m * rng.normal(size=50)
    many = steady_forces_many(p, u, v, r)
    assert np.array_equal(many, [steady_forces(p, *s) for s in zip(u, v, r)])
    inputs = p.allocate(many[:, 0], many[:, 1], many[:, 2])
    nu = np.column_stack([u, v, r])
    sim = simulate(p, inputs[:, None, :], nu0=nu, batch=50)
    assert np.allclose(sim.nu[:, 1], nu, rtol=1e-9, atol=1e-12)
