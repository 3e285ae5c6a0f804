"""The diagnosis on physics it did not generate (issue 13): cases of the MMG KVLCC2 battery that
`shiptrial diagnose` gets right (as last measured with benchmarks/bench_diagnose_mmg.py) must
stay right. The full battery, with the misses, is the benchmark's job."""

from __future__ import annotations

import pytest

from benchmarks.bench_diagnose_mmg import run_case, score

# right on the diagnosis of commit 04f2682 (python -m benchmarks.bench_diagnose_mmg: 3/18, these two and the plain control)
STAYS_RIGHT = ("control-ar1", "shallow-water")


@pytest.mark.slow
@pytest.mark.parametrize("name", STAYS_RIGHT)
def test_battery_case_stays_right(name, tmp_path):
    r = run_case(name, tmp_path, use_cli=False)
    assert r["hit"], (r["claimed"], r["why"])


def test_scoring_names_every_miss():
    truth = {"effects": ["current"], "checks": {"current": {"speed_mps": [0.7, 0.3, "rel"], "toward_deg": [60.0, 25.0, "angle"]}}}
    right = {"findings": [{"effect": "current", "parameters": {"speed_mps": 0.75, "toward_deg": 80.0}}],
             "per_run": [{"run": "a", "before": {"surge": 50.0}, "after": {"surge": 60.0}}]}
    assert score(truth, right) == (True, [])
    wrong = {"findings": [{"effect": "current", "parameters": {"speed_mps": 1.2, "toward_deg": 100.0}},
                          {"effect": "actuator_delay", "parameters": {"delay_s": 10.8}}],
             "per_run": [{"run": "a", "before": {"surge": 50.0}, "after": {"surge": 40.0}}], "fit_after": {"yaw": float("nan")}}
    hit, why = score(truth, wrong)
    assert not hit and len(why) == 5, why  # extra effect, speed, direction, a worse held-out run, NaN
    assert score({"effects": [], "checks": {}}, {"error": "RecordingError: x"})[0] is False
