"""plan-trial draws its figures in a drawer process forked when the command starts (cli.drawer):
the files are those of drawing in one process, a drawing error is the command's one-line error
with nothing written, and no process outlives the command, whatever happened."""

from __future__ import annotations

import os

import pytest

import cli.drawer as drawer
from cli.app import _run

START = "2026-06-01T08:00Z"
COUNTS = "steep_zigzag_surge=1"


def _files(d):
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def _children() -> set[int]:
    """Live (or unreaped) child processes of this process (Linux /proc)."""
    kids: set[int] = set()
    for task in os.listdir("/proc/self/task"):
        with open(f"/proc/self/task/{task}/children") as fh:
            kids.update(int(p) for p in fh.read().split())
    return kids


@pytest.fixture(scope="module")
def forked(tmp_path_factory):
    out = tmp_path_factory.mktemp("forked") / "out"
    assert _run(["plan", "--counts", COUNTS, "--out", str(out), "--start-time", START]) == 0
    return out


def test_drawer_writes_what_one_process_writes(forked, tmp_path, monkeypatch, capsys):
    """Without fork (other platforms) every figure is drawn in the command's process: the same
    files, byte for byte (plan.json up to its timings)."""
    monkeypatch.setattr(drawer, "CAN_FORK", False)
    out = tmp_path / "here"
    assert _run(["plan", "--counts", COUNTS, "--out", str(out), "--start-time", START]) == 0
    a, b = _files(forked), _files(out)
    assert a.keys() == b.keys() and {"plan.png", "full-scale-trial.pdf", "full-scale-trial.html",
                                     "full-scale-trial-track.png", "full-scale-trial-states.png"} <= a.keys()
    assert [k for k in a if k != "plan.json" and a[k] != b[k]] == []
    capsys.readouterr()


def test_drawing_error_is_one_line_and_nothing_is_written(tmp_path, monkeypatch, capsys):
    """The track figure (drawn in the drawer itself, not its child) fails: exit 2 with the file
    and the cause, no output directory, no process left."""
    import maps.export.plots as plots

    def broken(*a, **k):
        raise RuntimeError("no ink")

    monkeypatch.setattr(plots, "plot_track", broken)
    before = _children()
    out = tmp_path / "bad"
    assert _run(["plan", "--counts", COUNTS, "--out", str(out), "--start-time", START]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: full-scale-trial-track.png: writing the track figure failed: RuntimeError: no ink"]
    assert not out.exists() and _children() <= before


def test_failed_planning_ends_the_drawer(tmp_path, capsys):
    """--counts naming no primitive of the library fails inside the planning, after the drawer
    started: the one-line error, nothing written, the drawer ended and reaped."""
    out = tmp_path / "none"
    before = _children()
    assert _run(["plan", "--counts", "nosuch=1", "--out", str(out), "--start-time", START]) == 2
    assert capsys.readouterr().err.startswith("error: --counts: unknown primitive(s) nosuch for full-scale")
    assert not out.exists() and _children() <= before
