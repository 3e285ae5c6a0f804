"""Atomic outputs: a failed run never leaves a mix of old and new files."""

import os
import sys
import time

import pytest

from primitives.errors import UserError
from primitives.io import OUTPUT_MARKER, atomic_output_dir, check_out_path
from tests.procs import killable_writer


def test_atomic_output_dir_replaces_on_success(tmp_path):
    out = tmp_path / "out"
    with atomic_output_dir(out) as d:
        (d / "old.txt").write_text("old")
    with atomic_output_dir(out) as d:
        (d / "new.txt").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == [OUTPUT_MARKER, "new.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # no temporary left behind


def test_atomic_output_dir_never_replaces_a_directory_of_the_users_files(tmp_path):
    out = tmp_path / "docs"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    with pytest.raises(UserError, match="did not write"), atomic_output_dir(out) as d:
        (d / "new.txt").write_text("new")
    assert [p.name for p in out.iterdir()] == ["thesis.tex"]
    assert [p.name for p in tmp_path.iterdir()] == ["docs"]


def test_atomic_output_dir_keeps_previous_on_failure(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "plan.json").write_text("{}")  # a previous run's result
    (out / "plan.rtz").write_text("previous plan")
    with pytest.raises(RuntimeError), atomic_output_dir(out) as d:
        (d / "plan.rtz").write_text("half")
        raise RuntimeError("planner failed")
    assert (out / "plan.rtz").read_text() == "previous plan"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_check_out_path_refuses_a_file(tmp_path):
    f = tmp_path / "x.txt"
    f.write_text("")
    with pytest.raises(UserError, match="is a file"):
        check_out_path(f)


def _child(out, mode, **kw):
    return killable_writer("primitives.io", "atomic_output_dir", "plan.json", "swapping", out, mode, **kw)


def _hidden(d):
    return {p.name for p in d.iterdir() if p.name.startswith(".")}


def test_next_run_removes_the_temporaries_a_killed_run_left_and_nothing_else(tmp_path):
    """SIGKILL mid-write leaves a hidden temporary beside --out; the next run into the same
    directory (a later process) removes it and puts back a previous result a killed swap had moved
    aside, but keeps a running run's temporary, leftovers younger than itself, another
    destination's, and every look-alike shiptrial did not make."""
    import subprocess

    out = tmp_path / "out"
    out.mkdir()
    (out / "plan.json").write_text("last week's plan")
    running = _child(out, "running", stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    assert running.stdout.readline().strip() == "ready"
    (run_dir,) = _hidden(tmp_path)
    assert _child(tmp_path / "out.x", "writing").wait(60) == -9  # another destination's: never touched
    (other_dest,) = _hidden(tmp_path) - {run_dir}

    assert _child(out, "writing").wait(60) == -9
    (killed,) = _hidden(tmp_path) - {run_dir, other_dest}
    with atomic_output_dir(out) as d:  # this process is older than the leftover: it stays
        (d / "plan.json").write_text("older process")
    with atomic_output_dir(tmp_path / "elsewhere") as d:  # another destination: leaves them all
        (d / "plan.json").write_text("elsewhere")
    assert _hidden(tmp_path) == {run_dir, other_dest, killed}
    assert _child(out, "swapping").wait(60) == -9
    assert killed not in _hidden(tmp_path)  # a run after the kill removed that leftover
    (killed_swapping,) = _hidden(tmp_path) - {run_dir, other_dest}
    assert killed_swapping != killed and not out.exists()  # moved aside, the new one not in
    # look-alikes shiptrial did not make, and one whose owner file is not shiptrial's
    (tmp_path / ".out.mine0000").mkdir()
    (tmp_path / ".out.mine0000" / "keep.txt").write_text("mine")
    (tmp_path / ".out.link0000").symlink_to(tmp_path / "elsewhere")
    (tmp_path / ".out.fake0000").mkdir()
    (tmp_path / ".out.fake0000" / ".owner").write_text("not shiptrial's")
    looks = {".out.mine0000", ".out.link0000", ".out.fake0000"}

    next_run = (
        "import sys; from pathlib import Path; from primitives.io import atomic_output_dir\n"
        "with atomic_output_dir(sys.argv[1]) as d: (d / 'next.txt').write_text('next'); print(Path(sys.argv[1], 'plan.json').read_text())"
    )
    # A process's start is known to a clock tick (10 ms) and a file's time to the kernel's coarse clock: a
    # run started within a tick of the kill cannot prove itself younger, and rightly leaves the leftover
    # to a later run. A user's next run is never that quick; the test waits past the tick.
    time.sleep(0.05)
    done = subprocess.run([sys.executable, "-c", next_run, str(out)], check=True, timeout=60, capture_output=True, text=True)
    assert done.stdout.strip() == "older process"  # the previous result was put back before this run swapped
    assert _hidden(tmp_path) == {run_dir, other_dest} | looks
    assert (tmp_path / ".out.mine0000" / "keep.txt").read_text() == "mine" and (tmp_path / "elsewhere").is_dir()
    assert (out / "next.txt").read_text() == "next"
    running.stdin.close()
    assert running.wait(60) == 0
    assert (out / "plan.json").read_text() == "running" and _hidden(tmp_path) == {other_dest} | looks


def test_a_failed_swap_puts_the_previous_result_back(tmp_path, monkeypatch):
    import primitives.io as pio

    out = tmp_path / "out"
    with atomic_output_dir(out) as d:
        (d / "plan.json").write_text("previous")
    real, calls = pio.os.replace, []

    def flaky(src, dst):
        calls.append(src)
        if len(calls) == 2:  # the new result moving in, after the previous one went aside
            raise OSError("disk full")
        real(src, dst)

    monkeypatch.setattr(pio.os, "replace", flaky)
    with pytest.raises(OSError, match="disk full"), atomic_output_dir(out) as d:
        (d / "plan.json").write_text("new")
    assert (out / "plan.json").read_text() == "previous" and [p.name for p in tmp_path.iterdir()] == ["out"]


def test_a_temporary_killed_before_its_owner_file_had_its_text_goes_once_stale(tmp_path):
    """An empty, unlocked owner file and nothing else: removed after a day unchanged, never sooner."""
    import time

    from primitives.owned_dirs import OWNER

    def box(name, age_s):
        d = tmp_path / name
        d.mkdir()
        (d / OWNER).write_text("")
        then = time.time() - age_s
        for p in (d / OWNER, d):
            os.utime(p, (then, then))
        return d

    stale, recent = box(".out.n0t3xt00", 2 * 86400.0), box(".out.n0t3xt01", 60.0)
    with atomic_output_dir(tmp_path / "out") as d:
        (d / "plan.json").write_text("{}")
    assert not stale.exists() and recent.is_dir()


def test_to_jsonable_arrays_give_plain_numbers_and_none_for_non_finite():
    """Arrays (the fast whole-array path and the element walk) become nested lists of Python
    numbers; NaN and infinity become null, in float arrays of any shape and in 0-d arrays."""
    import json

    import numpy as np

    from primitives.io import to_jsonable

    obj = {
        "f": np.array([[1.5, 2.0], [3.25, -0.0]]),
        "f32": np.array([0.1], np.float32),
        "i": np.arange(3),
        "b": np.array([True, False]),
        "nan": np.array([1.0, np.nan, np.inf]),
        "nan0": np.array(np.nan),
        "f0": np.array(2.5),
        "nested": [np.array([1.0]), (np.int64(2), np.float64(np.nan))],
    }
    out = to_jsonable(obj)
    assert out == {
        "f": [[1.5, 2.0], [3.25, -0.0]],
        "f32": [float(np.float32(0.1))],
        "i": [0, 1, 2],
        "b": [True, False],
        "nan": [1.0, None, None],
        "nan0": None,
        "f0": 2.5,
        "nested": [[1.0], [2, None]],
    }
    kinds = {type(v) for v in (out["f"][0][0], out["f32"][0], out["i"][0], out["b"][0], out["f0"])}
    assert kinds == {float, int, bool}
    json.dumps(out, allow_nan=False)


def test_a_caches_source_digest_changes_with_any_source_file_and_nothing_else(tmp_path):
    """``hash_sources`` (the plan cache's and detect's noise cache's code version): every file of the
    packages with a listed suffix, path and bytes, in sorted order; compiled bytecode and other files
    left out, so an edit, a rename or a new module gives another key and a run that only writes
    ``__pycache__`` does not."""
    import hashlib

    from primitives.io import hash_sources

    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "a.py").write_text("x = 1\n")
    (pkg / "sub" / "b.py").write_text("y = 2\n")
    (pkg / "data.toml").write_text("k = 3\n")

    def digest(suffixes=(".py",)):
        return hash_sources(hashlib.sha256(b"v"), tmp_path, ("pkg",), suffixes).hexdigest()

    want = hashlib.sha256(b"v")
    for rel in ("pkg/a.py", "pkg/sub/b.py"):  # sorted paths, each "path\0bytes\0"
        want.update(rel.encode() + b"\0" + (tmp_path / rel).read_bytes() + b"\0")
    before = digest()
    assert before == want.hexdigest()
    (pkg / "__pycache__").mkdir()
    (pkg / "__pycache__" / "a.cpython-311.py").write_text("compiled")
    (pkg / "notes.txt").write_text("not a source")
    assert digest() == before
    assert digest((".py", ".toml")) != before  # data files where the cache lists them
    (pkg / "sub" / "b.py").write_text("y = 3\n")
    assert digest() != before
