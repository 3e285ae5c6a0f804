"""Atomic outputs: a failed run never leaves a mix of old and new files."""

import pytest

from primitives.errors import UserError
from primitives.io import OUTPUT_MARKER, atomic_output_dir, check_out_path


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
