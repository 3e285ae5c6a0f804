"""``shiptrial design`` and ``shiptrial plan`` with the robust criteria: the report and bad input."""

from __future__ import annotations

import json

import pytest

from cli.app import _run


def test_design_robust_report_json_and_markdown(tmp_path, capsys):
    out = tmp_path / "rep"
    args = ["design", "--ship", "model-ship", "--criterion", "bayes-D", "--prior-spread", "0.3", "--prior-draws", "20"]
    rc = _run([*args, "--monte-carlo", "4", "--prior-truths", "2", "--scheduler", "inline", "--out", str(out), "--json"])
    assert rc == 0
    doc = json.loads(capsys.readouterr().out)
    r = doc["robust"]
    assert doc["criterion"] == "bayes-D" and r["draws_used"] == 20 and r["prior"]["source"].startswith("+-30 %")
    assert set(r["d_efficiency"]) == {"local-D", "bayes-D", "local-D rounded", "rounded"}
    mc = doc["prior_monte_carlo"]
    assert set(mc) == {"local-D", "bayes-D"} and all(s["truths"] == 2 and s["runs"] == 4 for s in mc.values())
    md = (out / "report.md").read_text()
    assert "## Robust design" in md and "10th percentile" in md and "truths drawn from the prior" in md
    # where the figures come from, beside them (simulated on the profile's own model)
    assert "not evidence about a real ship or about model-structure error" in md
    # fewer runs than truths: never more runs than asked (review N6)
    rc = _run([*args, "--monte-carlo", "2", "--prior-truths", "5", "--scheduler", "inline", "--json"])
    mc = json.loads(capsys.readouterr().out)["prior_monte_carlo"]
    assert rc == 0 and all(s["truths"] == 2 and s["runs"] == 2 for s in mc.values())
    assert "Convex certificate" not in md and "bayes-D efficiency on the relaxed matrices" in md  # review N3


ROBUST = ["design", "--ship", "model-ship", "--monte-carlo", "0"]


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--criterion", "bayes-D", "--prior-spread", "1.5"], "--prior-spread 1.5: give a fraction in (0, 1]"),
        (["--criterion", "maximin-D", "--prior-spread", "0"], "--prior-spread 0: give a fraction in (0, 1]"),
        (["--criterion", "bayes-D"], "--criterion bayes-D designs over parameter draws"),
        (["--prior-spread", "0.3"], "--prior-spread is for the robust criteria"),
        (["--criterion", "bayes-D", "--prior-file", "NOFILE"], "NOFILE: not a readable prior file"),
        (["--criterion", "bayes-D", "--prior-file", "COV"], "'parameter_names' does not match ship 'model-ship'"),
        # the robust path's draws are noise-free: refused, never silently dropped (review B2)
        (["--criterion", "bayes-D", "--prior-spread", "0.3", "--noisy-moments", "3"], "--noisy-moments (disturbed"),
        # options that would be silently ignored (review N8)
        (["--prior-draws", "50"], "--prior-draws is for the robust criteria"),
        (["--criterion", "bayes-D", "--prior-spread", "0.3", "--prior-truths", "5"], "--prior-truths is for the Monte Carlo"),
        (["--criterion", "bayes-D", "--prior-file", "DRAWS", "--prior-draws", "50"], "used as given: drop --prior-draws"),
    ],
)
def test_bad_prior_one_line_exit_2_nothing_written(tmp_path, capsys, extra, match):
    cov = tmp_path / "cov.json"
    cov.write_text(json.dumps({"parameter_names": ["Xu", "Yv"], "covariance": [[1.0, 0.0], [0.0, 1.0]]}))
    drw = tmp_path / "draws.json"
    names = ["Xu", "Xvr", "X|u|u", "Xtau", "Yv", "Yur", "Ytau", "Nr", "Nuv", "Ntau"]
    drw.write_text(json.dumps({"parameter_names": names, "draws": [[1.0] * 10, [2.0] * 10]}))
    extra = [
        str(drw) if a == "DRAWS" else str(cov) if a == "COV" else str(tmp_path / "missing.json") if a == "NOFILE" else a
        for a in extra
    ]
    out = tmp_path / "rep"
    assert _run([*ROBUST, *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and match.replace("NOFILE", str(tmp_path / "missing.json")) in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def test_plan_refuses_a_bad_prior_before_planning(tmp_path, capsys):
    out = tmp_path / "plan"
    assert _run(["plan", "--ship", "kvlcc2", "--criterion", "maximin-D", "--prior-spread", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --prior-spread 2: give a fraction in (0, 1]") and len(err.strip().splitlines()) == 1
    assert not out.exists()
