"""Diagnosis a user can trust (issue 13): per-run held-out evidence, stable refits, plausibility,
the exported model is the scored model, robust noise level, clear failure when the baseline
cannot be simulated."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from cli.app import _run
from diagnose.api import run
from diagnose.battery import scenario
from diagnose.model import fit_percent, noise_std, noise_std_coloured, prepare
from diagnose.model_file import load_model
from diagnose.recording import read_marin_dat, write_csv
from diagnose.report import to_text
from primitives.ship import DOFS, load_profile

DATA = Path(__file__).resolve().parents[1] / "diagnose" / "data"


@pytest.fixture(scope="module")
def ship():
    return load_profile("model-ship")


@pytest.fixture(scope="module")
def damping_case(damping_diagnosis):
    return damping_diagnosis


def test_per_run_table_in_text_and_json_and_no_nan(damping_case, tmp_path, capsys):
    sc, d = damping_case
    assert [f["effect"] for f in d.findings] == ["quadratic_damping"]
    assert len(d.per_run) == 1 and d.per_run[0]["role"] == "validation"
    row = d.per_run[0]
    assert row["after"]["yaw"] > row["before"]["yaw"] + 5
    text = to_text(d)
    assert "Per run (validation runs, simulated)" in text and "Pooled" in text
    assert "nan" not in text.lower()
    assert d.findings[0]["heldout_per_run"] and d.findings[0]["plausibility"]
    rec = write_csv(sc.diagnose[0], tmp_path / "run.csv")
    val = write_csv(sc.validate[0], tmp_path / "val.csv")
    assert (
        _run(["diagnose", str(rec), "--ship", "model-ship", "--validate", str(val), "--out", str(tmp_path / "o"), "--json"]) == 0
    )
    out = capsys.readouterr().out
    assert "NaN" not in out and "nan" not in out.lower()
    doc = json.loads(out)
    assert doc["per_run"][0]["run"].endswith("val.csv") and set(doc["per_run"][0]["after"]) == set(DOFS)


def test_exported_model_reproduces_the_reported_fit(damping_case, tmp_path):
    from diagnose.report import write_all

    _sc, d = damping_case
    paths = write_all(d, tmp_path)
    model, P = load_model(paths["model"])
    for row, p in zip(d.per_run, d.val_preps):
        fit = fit_percent(p.y, model.simulate(prepare(model.profile, p.rec), P)[0])
        np.testing.assert_allclose(fit, [row["after"][k] for k in DOFS], atol=1e-6)
    assert load_profile(paths["model"]).model_terms[2][-1] == "r*|r|"  # still a loadable profile


def test_implausible_current_is_rejected_and_said(ship):
    slow = dataclasses.replace(ship, cruise_speed_mps=0.1)  # the battery's 0.05 m/s current exceeds 35 % of 0.1 m/s
    sc = scenario(("current",), 12)
    d = run(sc.diagnose, slow, validate=sc.validate)
    assert "current" not in [f["effect"] for f in d.findings]
    assert any(r["effect"] == "current" and "implausible" in r["reason"] for r in d.rejected)
    assert "Rejected: current: implausible" in to_text(d)


def test_leave_one_run_out_without_validation_runs(ship):
    sc = scenario(("sensor_bias",), 42)
    d = run(sc.diagnose + sc.validate, ship)
    assert [f["effect"] for f in d.findings] == ["sensor_bias"]
    assert d.per_run_method.startswith("leave one run out") and len(d.per_run) == 2
    assert all(r["after"]["sway"] >= r["before"]["sway"] for r in d.per_run)


def test_noise_level_robust_to_coloured_noise():
    rng = np.random.default_rng(3)
    t = np.arange(4000)
    s = np.stack([np.sin(t / 60), 0.5 * np.sin(t / 37 + 1), 0.2 * np.cos(t / 90)], -1)
    e = np.zeros((4000, 3))
    w = rng.normal(size=(4000, 3))
    for k in range(1, 4000):
        e[k] = 0.8 * e[k - 1] + w[k]
    y = s + 0.02 * e / e.std(axis=0)
    assert np.all(noise_std(y) < 0.012)  # the white-noise estimate misses most of it
    np.testing.assert_allclose(noise_std_coloured(y), 0.02, rtol=0.25)
    white = s + rng.normal(0, 0.02, s.shape)
    np.testing.assert_allclose(noise_std_coloured(white), 0.02, rtol=0.15)


@pytest.mark.slow
def test_marin_every_validation_run_fits_at_least_as_well():
    p = load_profile("kvlcc2-linear")  # the deliberately linear baseline: something left to find
    rec = lambda n: read_marin_dat(DATA / f"MARIN_FREE_KVLCC2_{n}_m.dat")  # noqa: E731
    d = run([rec("tc_35"), rec("tc_-35")], p, fit_on=[rec("zz_10"), rec("zz_-10")], validate=[rec("zz_20"), rec("zz_-20")])
    assert len(d.per_run) == 2
    for row in d.per_run:
        for k in DOFS:
            assert row["after"][k] >= row["before"][k] - 0.01, row
    assert "nan" not in to_text(d).lower()


def test_baseline_that_cannot_be_simulated_exits_non_zero(tmp_path, capsys):
    sc = scenario((), 43, n_prims=2)
    rec = write_csv(sc.diagnose[0], tmp_path / "run.csv")
    theta = load_profile("model-ship").params("true")
    theta[0] = 0.5  # surge "damping" that feeds energy in: the simulation explodes
    bad = tmp_path / "unstable.json"
    bad.write_text(json.dumps({"theta": theta.tolist()}))
    rc = _run(["diagnose", str(rec), "--ship", "model-ship", "--params", str(bad)])
    err = capsys.readouterr().err
    assert rc == 2 and "cannot be simulated" in err and len(err.strip().splitlines()) == 1


def _sampled_run(ship, delay_s: float, seed: int, n: int = 1600):
    """A run whose inputs are samples of smooth signals and whose ship feels them ``delay_s``
    late: over step k it feels the mean of x over [t_k - D, t_k + Ts - D], i.e. x(t_k + Ts/2 - D)."""
    from diagnose.recording import Recording
    from primitives.simulate import Disturbances, simulate

    rng = np.random.default_rng(seed)
    ts = ship.sample_time
    f = rng.uniform(0.15, 0.4, 3)
    ph = rng.uniform(0, 2 * np.pi, 3)

    def x(t):
        t = np.asarray(t, float)[:, None]
        return np.array([4300.0, 0.0, 0.0]) + np.array([1300.0, 800.0, 340.0]) * np.sin(f * t + ph)

    t = np.arange(n + 1) * ts
    felt = x(t[:-1] + 0.5 * ts - delay_s)
    sim = simulate(
        ship,
        felt,
        nu0=(0.8, 0.0, 0.0),
        seed=seed,
        disturbances=Disturbances(measurement_std=(0.02, 0.02, 0.02), heading_std=0.002),
    )
    rec = x(t)
    return Recording(
        f"sampled-{seed}", t, sim.y[0], sim.psi_meas[0], sim.pos_meas[0], {nm: rec[:, j] for j, nm in enumerate(ship.inputs)}
    )


def test_fractional_delay_of_sampled_inputs_has_no_half_sample_bias(ship):
    delay = 0.3  # 2.4 samples of 0.125 s
    d = run([_sampled_run(ship, delay, 1)], ship, validate=[_sampled_run(ship, delay, 2)])
    f = next(f for f in d.findings if f["effect"] == "actuator_delay")
    assert f["parameters"]["half_sample_s"] == pytest.approx(0.0625)
    assert f["parameters"]["delay_s"] == pytest.approx(delay, abs=0.03)  # well inside half a sample (0.0625 s)
