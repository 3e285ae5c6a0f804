"""benchmarks/bench_rollmass_truth.py (stop 55): a family resumed from an interrupted --dump has the rows of an
uninterrupted run, --only makes the fits of the same family, and a dump of another family is refused."""

from __future__ import annotations

import json
import sys

import pytest

from benchmarks import bench_rollmass_truth as bench
from tests.physics import basin_truth as bt

# a tiny family: short recordings (the bench's own length is 1), one variant and case, the least squares method (the
# resume does not depend on the method; oe's path record is tested in tests/test_rollmass_oe_fit.py)
ARGS = ["--runs", "3", "--variants", "base", "--cases", "case2", "--methods", "ls", "--workers", "1"]


@pytest.fixture
def short(monkeypatch):
    real = bt.simulate_runs
    monkeypatch.setattr(bt, "simulate_runs", lambda *a, **k: real(*a, **{**k, "length": 0.35}))


def _bench(monkeypatch, capsys, *args: str) -> str:
    monkeypatch.setattr(sys, "argv", ["bench_rollmass_truth.py", *ARGS, *args])
    bench.main()
    return capsys.readouterr().out


def _rows(path) -> list[list]:
    """The dump's rows without their CPU (the one field two runs of the same fit differ in)."""
    return [r[:6] + r[7:] for r in map(json.loads, path.read_text().splitlines())]


def test_a_resumed_family_has_the_uninterrupted_rows(short, monkeypatch, capsys, tmp_path):
    whole, cut = tmp_path / "whole.jsonl", tmp_path / "cut.jsonl"
    _bench(monkeypatch, capsys, "--dump", str(whole))
    lines = whole.read_text().splitlines()
    assert len(lines) == 3 and json.loads(lines[0])[7]["family"]["runs"] == 3
    cut.write_text(lines[0] + "\n")  # interrupted after its first fit
    _bench(monkeypatch, capsys, "--dump", str(cut), "--resume")
    assert _rows(cut) == _rows(whole)
    assert json.loads(cut.read_text().splitlines()[0])[6] == json.loads(lines[0])[6]  # the kept row untouched
    _bench(monkeypatch, capsys, "--dump", str(cut), "--resume")  # nothing left to fit: the dump stays as it is
    assert _rows(cut) == _rows(whole)
    one = tmp_path / "one.jsonl"
    _bench(monkeypatch, capsys, "--dump", str(one), "--only", "base/2/case2")  # the same family's run 2 alone
    assert _rows(one) == _rows(whole)[2:]


def test_a_dump_of_another_family_is_refused(short, monkeypatch, capsys, tmp_path):
    dump = tmp_path / "d.jsonl"
    row = ["base", "case2", "ls", 0, None, "", 1.0, {"family": {"runs": 30}}]
    dump.write_text(json.dumps(row) + "\n")
    with pytest.raises(SystemExit) as exc:
        _bench(monkeypatch, capsys, "--dump", str(dump), "--resume")
    assert "line 1 is of family" in str(exc.value) and "fix:" in str(exc.value)
    assert dump.read_text() == json.dumps(row) + "\n"  # not emptied
