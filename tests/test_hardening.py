"""Hardening behaviours a user relies on (issue 15): size refusals carry their estimate, --json is
pure JSON, nothing is written unasked, sweeps report failed cells, behaviour follows profile data."""

from __future__ import annotations

import json
import os

import pytest

from cli.app import _run
from primitives.errors import UserError
from primitives.ship import PROFILE_DIR, load_profile
from primitives.validate import check_counts, check_monte_carlo, monte_carlo_estimate


def _copy_of_model_ship(tmp_path, name="my-ship", **changes):
    import tomllib

    doc = tomllib.loads((PROFILE_DIR / "model-ship.toml").read_text())
    doc["name"] = name
    for k, v in changes.items():
        if v is None:
            doc.pop(k)
        else:
            doc[k] = v
    p = tmp_path / f"{name}.json"
    p.write_text(json.dumps(doc))
    return p


def test_monte_carlo_refusal_states_the_estimate_and_the_option():
    est = monte_carlo_estimate(500, 1000, designs=4, workers=2)
    assert est["cpu_s"] == pytest.approx(4 * 500 * 1000 * 30e-6)
    with pytest.raises(UserError, match=r"--monte-carlo 1000000 x --mc-samples 1000 .* would take about .* lower --monte-carlo"):
        check_monte_carlo(10**6, 1000)
    assert check_monte_carlo(500, 1000)["wall_s"] < 60  # the thesis's study is allowed


def test_counts_refusal_names_the_combinations():
    assert check_counts({"a": 3, "b": 3}) == 16
    with pytest.raises(UserError, match="count combinations"):
        check_counts({f"tau{i}": 50 for i in range(4)})


def test_json_output_stays_json_when_c_code_prints_to_stdout(monkeypatch, capfd):
    import primitives.library as lib

    real = lib.build_library

    def noisy(profile):
        os.write(1, b" ** On entry to DLASCL parameter number  4 had an illegal value\n")  # what LAPACK does
        print("a stray print from library code")
        return real(profile)

    monkeypatch.setattr(lib, "build_library", noisy)
    assert _run(["primitives", "--json"]) == 0
    out, err = capfd.readouterr()
    rows = json.loads(out)
    assert rows and "DLASCL" in err and "stray print" in err


@pytest.fixture(scope="module")
def one_design():
    """One real design of the model ship, reused: these tests are about files, not the optimum."""
    from expdesign.api import default_library, run_design

    prof = load_profile("model-ship")
    return run_design(prof, default_library(prof))


@pytest.fixture
def quick_design(monkeypatch, one_design):
    import expdesign.api

    monkeypatch.setattr(expdesign.api, "run_design", lambda *a, **k: one_design)


def test_design_without_out_writes_nothing(tmp_path, monkeypatch, capsys, quick_design):
    monkeypatch.chdir(tmp_path)
    assert _run(["design", "--monte-carlo", "0"]) == 0
    assert list(tmp_path.iterdir()) == []
    assert "optimal mix" in capsys.readouterr().out


def test_design_out_is_replaced_whole_and_marked(tmp_path, capsys, quick_design):
    out = tmp_path / "rep"
    assert _run(["design", "--monte-carlo", "0", "--out", str(out)]) == 0
    (out / "stale.png").write_text("from an older run")
    assert _run(["design", "--monte-carlo", "0", "--out", str(out)]) == 0
    names = {p.name for p in out.iterdir()}
    assert "design.json" in names and "report.md" in names and "stale.png" not in names
    assert [p.name for p in tmp_path.iterdir()] == ["rep"]


def test_behaviour_follows_the_profile_data_not_its_name(tmp_path):
    from expdesign.api import default_library

    renamed = load_profile(_copy_of_model_ship(tmp_path))
    assert renamed.library == "thesis-model-ship"
    a = [p.name for p in default_library(renamed, psi_switch=0.3)]
    b = [p.name for p in default_library(load_profile("model-ship"), psi_switch=0.3)]
    assert a == b


def test_sweep_with_a_failing_cell_exits_nonzero_and_lists_it(tmp_path, capsys):
    bad = _copy_of_model_ship(tmp_path, name="no-dictionary", library=None)
    cfg = tmp_path / "s.toml"
    cfg.write_text(f'[sweep]\nships = ["model-ship", "{bad}"]\ncriteria = ["D"]\n')
    rc = _run(["sweep", str(cfg), "--out", str(tmp_path / "t.csv"), "--scheduler", "inline"])
    err = capsys.readouterr().err
    assert rc == 1
    assert "1 of 2 cells failed" in err and str(bad) in err
    assert (tmp_path / "t.csv").read_text().count("\n") == 3  # header + both rows, the failure with its error


def test_sweep_interrupted_exits_130_and_writes_nothing(tmp_path, monkeypatch, capsys):
    import expdesign.sweep as sw

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt

    monkeypatch.setattr(sw, "run_sweep", interrupted)
    cfg = tmp_path / "s.toml"
    cfg.write_text('[sweep]\nships = ["model-ship"]\n')
    assert _run(["sweep", str(cfg), "--out", str(tmp_path / "t.csv")]) == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


@pytest.mark.parametrize("keep", [False, True])
def test_sweep_interrupted_mid_run_keeps_partial_only_when_asked(tmp_path, monkeypatch, capsys, keep):
    import expdesign.sweep as sw
    from expdesign.parallel import MapResult

    row = {k: None for k in sw.COLUMNS} | {"ship": "model-ship", "criterion": "D", "mean_subtraction": "complete"}
    monkeypatch.setattr(sw, "run_sweep", lambda cells, *_a, **_k: MapResult([row, None], [True, False], interrupted=True))
    cfg = tmp_path / "s.toml"
    cfg.write_text('[sweep]\nships = ["model-ship"]\ncriteria = ["D", "A"]\n')
    argv = ["sweep", str(cfg), "--out", str(tmp_path / "t.csv")] + (["--keep-partial"] if keep else [])
    assert _run(argv) == 130
    assert "1 of 2 cells finished" in capsys.readouterr().err
    written = sorted(p.name for p in tmp_path.iterdir())
    assert written == (["s.toml", "t.partial.csv", "t.partial.png"] if keep else ["s.toml"])


def test_unreachable_scheduler_is_one_line_and_exit_2(monkeypatch, capsys):
    import expdesign.parallel as par

    monkeypatch.setattr(par, "CONNECT_TIMEOUT_S", 1)
    rc = _run(["design", "--monte-carlo", "4", "--mc-samples", "200", "--scheduler", "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("error: --scheduler") and "Traceback" not in err and len(err.strip().splitlines()) == 1
