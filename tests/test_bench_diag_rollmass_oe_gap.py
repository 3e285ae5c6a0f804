"""benchmarks/diag_rollmass_oe_gap.py (stop 57): a split changes only what it names (the recorded split is the
truth bench's recordings bit for bit; a quiet role is basin_truth's quiet simulation of that dataset; the true
rudder column is the quiet simulation's, the other columns as recorded; the sea and sensor parts add up to the
recording), the table pairs fits by variant, case and run and counts a repeated fit once, and each bad option,
an existing non-empty dump or a missing table file is one stderr line, exit 2, no dump touched, before any
simulation (no fits here). The tests that simulate are marked slow (pytest -m slow)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks import diag_rollmass_oe_gap as gap
from tests.physics import basin_truth as bt

SCRIPT = Path(gap.__file__).resolve()
RUNS, SEED = 2, bt.variant_seed(gap.rollmass_oracle.FAMILY_SEED, "sway_roll")


@pytest.fixture(scope="module")
def family():
    return gap.Family("sway_roll", runs=RUNS, seed=SEED), bt.simulate_runs("sway_roll", RUNS, SEED)


def _same(a: bt.Recording, b: bt.Recording, skip: tuple = ()) -> bool:
    return a.meta == b.meta and all(np.array_equal(a.cols[k], b.cols[k]) for k in a.cols if k not in skip)


@pytest.mark.slow
def test_the_recorded_split_is_the_bench_recordings(family):
    fam, (ship, data) = family
    for case in ("case1", "case3"):
        got, ref = fam.recordings(case, 1, {}, False), bt.case_recordings(ship, data, case, 1)
        assert [r.role for r in got] == list(gap.ROLES) and all(map(_same, got, ref))


@pytest.mark.slow
def test_a_quiet_loaded_role_changes_that_recording_only(family):
    fam, (ship, data) = family
    got = fam.recordings("case2", 0, {"loaded": "quiet"}, False)
    ref = bt.case_recordings(ship, data, "case2", 0)
    assert _same(got[0], ref[0]) and _same(got[1], ref[1]) and not _same(got[2], ref[2])
    samples, m, zm = bt.DATASETS["0.400kg-4"]
    quiet = bt.simulate(ship, "sway_roll", (m, zm), samples, bt.dataset_seed(SEED, 3), quiet=True)
    assert np.array_equal(got[2].cols["phi"], quiet["phi"][0])


@pytest.mark.slow
def test_the_true_rudder_is_the_quiet_simulations_column_the_rest_as_recorded(family):
    fam, (ship, data) = family
    got = fam.recordings("case1", 1, {}, True)
    ref = bt.case_recordings(ship, data, "case1", 1)
    for g, r in zip(got, ref):
        assert _same(g, r, skip=("delta",))
        samples, m, zm = bt.DATASETS[g.name]
        seed = bt.dataset_seed(SEED, list(bt.DATASETS).index(g.name))
        true = bt.simulate(ship, "sway_roll", (m, zm), samples, seed, quiet=True)["delta"][1]
        assert np.array_equal(g.cols["delta"], true) and not np.array_equal(g.cols["delta"], r.cols["delta"])


@pytest.mark.slow
def test_the_sea_and_sensor_parts_add_up_to_the_recording(family):
    # every step after the integration is linear, and the gyro and accelerometer draws come before the encoder's
    fam, _ = family
    d = {part: fam.data("0.200kg-3", part) for part in gap.PARTS}
    for ch in ("p", "r", "a_s"):
        assert np.allclose(d["all"][ch] - d["sea"][ch], d["sensor"][ch] - d["quiet"][ch], rtol=0, atol=1e-9)
        assert not np.allclose(d["all"][ch], d["sea"][ch]) and not np.allclose(d["all"][ch], d["sensor"][ch])
    assert np.array_equal(d["sensor"]["delta"], d["all"]["delta"]) and np.array_equal(d["sea"]["delta"], d["quiet"]["delta"])


def test_parts_parse_and_name_the_split():
    assert gap.parse_parts("nominal=quiet,calibration=sea") == {"nominal": "quiet", "calibration": "sea"}
    assert gap.split_name(gap.parse_parts("calibration=quiet,nominal=quiet"), True) == (
        "nominal=quiet,calibration=quiet+true_rudder"
    )
    assert gap.split_name({}, False) == "recorded"
    for bad in ("nominal=loud", "ship=quiet", "loaded=quiet,loaded=sea"):
        with pytest.raises(ValueError):
            gap.parse_parts(bad)


def test_the_table_pairs_fits_by_variant_case_and_run(tmp_path):
    def row(run, m, z, split=None):
        fam = {"family": {"split": split}} if split else {}
        return ["base", "case2", "oe", run, [m, z, True, True, False], "", 1.0, fam]

    base, split = tmp_path / "b.jsonl", tmp_path / "s.jsonl"
    base.write_text("".join(json.dumps(r) + "\n" for r in (row(0, 4.0, 10.0), row(1, -2.0, 5.0), row(2, 9.0, 9.0))))
    split.write_text("".join(json.dumps(row(r, m, z, "x")) + "\n" for r, m, z in ((0, -1.0, 2.0), (1, 3.0, 5.0))))
    line = gap.table([str(split)], str(base)).splitlines()[1].split()
    # median |m| 2.0, |z| 3.5; baseline of the same runs 3.0, 7.5; per-fit |m| change -3 and +1, |z| -8 and 0
    assert line[:5] == ["x", "base", "case2", "2", "0"] and line[6:8] == ["2.00", "3.5"]
    assert line[9:11] == ["3.00", "7.5"] and line[12:14] == ["-1.00", "-1.00"] and line[15:17] == ["-4.0", "-4.0"]


def _main(monkeypatch, capsys, *args: str) -> tuple[int, str, str]:
    monkeypatch.setattr(sys, "argv", ["diag_rollmass_oe_gap.py", *args])
    with pytest.raises(SystemExit) as e:
        gap.main()
    out, err = capsys.readouterr()
    return e.value.code, out, err


def _one_line(err: str, option: str) -> bool:
    return len(err.strip().splitlines()) == 1 and f"error: {option}" in err and "fix:" in err and "Traceback" not in err


def test_the_table_counts_a_repeated_fit_once_and_warns(tmp_path, capsys):
    row = ["base", "case2", "oe", 0, [2.0, 1.0, True, True, False], "", 1.0, {"family": {"split": "x"}}]
    base, split = tmp_path / "b.jsonl", tmp_path / "s.jsonl"
    base.write_text(json.dumps(row[:7] + [{}]) + "\n")
    split.write_text(json.dumps(row) + "\n")
    line = gap.table([str(split), str(split)], str(base)).splitlines()[1].split()
    assert line[3:5] == ["1", "0"] and "1 repeated fit" in capsys.readouterr().err


@pytest.mark.parametrize(
    "bad,option",
    [
        (["--parts", "deck=quiet"], "--parts"),
        (["--cases", "case4"], "--cases"),
        (["--last", "30"], "--first"),
        (["--first", "3", "--last", "2"], "--first"),
        (["--dump-in-missing-folder"], "--dump"),
        (["--dump-not-empty"], "--dump"),
    ],
)
def test_bad_option_is_one_line_naming_it_exit_2_dump_untouched(bad, option, tmp_path, monkeypatch, capsys):
    dump = tmp_path / "d.jsonl"
    if bad == ["--dump-in-missing-folder"]:
        dump, bad = tmp_path / "no" / "d.jsonl", []
    if bad == ["--dump-not-empty"]:
        dump.write_text("[1]\n")
        bad = []
    before = dump.read_text() if dump.exists() else None
    monkeypatch.setattr(gap, "fit", lambda *a: pytest.fail("fitted"))  # a check missed must not start a simulation
    code, out, err = _main(monkeypatch, capsys, "--variant", "sway_roll", "--dump", str(dump), *bad)
    assert code == 2 and _one_line(err, option), err
    assert (dump.read_text() if dump.exists() else None) == before and out == ""


def test_append_and_force_open_a_non_empty_dump(tmp_path, monkeypatch):
    dump = tmp_path / "d.jsonl"
    dump.write_text("[1]\n")
    monkeypatch.setattr(gap, "fit", lambda *a: None)  # no simulation: only the dump's opening
    for flag, left in (("--append", "[1]\n"), ("--force", "")):
        monkeypatch.setattr(sys, "argv", ["x", "--variant", "sway_roll", "--dump", str(dump), flag, "--last", "0"])
        gap.main()
        assert dump.read_text() == left


def test_table_outside_the_repo_root_and_a_missing_dump(tmp_path, monkeypatch, capsys):
    row = ["sway_roll", "case1", "oe", 0, [1.0, 1.0, True, True, False], "", 1.0, {"family": {"split": "x"}}]
    dump = tmp_path / "s.jsonl"
    dump.write_text(json.dumps(row) + "\n")
    monkeypatch.chdir(tmp_path)  # --base and --oracle default to the script's folder, not the cwd
    monkeypatch.setattr(sys, "argv", ["x", "--table", str(dump)])
    gap.main()
    assert capsys.readouterr().out.splitlines()[1].split()[:3] == ["x", "sway_roll", "case1"]
    code, out, err = _main(monkeypatch, capsys, "--table", str(tmp_path / "missing.jsonl"))
    assert code == 2 and _one_line(err, "--table") and "missing.jsonl" in err and out == ""


def test_a_bad_option_from_the_command_line(tmp_path):
    # one subprocess: the script's own entry point (the other bad options run in-process above)
    dump = tmp_path / "d.jsonl"
    p = subprocess.run(
        [sys.executable, str(SCRIPT), "--variant", "sway_roll", "--dump", str(dump), "--parts", "nominal=loud"],
        capture_output=True,
        text=True,
        timeout=60,  # the check comes before the 30-run simulation
        env={**os.environ, "PYTHONPATH": str(SCRIPT.parents[1])},
    )
    assert p.returncode == 2 and _one_line(p.stderr, "--parts"), p.stderr
    assert not dump.exists() and p.stdout == ""
