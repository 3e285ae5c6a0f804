"""The diagnosis on physics it did not generate (issue 13): cases of the MMG KVLCC2 battery that
`shiptrial diagnose` gets right (as last measured with benchmarks/bench_diagnose_mmg.py) must
stay right. The full battery, with the misses, is the benchmark's job."""

from __future__ import annotations

import pytest

from benchmarks.bench_diagnose_mmg import run_case, score

# right with the kvlcc2 baseline fitted on the delivery-trial calm runs (python -m
# benchmarks.bench_diagnose_mmg --ship kvlcc2: 13/18 on branch issue-13s, 15/18 after the issue-13p
# merge, 16/18 on issue-13b with still air in the calm runs; also delay-2.5, delay-4, gyro-bias,
# current-0.5-ar1, model-current-0.6, wind-18, the thrust losses, model-wind-15): the controls claim nothing (no finding too
# small to matter), a current without a sensor bias beside it, the offsets at their size
STAYS_RIGHT = ("control-ar1", "shallow-water", "control", "model-control", "current-0.7", "offset-1.5", "model-offset-1")


@pytest.mark.slow
@pytest.mark.parametrize("name", STAYS_RIGHT)
def test_battery_case_stays_right(name, tmp_path):
    r = run_case(name, tmp_path, use_cli=False, ship="kvlcc2")
    assert r["hit"], (r["claimed"], r["why"])


def test_scoring_names_every_miss():
    truth = {"effects": ["current"], "checks": {"current": {"speed_mps": [0.7, 0.3, "rel"], "toward_deg": [60.0, 25.0, "angle"]}}}
    right = {
        "findings": [{"effect": "current", "parameters": {"speed_mps": 0.75, "toward_deg": 80.0}}],
        "per_run": [{"run": "a", "before": {"surge": 50.0}, "after": {"surge": 60.0}}],
    }
    assert score(truth, right) == (True, [])
    wrong = {
        "findings": [
            {"effect": "current", "parameters": {"speed_mps": 1.2, "toward_deg": 100.0}},
            {"effect": "actuator_delay", "parameters": {"delay_s": 10.8}},
        ],
        "per_run": [{"run": "a", "before": {"surge": 50.0}, "after": {"surge": 40.0}}],
        "fit_after": {"yaw": float("nan")},
    }
    hit, why = score(truth, wrong)
    assert not hit and len(why) == 5, why  # extra effect, speed, direction, a worse held-out run, NaN
    assert score({"effects": [], "checks": {}}, {"error": "RecordingError: x"})[0] is False


def test_model_scale_truth_is_judged_at_full_scale():
    """The findings of a model-scale case are full scale (the recordings are Froude-scaled to the
    ship): the truth is converted before scoring, so a right full-scale answer is a hit."""
    from benchmarks.bench_diagnose_mmg import full_scale_truth
    from tests.physics.mmg_battery import case, truth_of
    from tests.physics.mmg_kvlcc2 import Environment, kvlcc2

    c = case("model-current-0.6")
    ship = kvlcc2(c.scale)
    t = truth_of(c, ship, [], Environment(), ship.time_scale)
    assert t["checks"]["current"]["speed_mps"][0] < 0.1  # stated at model scale
    full = full_scale_truth(t)["checks"]["current"]
    assert abs(full["speed_mps"][0] - 0.6) < 1e-9 and full["toward_deg"][0] == 300.0
    good = {"findings": [{"effect": "current", "parameters": {"speed_mps": 0.62, "toward_deg": 310.0}}]}
    assert score(t, good) == (True, [])
    assert not score(t, {"findings": [{"effect": "current", "parameters": {"speed_mps": 0.089, "toward_deg": 300.0}}]})[0]
    c = case("model-delay-3")
    d = full_scale_truth(truth_of(c, ship, [], Environment(), ship.time_scale))["checks"]["actuator_delay"]["delay_s"]
    assert abs(d[0] - 3.0) < 1e-9 and abs(d[1] - 0.3) < 1e-9  # value and absolute tolerance
    assert (
        full_scale_truth(truth_of(case("current-0.7"), kvlcc2(1.0), [], Environment(), 1.0))["checks"]["current"]["speed_mps"][0]
        == 0.7
    )


def test_wind_truth_froude_powers():
    """The wind's mean accelerations of a model-scale run, converted, equal those of the
    Froude-similar full-scale run (checks the powers of the conversion, not just its form)."""
    from types import SimpleNamespace

    import numpy as np

    from benchmarks.bench_diagnose_mmg import full_scale_truth
    from tests.physics.mmg_battery import MODEL_SCALE, _wind_truth
    from tests.physics.mmg_kvlcc2 import kvlcc2

    k = np.arange(200.0)
    u, v, psi = 7.5 - 0.01 * k, 0.3 * np.sin(k / 20), 0.02 * k
    wind = np.array([-10.0, 6.0])
    s = np.sqrt(MODEL_SCALE)

    def run(scale: float):  # a steady wind: the mean at every sample
        return SimpleNamespace(
            u=u / scale, v=v / scale, r=0 * u, psi=psi, wind_ne=lambda w: (np.full(200, w[0]), np.full(200, w[1]))
        )

    full = _wind_truth(kvlcc2(1.0), [run(1.0)], wind)["coefficients"]
    model = _wind_truth(kvlcc2(MODEL_SCALE), [run(s)], wind / s)["coefficients"]
    truth = {"scale": "model", "scale_factor": MODEL_SCALE, "checks": {"wind": {"wind": [model, 0.4, "wind"]}}}
    conv = full_scale_truth(truth)["checks"]["wind"]["wind"][0]
    for key in full:
        assert abs(conv[key] / full[key] - 1.0) < 1e-6, (key, conv[key], full[key])


@pytest.mark.slow
def test_delay_is_named_without_validation_runs(tmp_path):
    """Leave one run out (no --validate): the linearised held-out verdict of a 4 s steering delay,
    a Gauss-Newton step from zero, made the left-out turning circle 80 % worse, so the delay was
    never refitted and a yaw inertia change was named instead. The linearised verdict now only
    orders the candidates; the refitted model is judged on the left-out runs from the refit."""
    from diagnose.api import run
    from diagnose.recording import load_recording
    from diagnose.recording_checks import conform
    from primitives.ship import load_profile
    from tests.physics.mmg_battery import case, generate, write_case

    prof = load_profile("kvlcc2")
    paths = write_case(generate(case("delay-4")), tmp_path / "delay-4")

    def load(ps):
        return conform([r for p in ps for r in load_recording(p)], prof)

    d = run(load(paths["diagnose"]), prof, fit_on=load(paths["calm"]))
    assert [f["effect"] for f in d.findings] == ["actuator_delay"], (d.findings, d.rejected)
    assert abs(d.findings[0]["parameters"]["delay_s"] - 4.0) < 0.3
    assert all(r["after"][ch] >= r["before"][ch] - 1.0 for r in d.per_run for ch in r["before"]), d.per_run


def _model_delay_estimate(seed: int, tmp: str) -> float:
    """Battery case model-delay-3 with noise seed ``seed`` diagnosed: the delay found (full scale s)."""
    from dataclasses import replace
    from pathlib import Path

    from diagnose.api import run
    from diagnose.recording import load_recording
    from diagnose.recording_checks import conform
    from primitives.ship import load_profile
    from tests.physics.mmg_battery import case, generate, write_case

    prof = load_profile("kvlcc2")
    g = generate(replace(case("model-delay-3"), seed=seed), visibility=False)
    paths = write_case(g, Path(tmp) / f"seed{seed}")
    recs = {role: conform([r for p in ps for r in load_recording(p)], prof) for role, ps in paths.items()}
    d = run(recs["diagnose"], prof, fit_on=recs["calm"], validate=recs["validate"])
    f = next(f for f in d.findings if f["effect"] == "actuator_delay")
    return f["parameters"]["delay_s"]  # full scale: the recordings are Froude-scaled to the ship


@pytest.mark.slow
def test_model_scale_delay_estimate_spread_over_noise_seeds(tmp_path):
    """The 3 s steering delay at model scale under AR(1) noise (battery case model-delay-3),
    noise seeds 1-4: the estimates scatter with a std under 0.13 s and none is off by more
    than the 0.3 s tolerance. With the search's channel weights (2 % of each signal's spread,
    not its noise) they scattered 0.186 s (2.77-3.20 s; seeds 1-14: 0.160 s, seed 7 2.56 s);
    refitted by Kallstrom's maximum-likelihood criterion (diagnose.magnitude) 0.072 s
    (2.82-2.99 s; seeds 1-14: 0.120 s). Four seeds, two at a time, keep the slow step inside CI's time."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    import numpy as np

    seeds = [1, 2, 3, 4]
    with ProcessPoolExecutor(max_workers=2, mp_context=mp.get_context("spawn")) as pool:
        est = np.array(list(pool.map(_model_delay_estimate, seeds, [str(tmp_path)] * len(seeds))))
    assert np.std(est, ddof=1) < 0.13, est
    assert np.max(np.abs(est - 3.0)) <= 0.3, est
