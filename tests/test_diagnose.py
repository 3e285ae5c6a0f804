"""Diagnosis of concealed effects: names the right physics, estimates it, improves held-out fit,
and stays silent on the control (issue 6). The full battery is marked slow."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cli.app import _run
from diagnose.api import run
from diagnose.battery import EFFECTS, battery, check, full_scale_battery, hit_rate, scenario
from diagnose.locate import alarm_windows, cusum, ljung_box
from diagnose.recording import Recording, write_csv
from diagnose.report import to_text
from primitives.ship import load_profile


@pytest.fixture(scope="module")
def ship():
    return load_profile("model-ship")


def test_control_gets_no_finding_and_the_model_explains_the_data(ship):
    sc = scenario((), 11)
    d = run(sc.diagnose, ship, validate=sc.validate)
    assert d.findings == []
    assert "explains the data" in to_text(d)
    assert d.fit_after == d.fit_before


@pytest.mark.parametrize("effects", [("current",), ("actuator_delay",), ("sensor_bias",), ("quadratic_damping",)])
def test_single_concealed_effect_is_named_estimated_and_improves_validation(ship, effects):
    sc = scenario(effects, 12)
    d = run(sc.diagnose, ship, validate=sc.validate)
    hit, why = check(effects, d.findings, d.fit_before, d.fit_after)
    assert hit, why
    f = d.findings[0]
    assert f["p_value"] < 1e-6 and f["evidence"]
    assert d.fit_on == "validation"


def test_current_parameters_and_plain_language(ship):
    sc = scenario(("current",), 13)
    d = run(sc.diagnose, ship, validate=sc.validate)
    f = d.findings[0]
    assert f["effect"] == "current"
    assert f["parameters"]["speed_mps"] == pytest.approx(np.hypot(*EFFECTS["current"]["current_ne"]), rel=0.3)
    assert abs(f["parameters"]["toward_deg"] - 315.0) < 25.0
    text = to_text(d)
    assert "current of" in text and "toward" in text and "validation" in text


def test_two_combined_effects_are_both_named(ship):
    effects = ("input_offset", "quadratic_damping")
    sc = scenario(effects, 14)
    d = run(sc.diagnose, ship, validate=sc.validate)
    hit, why = check(effects, d.findings, d.fit_before, d.fit_after)
    assert hit, why


def test_current_cannot_be_tested_on_a_straight_run(ship):
    sc = scenario(("current",), 15)
    rec = sc.diagnose[0]
    n = 400
    straight = Recording(
        "straight", rec.t[:n], rec.y[:n], np.zeros(n), rec.pos[:n], {k: np.tile(v[:1], n) for k, v in rec.channels.items()}
    )
    straight.y[:, 1:] = np.random.default_rng(0).normal(0, 0.02, (n, 2))
    straight.channels["tau_x"][:] = 4000.0
    d = run([straight], ship)
    assert "current" not in {f["effect"] for f in d.findings}
    reasons = {u["effect"]: u["reason"] for u in d.untestable}
    assert "current" in reasons and "heading" in reasons["current"]
    assert "cannot be tested: current" in to_text(d).lower()


def test_cusum_alarms_on_a_step_and_not_on_noise():
    rng = np.random.default_rng(1)
    eps = rng.normal(0, 1.0, 1000)
    g0 = cusum(eps, 1.5, 0.2)
    assert alarm_windows(g0, 10.0) == []
    eps[600:700] += 3.0
    win = alarm_windows(cusum(eps, 1.5, 0.2), 10.0)
    assert len(win) >= 1 and 560 <= win[0][0] <= 640


def test_ljung_box_separates_white_from_coloured():
    rng = np.random.default_rng(2)
    e = rng.normal(size=2000)
    ar = np.copy(e)
    for k in range(1, len(ar)):
        ar[k] = 0.7 * ar[k - 1] + e[k]
    assert ljung_box(e)[1] > 0.01
    assert ljung_box(ar)[1] < 1e-6


def test_cli_json_and_model_file(tmp_path, capsys):
    sc = scenario(("quadratic_damping",), 16)
    rec = write_csv(sc.diagnose[0], tmp_path / "run.csv", meta={"ship": "model-ship"})
    val = write_csv(sc.validate[0], tmp_path / "val.csv")
    out = tmp_path / "out"
    rc = _run(["diagnose", str(rec), "--ship", "model-ship", "--validate", str(val), "--out", str(out), "--json"])
    assert rc == 0
    doc = json.loads(capsys.readouterr().out)
    for key in ("findings", "fit_before", "fit_after", "model"):
        assert key in doc
    f = doc["findings"][0]
    assert f["effect"] == "quadratic_damping" and f["dof"] == "yaw"
    assert f["parameters"]["term"] == "r*|r|" and f["parameters"]["value"] == pytest.approx(-0.25, rel=0.4)
    assert "p_value" in f and f["evidence"]
    assert doc["fit_after"]["yaw"] > doc["fit_before"]["yaw"] + 5
    refit = load_profile(doc["model"])  # the written model is a loadable profile with the new term
    assert "r*|r|" in refit.model_terms[2]
    assert (out / "residuals_diagnosed_1.png").stat().st_size > 1000
    assert (out / "residuals_validation_1.png").stat().st_size > 1000
    assert "quadratic_damping" in (out / "report.txt").read_text()


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--ship", "no-such-ship"], "unknown ship"),
        (["--ship", "full-scale"], "n1"),
    ],
)
def test_cli_bad_input_exit_2_one_line(tmp_path, capsys, args, needle):
    sc = scenario((), 17, n_prims=2)
    rec = write_csv(sc.diagnose[0], tmp_path / "run.csv")
    rc = _run(["diagnose", str(rec), *args])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert needle in err and len(err.splitlines()) == 1


def test_cli_missing_file_exit_2(tmp_path, capsys):
    rc = _run(["diagnose", str(tmp_path / "nope.csv"), "--ship", "model-ship"])
    assert rc == 2
    assert "nope.csv" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("ship,cases", [("model-ship", battery((1, 2, 3))), ("full-scale", full_scale_battery((1, 2, 3)))])
def test_full_battery_hit_rate(ship, cases):
    out = hit_rate(cases, ship=ship)
    misses = [(r["case"], r["seed"], r["why"]) for r in out["rows"] if not r["hit"]]
    assert out["hit_rate"] >= 0.9, misses
    controls = [r for r in out["rows"] if r["case"].endswith(":control")]
    assert controls and all(r["named"] == [] for r in controls)


def test_fit_on_refits_a_crude_baseline_then_names_the_current(ship):
    ctrl = scenario((), 21)
    sc = scenario(("current",), 22)
    d = run(sc.diagnose, ship, theta=ship.params("nominal"), fit_on=ctrl.diagnose + ctrl.validate, validate=sc.validate)
    np.testing.assert_allclose(d.theta, ship.params("true"), rtol=0.2, atol=2e-6)
    assert [f["effect"] for f in d.findings] == ["current"]
    assert d.fit_after["sway"] > d.fit_before["sway"] + 5


def test_cli_params_file_and_bad_params(tmp_path, capsys):
    sc = scenario((), 23, n_prims=3)
    rec = write_csv(sc.diagnose[0], tmp_path / "run.csv")
    good = tmp_path / "theta.json"
    good.write_text(json.dumps({"theta": ship_true()}))
    assert (
        _run(["diagnose", str(rec), "--ship", "model-ship", "--params", str(good), "--out", str(tmp_path / "o"), "--json"]) == 0
    )
    doc = json.loads(capsys.readouterr().out)
    assert doc["findings"] == [] and doc["explained"] is True
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"theta": [1.0, 2.0]}))
    assert _run(["diagnose", str(rec), "--ship", "model-ship", "--params", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and "theta" in err


def ship_true() -> list[float]:
    return load_profile("model-ship").params("true").tolist()


def test_full_scale_thruster_misalignment_and_untestable_thrust_loss():
    fs = load_profile("full-scale")
    sc = scenario(("input_offset",), 31, profile=fs)
    d = run(sc.diagnose, fs, validate=sc.validate)
    assert [f["effect"] for f in d.findings] == ["input_offset"]
    p = d.findings[0]["parameters"]
    assert p["input"] == "alpha2" and p["offset"] == pytest.approx(0.05, rel=0.35)
    assert "offset_deg" in p
    assert any(u["effect"] == "thrust_loss" and "u_r*tau_x" in u["reason"] for u in d.untestable)
