"""``shiptrial design``: JSON keys, report files and user errors."""

from __future__ import annotations

import json

from cli.app import _run


def test_design_json_keys_and_files(tmp_path, capsys):
    out = tmp_path / "rep"
    rc = _run(["design", "--ship", "model-ship", "--monte-carlo", "12", "--seed", "1", "--out", str(out), "--json"])
    assert rc == 0
    doc = json.loads(capsys.readouterr().out)
    for key in ("weights", "logdet", "efficiency_vs_uniform", "efficiency_bound", "rounded", "monte_carlo"):
        assert key in doc
    assert abs(sum(doc["weights"].values()) - 1) < 1e-9
    assert set(doc["rounded"]) == set(doc["weights"])
    for name in ("optimized", "random", "uniform"):
        s = doc["monte_carlo"][name]
        for key in ("param_rmse_p50", "frac_param_rmse_below_1_5", "sim_rmse_p50", "frac_sim_rmse_below_0_15"):
            assert key in s
    assert doc["mean_subtraction"] == "complete"
    assert json.loads((out / "design.json").read_text()) == doc
    md = (out / "report.md").read_text()
    assert "## Monte Carlo evaluation" in md and "tau6" in md
    for f in ("ratios.png", "mc_param_rmse.png", "mc_sim_rmse_dof.png", "mc_sim_rmse_norm.png"):
        assert (out / f).stat().st_size > 1000


def test_design_without_monte_carlo(tmp_path, capsys):
    rc = _run(
        ["design", "--monte-carlo", "0", "--criterion", "A", "--mean-subtraction", "batchwise", "--out", str(tmp_path), "--json"]
    )
    assert rc == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["monte_carlo"] is None and doc["criterion"] == "A"
    assert not (tmp_path / "mc_param_rmse.png").exists()


def test_infeasible_constraints_exit_2(tmp_path, capsys):
    rc = _run(["design", "--monte-carlo", "0", "--min-frac", "0.2", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.startswith("error: infeasible constraints") and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_bad_options_exit_2(tmp_path, capsys):
    assert _run(["design", "--monte-carlo", "0", "--criterion", "Q", "--out", str(tmp_path)]) == 2
    assert "criterion" in capsys.readouterr().err
    assert _run(["design", "--ship", "no-such-ship", "--out", str(tmp_path)]) == 2
    assert "unknown ship" in capsys.readouterr().err
