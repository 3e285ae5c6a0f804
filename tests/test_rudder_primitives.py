"""Manoeuvres of rudder/propeller ships (kvlcc2 and user profiles) in helm terms, their
information and design, and the profile's [helm]/[engine] data."""

import json
import re
from functools import cache

import numpy as np
import pytest

from cli.app import _run
from expdesign.api import default_library, run_design
from primitives import helm as hm
from primitives.information import library_information, unidentified_parameters
from primitives.library import build_library
from primitives.ship import PROFILE_DIR, ProfileError, load_profile
from primitives.simulate import simulate

KVLCC2_TOML = (PROFILE_DIR / "kvlcc2.toml").read_text(encoding="utf-8")


@cache
def kv_lib():
    return build_library("kvlcc2")


def _prim(name):
    return next(p for p in kv_lib() if p.name == name)


def _heading_deg(p, k):
    return float(np.degrees(p.track[k, 2]))


def test_kvlcc2_library_has_the_issue_manoeuvres():
    names = {p.name for p in kv_lib()}
    assert {
        "zigzag_10_10_s",
        "zigzag_10_10_p",
        "zigzag_20_20_s",
        "zigzag_20_20_p",
        "turning_circle_35_s",
        "turning_circle_35_p",
        "pull_out_20_s",
        "direct_spiral",
        "acceleration",
        "deceleration",
        "stopping",
        "straight",
        "turn_s",
        "turn_p",
    } <= names
    assert sum(n.startswith("zz_exc_") for n in names) == 4
    assert "spot_turn_s" not in names  # a single-screw ship cannot turn on the spot


def test_zigzag_reverses_the_rudder_at_the_heading():
    for name, psi in (("zigzag_10_10_s", 10.0), ("zigzag_20_20_p", -20.0)):
        p = _prim(name)
        assert len(p.split_points) == 4
        for i, k in enumerate(p.split_points):  # the first sample at or past the switching heading
            target = psi * (-1) ** i
            assert np.sign(target) * _heading_deg(p, k) >= abs(target) > np.sign(target) * _heading_deg(p, k - 1), (name, i)
        # the rudder order at each reversal names the heading it waits for
        at = [o for o in p.orders if "at_heading_change_deg" in o.values]
        assert [round(o.t_s) for o in at] == [round(k * p.profile.sample_time) for k in p.split_points]


def test_starboard_rudder_turns_to_starboard_and_the_circle_closes():
    tc_s, tc_p = _prim("turning_circle_35_s"), _prim("turning_circle_35_p")
    assert tc_s.orders[1].values["rudder_deg"] == 35.0 and tc_s.orders[1].text.startswith("Hard a-starboard")
    assert _heading_deg(tc_s, -1) == pytest.approx(360.0, abs=3.0)
    assert _heading_deg(tc_p, -1) == pytest.approx(-360.0, abs=3.0)
    # kvlcc2's model turns to port for positive delta: the [helm] sign is consistent with it
    assert tc_s.profile.helm.starboard_sign == -1.0 and tc_s.inputs[-1, 0] < 0


def test_speed_changes_use_engine_steps_within_the_limits():
    acc, dec, stop = _prim("acceleration"), _prim("deceleration"), _prim("stopping")
    n0 = hm.steady_rps(acc.profile)
    assert acc.nu[-1, 0] > acc.nu[0, 0] + 2.0 and dec.nu[-1, 0] < dec.nu[0, 0] - 2.0
    assert acc.inputs[-1, 1] == pytest.approx(n0) and dec.inputs[-1, 1] == pytest.approx(0.5 * n0)
    # kvlcc2's engine has no astern (rps_limits from 0): stopping is engine stop and coasting
    assert stop.inputs[-1, 1] == 0.0 and "no astern" in stop.description
    assert stop.nu[-1, 0] == pytest.approx(0.5 * stop.profile.cruise_speed_mps, abs=0.05)


def test_steady_rps_holds_the_cruise_speed():
    prof = load_profile("kvlcc2")
    n0 = hm.steady_rps(prof)
    res = simulate(prof, np.tile([0.0, n0], (500, 1)), nu0=(prof.cruise_speed_mps, 0, 0))
    assert res.nu[0, -1, 0] == pytest.approx(prof.cruise_speed_mps, abs=1e-3)
    assert hm.steady_speed(prof, n0) == pytest.approx(prof.cruise_speed_mps, abs=1e-6)


def test_turns_steady_on_the_new_course():
    for name, dpsi in (("turn_s", 90.0), ("turn_p", -90.0)):
        p = _prim(name)
        assert _heading_deg(p, -1) == pytest.approx(dpsi, abs=2.0)
        texts = [o.text for o in p.orders]
        assert any("counter-rudder" in t for t in texts) and texts[-1].startswith("Midships")


def test_kvlcc2_information_is_full_rank_and_design_runs():
    prof = load_profile("kvlcc2")
    lib = [p for p in kv_lib() if p.kind == "informative"]
    infos = library_information(prof, lib)
    for ms in ("none", "batchwise"):
        gamma = sum(i.gamma(ms) for i in infos) / len(infos)
        assert np.linalg.matrix_rank(gamma) == len(prof.predictor_param_names)
        assert unidentified_parameters(prof, gamma) == []
    d = run_design(prof, lib, trial_length_s=6 * 3600)
    assert d.logdet > -np.inf and d.efficiency_vs_uniform > 1.0
    assert sum(d.rounded.values()) > 0 and set(d.rounded) <= {p.name for p in lib}


def _user_profile(tmp_path, text, name="ship.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _without_helm_engine(text):
    return re.sub(r"\[helm\].*?(?=\[model\])", "", text, flags=re.S)


def test_user_rudder_profile_without_helm_gets_defaults(tmp_path):
    prof = load_profile(
        _user_profile(tmp_path, _without_helm_engine(KVLCC2_TOML).replace('name = "kvlcc2"', 'name = "my-tanker"'))
    )
    assert prof.helm.rudder_rate_deg_s == 2.32 and prof.helm.max_rudder_deg == pytest.approx(35.0, abs=0.01)
    assert prof.helm.starboard_sign == -1.0  # derived from the model's yaw response
    assert prof.engine.rps_limits == (0.0, 2.0)
    assert default_library(prof)[0].name == "zigzag_10_10_s"  # the design's dictionary


@pytest.mark.parametrize(
    "edit, field",
    [
        (lambda t: t.replace("max_rudder_deg = 35.0", "max_rudder_deg = 40.0"), "helm.max_rudder_deg"),
        (lambda t: t.replace("rudder_rate_deg_s = 2.32", "rudder_rate_deg_s = -1"), "helm.rudder_rate_deg_s"),
        (lambda t: t.replace("rps_limits = [0.0, 2.0]", "rps_limits = [0.0, 3.0]"), "engine.rps_limits"),
        (lambda t: t.replace("approach_rpm = 91.4", 'approach_rpm = "fast"'), "engine.approach_rpm"),
        (lambda t: t.replace("starboard_sign = -1", "starboard_sign = 2"), "helm.starboard_sign"),
        (lambda t: t.replace("rps_limits = [0.0, 2.0]", "rps_limits = [2.0, 1.0]"), "engine.rps_limits"),
        (lambda t: t.replace('inputs = ["delta", "n"]', 'inputs = ["n", "delta"]'), "inputs"),
    ],
)
def test_bad_helm_engine_fields_name_the_field(tmp_path, edit, field):
    path = _user_profile(tmp_path, edit(KVLCC2_TOML))
    with pytest.raises(ProfileError, match=re.escape(field)) as exc:
        load_profile(path)
    assert str(path) in str(exc.value) and "\n" not in str(exc.value)


def test_unreachable_cruise_speed_is_a_profile_error(tmp_path):
    prof = load_profile(_user_profile(tmp_path, KVLCC2_TOML.replace("cruise_speed_mps = 7.97", "cruise_speed_mps = 12.0")))
    with pytest.raises(ProfileError, match="cannot hold 12.00 m/s within the engine's 120 rpm"):
        build_library(prof)


def test_cli_primitives_for_kvlcc2_and_a_bad_profile(tmp_path, capsys):
    assert _run(["primitives", "--ship", "kvlcc2", "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    tc = rows["turning_circle_35_s"]
    assert tc["orders"][1]["text"].startswith("Hard a-starboard") and tc["orders"][1]["rudder_deg"] == 35.0
    assert tc["abort_criteria"].startswith("abort if speed")
    bad = _user_profile(tmp_path, KVLCC2_TOML.replace("cruise_speed_mps = 7.97", "cruise_speed_mps = 12.0"))
    assert _run(["primitives", "--ship", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "12.00 m/s" in err and "Traceback" not in err


def test_engine_rate_and_mcr_shape_the_engine_orders(tmp_path):
    text = KVLCC2_TOML.replace("approach_rpm = 91.4", "approach_rpm = 91.4\nrps_rate = 0.005\nmcr_rpm = 120.0")
    prof = load_profile(_user_profile(tmp_path, text))
    n0 = hm.steady_rps(prof)
    gen = hm.speed_change(prof, 0.5 * n0, n0)
    shaft = gen.inputs[:, 1]
    assert np.abs(np.diff(shaft)).max() <= 0.005 * prof.sample_time + 1e-12  # the shaft follows at the engine rate
    assert shaft[-1] == pytest.approx(n0)
    from primitives.orders import inputs_from_orders

    np.testing.assert_allclose(inputs_from_orders(prof, gen.orders, len(shaft)), gen.inputs, atol=1e-12)
    execute = [o for o in gen.orders if "execute" in o.text][0]
    assert "% MCR" in execute.text and execute.values["mcr_pct"] == pytest.approx(100 * (60 * n0 / 120.0) ** 3)
