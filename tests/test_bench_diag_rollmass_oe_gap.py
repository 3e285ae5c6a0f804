"""benchmarks/diag_rollmass_oe_gap.py (stop 57): a split changes only what it names (the recorded split is the
truth bench's recordings bit for bit; a quiet role is basin_truth's quiet simulation of that dataset; the true
rudder changes the rudder column only, by the encoder's error), the table pairs fits by variant, case and run,
and each bad option is one stderr line, exit 2, no dump, before any simulation (no fits here)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks import diag_rollmass_oe_gap as gap
from tests.physics import basin_truth as bt

SCRIPT = Path(gap.__file__).resolve()
RUNS, SEED = 2, gap.variant_seed("sway_roll")


@pytest.fixture(scope="module")
def family():
    return gap.Family("sway_roll", runs=RUNS, seed=SEED), bt.simulate_runs("sway_roll", RUNS, SEED)


def _same(a: bt.Recording, b: bt.Recording, skip: tuple = ()) -> bool:
    return a.meta == b.meta and all(np.array_equal(a.cols[k], b.cols[k]) for k in a.cols if k not in skip)


def test_the_recorded_split_is_the_bench_recordings(family):
    fam, (ship, data) = family
    for case in ("case1", "case3"):
        got, ref = fam.recordings(case, 1, {}, False), bt.case_recordings(ship, data, case, 1)
        assert [r.role for r in got] == list(gap.ROLES) and all(map(_same, got, ref))


def test_a_quiet_loaded_role_changes_that_recording_only(family):
    fam, (ship, data) = family
    got = fam.recordings("case2", 0, {"loaded": "quiet"}, False)
    ref = bt.case_recordings(ship, data, "case2", 0)
    assert _same(got[0], ref[0]) and _same(got[1], ref[1]) and not _same(got[2], ref[2])
    samples, m, zm = bt.DATASETS["0.400kg-4"]
    quiet = bt.simulate(ship, "sway_roll", (m, zm), samples, bt.dataset_seed(SEED, 3), quiet=True)
    assert np.array_equal(got[2].cols["phi"], quiet["phi"][0])


def test_the_true_rudder_changes_the_rudder_column_only_by_the_encoder_error(family):
    fam, (ship, data) = family
    got = fam.recordings("case1", 1, {}, True)
    ref = bt.case_recordings(ship, data, "case1", 1)
    for g, r in zip(got, ref):
        assert _same(g, r, skip=("delta",))
        diff = np.abs(g.cols["delta"] - r.cols["delta"])
        assert 0 < diff.max() < np.deg2rad(0.3)  # encoder offset (0.05 deg sd) and 0.1 deg steps


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


@pytest.mark.parametrize(
    "bad,option",
    [
        (["--parts", "nominal=loud"], "--parts"),
        (["--parts", "deck=quiet"], "--parts"),
        (["--cases", "case4"], "--cases"),
        (["--last", "30"], "--first"),
        (["--first", "3", "--last", "2"], "--first"),
        (["--dump-in-missing-folder"], "--dump"),
    ],
)
def test_bad_option_is_one_line_naming_it_exit_2_no_dump(bad, option, tmp_path):
    dump = tmp_path / "d.jsonl"
    if bad == ["--dump-in-missing-folder"]:
        dump, bad = tmp_path / "no" / "d.jsonl", []
    p = subprocess.run(
        [sys.executable, str(SCRIPT), "--variant", "sway_roll", "--dump", str(dump), *bad],
        capture_output=True,
        text=True,
        timeout=60,  # the check comes before the 30-run simulation
    )
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert f"error: {option}" in p.stderr and "fix:" in p.stderr and "Traceback" not in p.stderr
    assert not dump.exists() and p.stdout == ""
