"""benchmarks/compare_rollmass_dumps.py (stop 56 review): two rows are called bit-identical only when they record the
same fields with the same values; a field only one row records is a difference, said."""

from __future__ import annotations

import copy

from benchmarks.compare_rollmass_dumps import _same

# a dump row: variant, case, method, run, answer, warning, CPU, fitted parameters (with the path and family keys)
ROW = ["base", "case1", "oe", 0, [1.5, -2.0, True, True, False], "", 4.2, {"kappa": 0.31, "X_v": 20.0, "path": {}, "family": {}}]


def _with(**extra: object) -> list:
    r = copy.deepcopy(ROW)
    r[7].update(extra)
    return r


def test_rows_recording_the_same_fields_alike_are_bit_identical_whatever_their_cpu_path_and_family():
    other = copy.deepcopy(ROW)
    other[6], other[7]["path"], other[7]["family"] = 9.9, {"path": "redo"}, {"runs": 3}
    assert _same(ROW, other) == " (row bit-identical)"


def test_a_field_one_row_records_and_the_other_not_is_a_difference_said():
    assert _same(ROW, _with(m_sd=0.01, z_sd=0.002)) == " (shared fields bit-identical; only after: m_sd, z_sd)"
    assert _same(_with(m_sd=0.01), ROW) == " (shared fields bit-identical; only before: m_sd)"  # a newer row dropped it
    assert "bit-identical" not in _same(ROW, _with(kappa=0.32))  # a shared field that differs
    assert _same(ROW, _with(kappa=0.32, m_sd=0.01)) == ""
    moved = copy.deepcopy(ROW)
    moved[4][0] = 1.6
    assert _same(ROW, moved) == ""


def test_the_paths_are_counted_before_and_after_the_geodesic_continuation_included():
    """Stop 59: a fit the redo took before and the geodesic continuation after is counted as such, with its CPU; a
    counter that knows only stop 56's paths (exact, continued, redo) drops the geodesic fits (mutant tried)."""
    from benchmarks.compare_rollmass_dumps import _paths

    def row(run: int, path: str, cpu: float) -> list:
        r = copy.deepcopy(ROW)
        r[3], r[6], r[7]["path"] = run, cpu, {"path": path}
        return r

    before = {
        ("base", "case1", "oe", i): row(i, p, c) for i, (p, c) in enumerate([("exact", 4.0), ("redo", 110.0), ("redo", 90.0)])
    }
    after = {k: row(k[3], p, c) for k, (p, c) in zip(before, [("exact", 4.0), ("geodesic", 20.0), ("redo", 95.0)])}
    after[("base", "case1", "oe", 9)] = row(9, "exact", 3.0)  # unpaired: not counted
    assert _paths(before, after) == "exact 1 (4 s) -> 1 (4 s); geodesic 0 -> 1 (20 s); redo 2 (200 s) -> 1 (95 s)"
