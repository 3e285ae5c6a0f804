"""benchmarks/bench_rollmass_truth.py (stop 55): a family resumed from an interrupted --dump has the rows of an
uninterrupted run, --only makes the fits of the same family, and a dump of another family or code, with a fit twice
or a broken line is refused (a last line cut by an interrupted write is dropped and refit); stop 56: a dump another
process holds is refused (and no pool worker holds it), and the code key covers the project modules the estimator
imports."""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys
from pathlib import Path

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
    """The bench's stderr (its notes)."""
    monkeypatch.setattr(sys, "argv", ["bench_rollmass_truth.py", *ARGS, *args])
    bench.main()
    return capsys.readouterr().err


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


def test_a_dump_of_another_family_or_code_is_refused_and_left(short, monkeypatch, capsys, tmp_path):
    dump = tmp_path / "d.jsonl"
    _bench(monkeypatch, capsys, "--dump", str(dump), "--only", "base/0/case2")  # a real dump: every key but one agrees
    text = dump.read_text()
    for other, says in (
        (["--runs", "4"], "line 1 is of family"),
        (["--quiet"], "line 1 is of family"),
        (["--seed", "7"], "line 1 is of family"),
    ):
        with pytest.raises(SystemExit) as exc:
            _bench(monkeypatch, capsys, "--dump", str(dump), "--resume", *other)
        assert says in str(exc.value) and "fix:" in str(exc.value)
        assert dump.read_text() == text  # not emptied, not appended to
    monkeypatch.setattr(bench, "_code_hash", lambda: "0123456789ab")  # the estimator or the bench edited since
    with pytest.raises(SystemExit) as exc:
        _bench(monkeypatch, capsys, "--dump", str(dump), "--resume")
    assert "written by other code" in str(exc.value) and "start a new --dump" in str(exc.value)
    assert dump.read_text() == text


def test_a_cut_last_line_is_refit_and_a_repeated_fit_refused(short, monkeypatch, capsys, tmp_path):
    whole, dump = tmp_path / "whole.jsonl", tmp_path / "d.jsonl"
    _bench(monkeypatch, capsys, "--dump", str(whole))
    lines = whole.read_text().splitlines()
    dump.write_text(lines[0] + "\n" + lines[1][:40])  # interrupted in the middle of writing its second row
    assert "line 2 truncated (interrupted write): dropped" in _bench(monkeypatch, capsys, "--dump", str(dump), "--resume")
    assert _rows(dump) == _rows(whole)
    dump.write_text(lines[0] + "\n" + lines[1] + "\n" + lines[0] + "\n")  # two processes resumed it
    with pytest.raises(SystemExit) as exc:
        _bench(monkeypatch, capsys, "--dump", str(dump), "--resume")
    assert "lines 1 and 3 hold the same fit base/case2/ls/0" in str(exc.value) and "fix:" in str(exc.value)
    cut = lines[0] + "\n" + lines[1][:40] + "\n"  # a broken line that is not the last write's: refused, left
    dump.write_text(cut)
    with pytest.raises(SystemExit) as exc:
        _bench(monkeypatch, capsys, "--dump", str(dump), "--resume")
    assert "line 2 is not a bench row" in str(exc.value) and dump.read_text() == cut


@pytest.mark.parametrize("spec", ["base/7/case2", "bas/1/case2", "base/1", "base/1/case1", "base/x/case2"])
def test_an_only_that_names_no_fit_is_a_usage_error(monkeypatch, capsys, tmp_path, spec):
    dump = tmp_path / "d.jsonl"
    dump.write_text("kept\n")
    with pytest.raises(SystemExit) as exc:
        _bench(monkeypatch, capsys, "--dump", str(dump), "--only", f"base/0/case2,{spec}")
    assert exc.value.code == 2 and f"--only {spec}: no such fit of this family" in capsys.readouterr().err
    assert dump.read_text() == "kept\n"  # no dump written


def test_a_dump_another_process_holds_is_refused_and_left(short, monkeypatch, capsys, tmp_path):
    """Stop 56: the bench locks its --dump (fcntl.flock); a second writer, resuming or starting it, is refused in one
    line and the file is left (a fresh run would otherwise empty the first one's rows)."""
    dump = tmp_path / "d.jsonl"
    _bench(monkeypatch, capsys, "--dump", str(dump), "--only", "base/0/case2")
    text = dump.read_text()
    with open(dump) as other:  # another process's lock: a second open file description, as another process has
        fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
        for args in (["--resume"], []):
            with pytest.raises(SystemExit) as exc:
                _bench(monkeypatch, capsys, "--dump", str(dump), *args)
            assert "another process is writing this dump" in str(exc.value) and "fix:" in str(exc.value)
            assert "\n" not in str(exc.value) and dump.read_text() == text
    _bench(monkeypatch, capsys, "--dump", str(dump), "--resume", "--only", "base/1/case2")  # released: resumes
    assert len(dump.read_text().splitlines()) == 2


def _dump_not_open_here(job: tuple) -> list[tuple]:
    """The bench's fit (``bench._one``), in a pool worker that has checked it holds no descriptor of the dump (an
    inherited one would hold the parent's lock: a killed bench's orphaned worker kept it until its fit ended)."""
    fds = Path("/proc/self/fd")
    held = [fd.name for fd in fds.iterdir() if os.path.realpath(fd) == os.path.realpath(os.environ["BENCH_TEST_DUMP"])]
    assert not held, f"worker {os.getpid()} holds the dump open (fd {held}), and with it the lock"
    return _REAL_ONE(job)


_REAL_ONE = bench._one


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs /proc (Linux)")
def test_no_pool_worker_holds_the_dump_or_its_lock(short, monkeypatch, capsys, tmp_path):
    """Stop 56 review: the workers are forked after the dump is locked; each closes its inherited descriptor, so only
    the bench's own process holds the lock (a killed bench's dump can be resumed at once) and rows are still written."""
    dump = tmp_path / "d.jsonl"
    monkeypatch.setenv("BENCH_TEST_DUMP", str(dump))
    monkeypatch.setattr(bench, "_one", _dump_not_open_here)  # forked workers see the patched module
    _bench(monkeypatch, capsys, "--dump", str(dump), "--only", "base/0/case2,base/1/case2", "--workers", "2")
    assert len(dump.read_text().splitlines()) == 2
    with open(dump) as mine:  # released with the bench's own descriptor: lockable at once
        fcntl.flock(mine, fcntl.LOCK_EX | fcntl.LOCK_NB)


def test_the_code_hash_covers_every_project_module_the_estimator_imports():
    """Stop 56: :data:`bench.ESTIMATOR_IMPORTS` is the project's modules outside identify/rollmass/ that a fresh
    interpreter loads with the estimator (identify.rollmass.api), so an edit to one of them refuses a resume."""
    code = (
        "import sys, identify.rollmass.api\n"
        "print('\\n'.join(sorted(m.__file__ for n, m in sys.modules.items() if getattr(m, '__file__', None))))"
    )
    root = Path(bench.__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True).stdout
    files = {Path(f).resolve() for f in out.splitlines()}
    mine = sorted(f.relative_to(root).as_posix() for f in files if f.is_relative_to(root))
    outside = [f for f in mine if not f.startswith("identify/rollmass/")]
    assert outside == sorted(bench.ESTIMATOR_IMPORTS)
