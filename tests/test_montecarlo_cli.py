"""``shiptrial design`` Monte Carlo: Ctrl-C exits 130 and writes nothing unless --keep-partial,
which writes a report marked partial with the runs that finished."""

from __future__ import annotations

import json

import pytest

import expdesign.mc_parallel as mc
from cli.app import _run

ARGS = ["design", "--monte-carlo", "6", "--mc-samples", "400", "--scheduler", "inline", "--seed", "1"]


@pytest.fixture
def ctrl_c_in_random(monkeypatch):
    real = mc.run_chunk

    def run_chunk(shared, design, run_ids):
        if design == "random":
            raise KeyboardInterrupt
        return real(shared, design, run_ids)

    monkeypatch.setattr(mc, "run_chunk", run_chunk)


def test_ctrl_c_exits_130_and_writes_nothing(tmp_path, capsys, ctrl_c_in_random):
    out = tmp_path / "rep"
    assert _run([*ARGS, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert "interrupted" in err and "optimized 6, random 0" in err and "--keep-partial" in err
    assert not (out / "design.json").exists()


def test_keep_partial_writes_a_report_marked_partial(tmp_path, capsys, ctrl_c_in_random):
    out = tmp_path / "rep"
    assert _run([*ARGS, "--out", str(out), "--keep-partial"]) == 130
    doc = json.loads((out / "design.json").read_text())
    st = doc["monte_carlo_status"]
    assert st["partial"] and st["interrupted"] and st["runs_finished"] == {"optimized": 6, "random": 0, "uniform": 0, "thesis": 0}
    assert set(doc["monte_carlo"]) == {"optimized"}  # never claims runs that did not finish
    assert doc["monte_carlo"]["optimized"]["runs"] == 6 and "runs" not in doc["monte_carlo_config"]
    md = (out / "report.md").read_text()
    assert "PARTIAL RESULT (interrupted)" in md and "random 0 of 6" in md  # the design with no finished run is said


def test_keep_partial_with_no_finished_run_says_there_is_nothing_to_keep(tmp_path, capsys, monkeypatch):
    def interrupted(shared, design, run_ids):
        raise KeyboardInterrupt

    monkeypatch.setattr(mc, "run_chunk", interrupted)
    out = tmp_path / "rep"
    assert _run([*ARGS, "--out", str(out), "--keep-partial"]) == 130
    err = capsys.readouterr().err
    assert "optimized 0, random 0, uniform 0, thesis 0" in err and "no run finished, nothing to keep: nothing written" in err
    assert not out.exists()


def test_complete_report_states_protocol_thesis_numbers_and_open_choices(tmp_path, capsys):
    out = tmp_path / "rep"
    assert _run([*ARGS, "--out", str(out), "--mc-settle", "4", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["monte_carlo_status"]["complete"] and doc["monte_carlo_config"]["protocol"] == "continuous"
    assert doc["monte_carlo_config"]["settle"] == 4 and doc["monte_carlo_thesis"]["optimized"]["param"] == 0.99
    opt = doc["monte_carlo"]["optimized"]
    assert [p["parameter"] for p in opt["parameters"]][:3] == ["Xu", "Xvr", "X|u|u"] and len(opt["digest"]) == 64
    worst = min(opt["parameters"], key=lambda p: p["frac_within_tolerance"])
    assert opt["limiting_parameter"] == worst["parameter"]
    choices = {c["choice"]: c["value"] for c in doc["monte_carlo_config"]["open_choices"]}
    assert "library order" in choices["primitive order"] and "Table 6.2" in choices["parameter error"]
    md = (out / "report.md").read_text()
    for text in (
        "Protocol **continuous**",
        "| thesis |",
        "Choices Ljungberg (2022) leaves open",
        "settling between primitives: 4 samples",
        "optimized thesis 99.0 %, ours",
        r"X\|u\|u",
        "Limiting parameter:",
    ):
        assert text in md
