"""benchmarks/rollmass_lag_windows.py (stop 62): each oe row's ``lag_windows`` read as the product's interval
``estimate +- t_{0.975, nu} sd``, and a dump without them refused in one line naming the file (review of stop 62)."""

from __future__ import annotations

import json
import sys

import pytest
from scipy import stats

from benchmarks import rollmass_lag_windows as lw
from tests.physics import basin_truth as bt


def _row(run: int, windows: dict | None) -> list:
    """A case-1 oe row 1 % / 10 mm off the truth; ``windows``: ``{key: [m_sd / m_true, z_sd m, dof, lags]}``."""
    m_true, _ = bt.truth_load("case1")
    extra = {} if windows is None else {"lag_windows": {k: [s * m_true, z, d, d, L] for k, (s, z, d, L) in windows.items()}}
    return ["base", "case1", "oe", run, [1.0, 10.0, True, True, True], "", 3.0, extra]


def test_a_windows_interval_is_the_products_and_holds_by_its_own_t():
    # 1 % off with an sd of 0.5 %: z 2.0, inside t_{0.975, 10} = 2.23, outside at an sd of 0.4 % (z 2.5, t 2.09 at
    # 25 dof); the sample time from the 5 s window's 250 lags (50 Hz), so the 20 s window's 1000 lags are 20 s
    fits = lw._fit_windows(_row(0, {"5": (0.004, 0.005, 25.0, 250), "20": (0.005, 0.004, 10.0, 1000)}))
    zm, zz, tm, tz, wm, wz, window = fits["20"]
    assert (zm, zz, window) == pytest.approx((2.0, 2.5, 20.0))
    assert (tm, tz) == pytest.approx((stats.t.ppf(0.975, 10.0),) * 2, rel=1e-9)
    assert (wm, wz) == pytest.approx((200 * tm * 0.005, 2000 * tz * 0.004), rel=1e-9)
    assert fits["5"][0] == pytest.approx(2.5) and abs(fits["5"][0]) > fits["5"][2]  # a miss at 5 s
    assert lw._fit_windows(["base", "case1", "oe", 1, None, "failed", 3.0, {}]) is None


def test_a_dump_without_windows_is_refused_naming_the_file(tmp_path, monkeypatch):
    good, old = tmp_path / "good.jsonl", tmp_path / "old.jsonl"
    good.write_text(json.dumps(_row(0, {"own": (0.005, 0.004, 10.0, 1000), "5": (0.004, 0.005, 25.0, 250)})) + "\n")
    old.write_text(json.dumps(_row(1, None)) + "\n")
    monkeypatch.setattr(sys, "argv", ["rollmass_lag_windows.py", str(good), str(old)])
    with pytest.raises(SystemExit, match=r"old.jsonl: fit base/case1/oe/1 has no lag_windows; fix: "):
        lw.main()
