"""The MMG battery table's interval coverage (benchmarks/mmg_battery_table.py): a miss, an ERROR
row, a missing std and a spurious finding are counted, never dropped (issue 26 review)."""

from __future__ import annotations

from benchmarks.mmg_battery_table import coverage, table

TRUTH = {"scale": "full", "checks": {"thrust_loss": {"loss_percent": [20.0, 5.0, "abs"]}}}


def _row(case: str, findings, error=None, truth=TRUTH) -> dict:
    return {"case": case, "truth": truth, "findings": findings, "error": error, "hit": False, "diagnose_s": 1.0, "cpu_s": 1.0}


def _loss(value: float, std: float | None) -> dict:
    return {"effect": "thrust_loss", "dof": "surge", "parameters": {"loss_percent": value, "loss_percent_std": std}}


def test_misses_errors_missing_stds_and_spurious_findings_are_not_covered():
    bias = {"effect": "sensor_bias", "dof": "yaw", "parameters": {"signal": "r", "bias": -6e-5, "bias_std": 2.7e-5}}
    assert coverage(_row("a-seed1", [_loss(19.0, 1.0)])) == {"in": 1}
    assert coverage(_row("a-seed2", [_loss(25.0, 1.0)])) == {"out": 1}
    assert coverage(_row("a-seed3", [bias])) == {"no estimate": 1, "spurious out": 1}  # the wrong effect named
    assert coverage(_row("a-seed4", [_loss(19.0, None)])) == {"no std": 1}
    assert coverage(_row("a-seed5", None, error="boom")) == {"error": 1}
    control = {"scale": "full", "checks": {}}
    assert coverage(_row("c-seed1", [bias], truth=control)) == {"spurious out": 1}
    assert coverage(_row("c-seed2", [], truth=control)) == {}


def test_the_table_prints_the_counts_next_to_the_ratio():
    rows = [_row("a-seed1", [_loss(19.0, 1.0)]), _row("a-seed2", None, error="boom"), _row("a-seed3", [])]
    text = table(rows)
    assert "1/3 (33 %; in 1, no estimate 1, error 1)" in text


def test_rescore_recomputes_each_half_width_from_its_recorded_parts():
    """A stored row's half-width, run under another quantile rule, is replaced by this code's from
    the parts bench_diagnose_mmg recorded beside it; a finding without parts is counted and left."""
    from benchmarks.mmg_battery_table import rescore
    from diagnose.uncertainty import half_width_95

    parts = {"noise": 1.0, "model": 0.0, "within": 2.0, "reference": 0.0, "heldout": 0.1, "n_runs": 3, "n_heldout": 2}
    f = _loss(19.0, 2.3)
    f["parameters"] |= {"loss_percent_std_95": 9.9, "loss_percent_std_parts": parts}
    old = _loss(19.0, 2.3)
    old["parameters"]["loss_percent_std_95"] = 9.9
    assert rescore([_row("a-seed1", [f, old])]) == 1
    assert f["parameters"]["loss_percent_std_95"] == half_width_95(**parts) != 9.9
    assert old["parameters"]["loss_percent_std_95"] == 9.9
