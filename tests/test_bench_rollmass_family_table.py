"""benchmarks/rollmass_family_table.py (stop 54): the exact binomial interval on a coverage and the
complete-runs filter of an interrupted family dump."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from scipy.stats import binom

from benchmarks import rollmass_family_table as ft


def test_clopper_pearson_known_values():
    # Clopper & Pearson's exact interval: 0 of 10 -> [0, 30.85 %] (1 - 0.025^(1/10)); 10 of 10 -> [69.15 %, 100 %]
    lo, hi = ft.clopper_pearson(0, 10)
    assert lo == 0.0 and hi == pytest.approx(100 * (1 - 0.025 ** (1 / 10)), rel=1e-9)
    lo, hi = ft.clopper_pearson(10, 10)
    assert lo == pytest.approx(100 * 0.025 ** (1 / 10), rel=1e-9) and hi == 100.0
    # an interior count: the interval holds k / n and is the tail-probability inversion
    lo, hi = ft.clopper_pearson(26, 30)
    assert lo < 100 * 26 / 30 < hi
    assert binom.sf(25, 30, lo / 100) == pytest.approx(0.025, rel=1e-6)
    assert binom.cdf(26, 30, hi / 100) == pytest.approx(0.025, rel=1e-6)


def _row(variant, case, run, err_m=1.0, hold=True, cpu=3.0):
    return [variant, case, "oe", run, [err_m, 2.0, hold, hold, False], "", cpu, {}]


def test_complete_runs_drop_a_partial_run():
    rows = [_row(v, c, r) for r in range(3) for v in ("base", "waves") for c in ("case1", "case2")]
    rows = rows[:-1]  # run 2 lost its last fit (an interrupted dump)
    kept = ft._complete(rows)
    assert sorted({r[3] for r in kept}) == [0, 1] and len(kept) == 8


def test_cell_counts_and_failures(tmp_path, capsys):
    rows = [_row("base", "case1", r, err_m=e, hold=h) for r, (e, h) in enumerate([(-2.0, True), (6.0, False), (4.0, True)])]
    rows.append(["base", "case1", "oe", 3, None, "not converged", 120.0, {}])
    c = ft._cell(rows)
    assert c["n"] == 4 and c["fail"] == 1 and c["ng"] == 3 and c["k_b"] == 2
    assert c["med_m"] == 4.0 and c["bias_m"] == 4.0 and c["cpu"] == pytest.approx(np.median([3.0, 3.0, 3.0, 120.0]))
    dump = tmp_path / "d.jsonl"
    dump.write_text("".join(json.dumps(r) + "\n" for r in rows))
    sys.argv = ["x", str(dump)]
    ft.main()
    out = capsys.readouterr().out
    assert "failed: base case1 run 3: not converged" in out and "4 oe fits" in out


def test_the_recorded_paths_are_split_the_geodesic_continuation_included():
    """Stop 59: the fits whose exact end the geodesic LM continued are counted with their CPU beside the redo's and
    stop 56's exact continuation's; a split that knows only the old paths drops them (mutant tried); an older dump
    without paths gives no split."""
    rows = [_row("base", "case1", r, cpu=c) for r, c in enumerate([3.0, 20.0, 25.0, 100.0, 12.0])]
    for r, p in zip(rows, ["exact", "geodesic", "geodesic", "redo", "continued"]):
        r[7] = {"path": {"path": p}}
    cpu = np.array([r[6] for r in rows])
    assert ft._path_split(rows, cpu) == [
        "fits that took the redo (recorded): 1 of 5, 100 s cpu",
        "fits whose exact path was continued (exact LM) (recorded): 1, 12 s cpu",
        "fits whose exact path was continued by the geodesic LM (recorded): 2, 45 s cpu",
    ]
    assert ft._path_split([_row("base", "case1", 0)], np.array([3.0])) == []


def test_dumps_of_disjoint_runs_are_pooled_and_a_fit_in_two_refused(tmp_path, capsys, monkeypatch):
    """Stop 60: runs 0-6 and 7-13 of one family fitted into two dumps make one table; a fit in both is refused (it
    would count one ship twice)."""
    a, b = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    a.write_text("".join(json.dumps(_row("base", "case1", r)) + "\n" for r in range(2)))
    b.write_text("".join(json.dumps(_row("base", "case1", r)) + "\n" for r in range(2, 5)))
    monkeypatch.setattr(sys, "argv", ["x", str(a), str(b)])
    ft.main()
    assert "5 oe fits, runs 0-4 (5 runs)" in capsys.readouterr().out
    b.write_text(json.dumps(_row("base", "case1", 1)) + "\n")
    with pytest.raises(SystemExit, match=r"b.jsonl: line 1 repeats the fit base/case1/oe/1 of .*a.jsonl line 2"):
        ft.load([str(a), str(b)])


def _fam_row(run: int, runs: int, code: str = "abc") -> list:
    r = _row("base", "case1", run)
    r[7] = {"family": {"runs": runs, "seed": 2015, "quiet": False, "with_u": True, "heel_ref": "acc-lp", "code": code}}
    return r


def test_dumps_of_two_families_or_bad_files_are_refused_in_one_line(tmp_path):
    """Review of stop 60: run k is another ship at another ``--runs``, so dumps of two family settings are not pooled
    (another code is: stop 54's runs beside a re-fit is a comparison the docs make); a dump without the record (stop
    54's) pools with any; a missing file or a line that is not a row is named, not a traceback."""
    a, b, old = tmp_path / "a.jsonl", tmp_path / "b.jsonl", tmp_path / "old.jsonl"
    a.write_text(json.dumps(_fam_row(0, 30)) + "\n")
    b.write_text(json.dumps(_fam_row(1, 30, code="def")) + "\n")
    old.write_text(json.dumps(_row("base", "case1", 2)) + "\n")
    assert [r[3] for r in ft.load([str(a), str(b), str(old)])] == [0, 1, 2]
    b.write_text(json.dumps(_fam_row(1, 7)) + "\n")
    with pytest.raises(SystemExit, match=r"b.jsonl: line 1's family settings .*'runs': 7.* differ from .*a.jsonl line 1's"):
        ft.load([str(a), str(b)])
    with pytest.raises(SystemExit, match=r"nope.jsonl: cannot read the dump"):
        ft.load([str(tmp_path / "nope.jsonl")])
    b.write_text(json.dumps(_fam_row(1, 30)) + "\n{not json\n")
    with pytest.raises(SystemExit, match=r"b.jsonl: line 2 is not a dump row"):
        ft.load([str(a), str(b)])
