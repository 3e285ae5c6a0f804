"""benchmarks/rollmass_family_zscores.py (stop 60): a dump row's errors in units of its reported sd, read against the
critical value its interval used (the bench records the degrees of freedom since stop 60), the bias / spread split of
the misses and the inflation measured on other fits."""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest
from scipy.special import stdtrit

from benchmarks import bench_rollmass_truth as bench
from benchmarks import rollmass_family_zscores as zs
from tests.physics import basin_truth as bt


def _row(s_m: float, s_z: float, case: str = "case1", dof: float = 20.0, run: int = 0, variant: str = "base") -> list:
    """A dump row whose mass and height errors are ``s_m`` and ``s_z`` reported sds (m_sd 0.01 kg, z_sd 10 mm)."""
    m_true, _ = bt.truth_load(case)
    t = float(stdtrit(dof, 0.975))
    ans = [100 * s_m * 0.01 / m_true, 10.0 * s_z, abs(s_m) <= t, abs(s_z) <= t, False]
    return [variant, case, "oe", run, ans, "", 3.0, {"m_sd": 0.01, "z_sd": 0.01, "m_dof": dof, "z_dof": dof}]


def test_a_row_is_read_in_sd_units_against_its_own_critical_value():
    s_m, s_z, t_m, t_z = zs.standardised(_row(2.5, -1.0, case="case2", dof=10.0))
    assert s_m == pytest.approx(2.5) and s_z == pytest.approx(-1.0)
    assert t_m == t_z == pytest.approx(2.2281388519649385)  # t_{0.975, 10}
    row = _row(1.0, 1.0)
    row[7]["m_dof"] = row[7]["z_dof"] = math.inf  # no degrees of freedom known: the normal 1.96, as MassEstimate.critical
    assert zs.standardised(row)[2:] == (1.96, 1.96)
    old = _row(1.0, 1.0)
    del old[7]["m_dof"]  # a dump before stop 60 records no degrees of freedom: not read
    assert zs.standardised(old) is None
    assert zs.standardised(["base", "case1", "oe", 0, None, "not converged", 9.0, {}]) is None


def test_miss_share_of_a_normal():
    assert zs.miss_share(0.0, 1.0, 1.959963984540054) == pytest.approx(5.0, abs=1e-9)
    assert zs.miss_share(1.96, 1.0, 1.96) == pytest.approx(50.0, abs=0.1)  # centred on the bound: half out
    assert zs.miss_share(0.0, 2.0, 1.96) == pytest.approx(100 * 2 * (1 - 0.8365), abs=0.1)  # Phi(0.98) = 0.8365


def test_bias_and_spread_are_told_apart():
    biased = [_row(s, s, run=i) for i, s in enumerate(np.linspace(1.0, 3.0, 21))]  # median 2, sd 0.62
    g = zs.group(biased)
    assert g["m"]["med"] == pytest.approx(2.0) and g["m"]["bias_only"] > 40 and g["m"]["spread_only"] < 1
    assert g["m"]["neg"] == 0 and g["m"]["pos"] == sum(s > g["t_m"][0] for s in np.linspace(1.0, 3.0, 21))
    spread = [_row(s, -s, run=i) for i, s in enumerate(np.linspace(-4.0, 4.0, 21))]  # median 0, sd 2.5
    g = zs.group(spread)
    assert g["z"]["med"] == pytest.approx(0.0) and g["z"]["spread_only"] > 40 and g["z"]["bias_only"] < 6
    assert g["z"]["rsd"] == pytest.approx(1.4826 * 2.0)  # the median |s| of -4 .. 4 in steps of 0.4 is 2
    assert g["both"] == g["both_recorded"]  # recomputed from s and t as the rows recorded it


def test_an_inflation_is_measured_on_other_fits_and_widens_the_intervals():
    calib = [_row(s, 2 * s, run=i) for i, s in enumerate([1.0, -1.0, 3.0, -3.0])]
    k = zs.rms_factor(calib)
    assert k == pytest.approx((math.sqrt(5.0), 2 * math.sqrt(5.0)))
    held_out = [_row(3.0, 3.0, run=0), _row(0.5, 0.5, run=1)]
    assert zs.group(held_out)["both"] == 50.0 and zs.group(held_out, k)["both_inflated"] == 100.0


def test_the_bench_records_the_critical_values_its_intervals_used(monkeypatch, capsys, tmp_path):
    """Each dumped oe row records its Satterthwaite degrees of freedom: from them and the sds the recorded holds are
    recomputed exactly; without the bench's m_dof / z_dof the row cannot be read (the test fails)."""
    real = bt.simulate_runs
    monkeypatch.setattr(bt, "simulate_runs", lambda *a, **k: real(*a, **{**k, "length": 0.35}))
    dump = tmp_path / "d.jsonl"
    args = ["--runs", "1", "--variants", "base", "--cases", "case2", "--methods", "oe", "--workers", "1", "--dump", str(dump)]
    monkeypatch.setattr(sys, "argv", ["bench_rollmass_truth.py", *args])
    bench.main()
    capsys.readouterr()
    (row,) = map(json.loads, dump.read_text().splitlines())
    got = zs.standardised(row)
    assert got is not None
    s_m, s_z, t_m, t_z = got
    assert 1.96 < t_m < 13 and 1.96 < t_z < 13  # oe's intervals take Student's t on a finite nu
    assert row[4][2] == (abs(s_m) <= t_m) and row[4][3] == (abs(s_z) <= t_z)


def test_the_pooled_checks_of_the_reading_are_computed_by_the_script():
    """Review of stop 60: the figures the docs' reading rests on (the two intervals missing together, 1.96 in place of
    t, the tails, the runs with a miss) come from the script, not a scratch call."""
    s = {(0, "case1"): 2.1, (0, "case2"): 0.5, (1, "case1"): 3.0, (1, "case2"): -3.0, (2, "case1"): 0.0, (2, "case2"): 2.5}
    rows = [_row(v, v, case=c, dof=10.0, run=r) for (r, c), v in s.items()]  # t_{0.975, 10} = 2.23
    c = zs.checks(rows)
    assert c["corr"] == pytest.approx(1.0) and c["n"] == 6
    assert c["hold_t"] == 3 and c["hold_196"] == 2  # 2.1 holds with t, not with 1.96
    assert c["runs"] == 3 and c["runs_missed"] == 2 and c["runs_all_missed"] == 1
    assert c["kurtosis_se"] == pytest.approx(2.0) and 0 < c["shapiro_p"] <= 1
    assert zs.checks(rows[:2]) is None


@pytest.mark.parametrize("bad", ["0", "-1.4", "nan", "x"])
def test_an_inflation_factor_must_be_above_zero(bad, monkeypatch, tmp_path, capsys):
    dump = tmp_path / "d.jsonl"
    dump.write_text(json.dumps(_row(1.0, 1.0)) + "\n")
    monkeypatch.setattr(sys, "argv", ["x", str(dump), "--inflate", bad])
    with pytest.raises(SystemExit) as exc:
        zs.main()
    assert exc.value.code == 2 and "is not a factor above 0" in capsys.readouterr().err
