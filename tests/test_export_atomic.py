"""A set of exports is all-or-nothing: a writer failing late leaves no new file, and files already
in the destination are as they were (``shiptrial export --format all``, ``export_plan`` of the
card, ``plan``), while a success replaces them and leaves no temporary behind."""

from __future__ import annotations

import os

import pytest

import maps.export.card as card
import maps.export.plots as plots
import maps.export.rtz as rtz
import maps.export.staging as staging
from cli.app import _run
from maps.export import export_plan
from maps.export._testing import synthetic_plan
from maps.export.ownership import MANIFEST, write_record
from maps.export.staging import staged_outputs
from primitives.errors import UserError
from primitives.io import OUTPUT_MARKER
from tests.procs import killable_writer

START = "2026-06-01T08:00:00Z"
OLD_GPX = b"<gpx>the route of last week</gpx>"


@pytest.fixture(scope="module")
def plan():
    return synthetic_plan("model-ship", ("straight", "zigzag_20_20_p", "turn_s"))


@pytest.fixture(scope="module")
def plan_file(plan, tmp_path_factory):
    p = tmp_path_factory.mktemp("plan") / "plan.json"
    p.write_text(plan.to_json())
    return p


def _snapshot(d):
    """Every entry of ``d``, hidden ones included, with its bytes."""
    return {p.name: p.read_bytes() for p in d.iterdir()}


def _refuse(*a, **k):
    raise UserError("the writer refused the plan")


@pytest.fixture
def out(tmp_path):
    d = tmp_path / "out"
    d.mkdir()
    (d / "model-ship-trial.gpx").write_bytes(OLD_GPX)  # a file of the same name as an export
    # last week's directory export wrote it (a user's own file is refused: test_bad_input)
    write_record(d, {}, [d / "model-ship-trial.gpx"])
    (d / "notes.txt").write_text("crew notes")
    return d


@pytest.mark.parametrize(
    "module, writer",
    [(rtz, "write_rtz"), (card, "write_card_pdf"), (plots, "plot_states")],
    ids=["rtz", "card-pdf", "states-png-last"],
)
def test_cli_export_all_failing_late_writes_nothing(plan_file, out, module, writer, monkeypatch, capsys):
    before = _snapshot(out)
    monkeypatch.setattr(module, writer, _refuse)
    assert _run(["export", str(plan_file), "--format", "all", "--out", str(out), "--start", START]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert err == "error: the writer refused the plan", err
    assert "wrote" not in captured.out
    assert _snapshot(out) == before  # no new file, no temporary, the old GPX unchanged


def test_cli_export_all_replaces_files_and_leaves_no_temporary(plan_file, out, capsys):
    assert _run(["export", str(plan_file), "--format", "all", "--out", str(out), "--start", START]) == 0
    names = {p.name for p in out.iterdir()}
    assert names == {"notes.txt", MANIFEST} | {
        f"model-ship-trial{s}" for s in (".geojson", ".gpx", ".rtz", ".csv", ".html", ".pdf", "-track.png", "-states.png")
    }
    assert (out / "model-ship-trial.gpx").read_bytes() != OLD_GPX and (out / "notes.txt").read_text() == "crew notes"
    wrote = [line.split(" ", 1)[1] for line in capsys.readouterr().out.splitlines()]
    assert sorted(wrote) == sorted(str(out / n) for n in names - {"notes.txt", MANIFEST})


def test_card_html_not_left_when_its_pdf_fails(plan, tmp_path, monkeypatch):
    monkeypatch.setattr(card, "write_card_pdf", _refuse)
    dest = tmp_path / "new" / "dir"
    with pytest.raises(UserError):
        export_plan(plan, "card", dest / "card.html", start=START)
    assert list(tmp_path.iterdir()) == []  # not even the directories it made


def test_failed_rename_puts_back_what_the_earlier_ones_replaced(tmp_path, monkeypatch):
    (tmp_path / "a.txt").write_text("old a")
    (tmp_path / "b.txt").write_text("old b")
    real, calls = os.replace, []

    def flaky(src, dst):
        calls.append(dst)
        if len(calls) == 5:  # a -> old, a in, b -> old, b in, c in: the last rename fails
            raise OSError("disk went away")
        real(src, dst)

    monkeypatch.setattr(staging.os, "replace", flaky)
    with pytest.raises(OSError, match="disk went away"), staged_outputs(tmp_path) as tmp:
        for name in ("a.txt", "b.txt", "c.txt"):
            (tmp / name).write_text(f"new {name}")
    assert _snapshot(tmp_path) == {"a.txt": b"old a", "b.txt": b"old b"}


def test_plan_failing_late_leaves_the_last_run_as_it_was(tmp_path, monkeypatch, capsys):
    """plan-trial writes the PDF card in a forked child beside the other exports: when the RTZ
    writer fails, neither the PDF nor any other file replaces the previous run's."""
    out = tmp_path / "trial"
    out.mkdir()
    for name, data in ((OUTPUT_MARKER, b"written by shiptrial"), ("plan.json", b"{}"), ("full-scale-trial.pdf", b"%PDF old")):
        (out / name).write_bytes(data)  # what a previous run left
    before = _snapshot(out)
    monkeypatch.setattr(rtz, "write_rtz", _refuse)
    assert _run(["plan", "--counts", "steep_zigzag_surge=1", "--out", str(out), "--start-time", START]) == 2
    assert capsys.readouterr().err.strip() == "error: the writer refused the plan"
    assert _snapshot(out) == before and [p.name for p in tmp_path.iterdir()] == ["trial"]


def _child(out, mode, **kw):
    return killable_writer(
        "maps.export.staging", "staged_outputs", "route.gpx", "publishing", out, mode, text="'new route'", **kw
    )


def _staging_dirs(d):
    return sorted(p.name for p in d.iterdir() if p.name.startswith(staging.PREFIX))


def test_next_export_removes_what_a_killed_export_left_and_nothing_else(tmp_path):
    """SIGKILL mid-export leaves a hidden staging directory; the next export (a later process)
    removes it and puts back a file a killed publish had moved aside, but keeps a running
    export's directory, the leftovers of processes younger than itself and every
    .shiptrial-export.* entry shiptrial did not make."""
    import subprocess
    import sys
    import time

    out = tmp_path / "out"
    out.mkdir()
    (out / "route.gpx").write_text("last week's route")
    running = _child(out, "running", stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    assert running.stdout.readline().strip() == "ready"
    (run_dir,) = _staging_dirs(out)

    assert _child(out, "writing").wait(60) == -9
    (killed,) = set(_staging_dirs(out)) - {run_dir}
    time.sleep(0.05)  # the next export must start a clock tick after the kill to prove itself younger (as below)
    assert _child(out, "publishing").wait(60) == -9  # an export after the kill: it removed the first leftover
    (killed_publishing,) = set(_staging_dirs(out)) - {run_dir}
    assert killed_publishing != killed and not (out / "route.gpx").exists()  # moved aside, the new one not in

    with staged_outputs(out) as tmp:  # this process is older than the leftover: it stays
        (tmp / "other.txt").write_text("x")
    assert set(_staging_dirs(out)) == {run_dir, killed_publishing}
    # look-alikes shiptrial did not make, and one whose owner file is not shiptrial's
    (out / ".shiptrial-export.mine").mkdir()
    (out / ".shiptrial-export.mine" / "keep.txt").write_text("mine")
    (out / ".shiptrial-export.link").symlink_to(tmp_path)
    (out / ".shiptrial-export.fake").mkdir()
    (out / ".shiptrial-export.fake" / staging.OWNER).write_text("not shiptrial's")

    next_export = (
        "import sys; from maps.export.staging import staged_outputs\n"
        "with staged_outputs(sys.argv[1]) as tmp: (tmp / 'next.txt').write_text('next')"
    )
    time.sleep(0.05)  # past the 10 ms clock tick a process's start is known to (see tests/test_io.py)
    subprocess.run([sys.executable, "-c", next_export, str(out)], check=True, timeout=60)
    assert (out / "route.gpx").read_text() == "last week's route"  # put back, then its directory removed
    assert set(_staging_dirs(out)) == {run_dir, ".shiptrial-export.mine", ".shiptrial-export.link", ".shiptrial-export.fake"}
    assert (out / ".shiptrial-export.mine" / "keep.txt").read_text() == "mine" and tmp_path.is_dir()
    running.stdin.close()
    assert running.wait(60) == 0
    assert (out / "route.gpx").read_text() == "new route" and run_dir not in _staging_dirs(out)
    assert (out / "next.txt").read_text() == "next"


def _old_version_dir(out, name, files, *, age_s=2 * 86400.0, top=()):
    """A staging directory as the versions before the owner file left it: ``files`` maps
    "new/x.gpx" or "old/route.gpx" to its text; every time stamp ``age_s`` in the past."""
    import time

    d = out / name
    d.mkdir()
    for rel, text in files.items():
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).write_text(text)
    for rel in top:
        (d / rel).write_text("someone's")
    then = time.time() - age_s
    for p in sorted(d.rglob("*"), reverse=True) + [d]:
        os.utime(p, (then, then), follow_symlinks=False)
    return d


def test_next_export_removes_an_earlier_versions_stale_staging_and_nothing_else(tmp_path):
    """Staging directories of the versions before the owner file (killed while writing, or while
    publishing with a destination file moved aside to old/) go once nothing in them changed for a
    day, the moved-aside file put back; anything not provably such a leftover stays: a recent
    one (an export may be running), a look-alike name, another file in it, a sub-directory, a
    file of no export's kind, a link, or a moved-aside file whose name is taken again."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "taken.gpx").write_text("this week's route")
    gone = [
        _old_version_dir(out, ".shiptrial-export.k1ll3d_w", {"new/ship-trial.gpx": "g", "new/.ship-trial.csv.x1y2": "c"}),
        _old_version_dir(out, ".shiptrial-export.publ1sh3", {"new/ship-trial.rtz": "r", "old/route.gpx": "last week's route"}),
        _old_version_dir(out, ".shiptrial-export.0nlyold0", {"old/card.html": "last week's card"}),
        _old_version_dir(out, ".shiptrial-export.empty000", {}),
    ]
    kept = [
        _old_version_dir(out, ".shiptrial-export.recent00", {"new/ship-trial.gpx": "g"}, age_s=60.0),
        _old_version_dir(out, ".shiptrial-export.short", {"new/ship-trial.gpx": "g"}),
        _old_version_dir(out, ".shiptrial-export.extra000", {"new/ship-trial.gpx": "g"}, top=("notes.txt",)),
        _old_version_dir(out, ".shiptrial-export.subdir00", {"new/deep/ship-trial.gpx": "g"}),
        _old_version_dir(out, ".shiptrial-export.notours0", {"new/thesis.tex": "mine"}),
        _old_version_dir(out, ".shiptrial-export.taken000", {"old/taken.gpx": "last week's route"}),
    ]
    link = out / ".shiptrial-export.link0000"
    link.symlink_to(kept[0])

    removed = staging.remove_stale(out)
    assert sorted(removed) == sorted(gone) and not any(d.exists() for d in gone)
    assert (out / "route.gpx").read_text() == "last week's route" and (out / "card.html").read_text() == "last week's card"
    assert all(d.is_dir() for d in kept) and link.is_symlink()
    assert (out / "taken.gpx").read_text() == "this week's route" and (kept[-1] / "old" / "taken.gpx").exists()
    assert (kept[4] / "new" / "thesis.tex").read_text() == "mine"
    with staged_outputs(out) as tmp:  # an export runs through them all
        (tmp / "next.gpx").write_text("next")
    assert (out / "next.gpx").read_text() == "next" and all(d.is_dir() for d in kept)


def test_staging_killed_before_its_owner_file_had_its_text_goes_once_stale(tmp_path):
    """Killed between creating its owner file and writing shiptrial's text into it: an empty,
    unlocked owner file. Such a directory is judged as an earlier version's (stale after a day,
    only export files in it), never sooner."""
    out = tmp_path / "out"
    out.mkdir()
    stale = _old_version_dir(out, ".shiptrial-export.n0t3xt00", {"new/ship-trial.gpx": "g", staging.OWNER: ""})
    recent = _old_version_dir(out, ".shiptrial-export.n0t3xt01", {"new/ship-trial.gpx": "g", staging.OWNER: ""}, age_s=60.0)
    other = _old_version_dir(out, ".shiptrial-export.n0t3xt02", {"new/thesis.tex": "mine", staging.OWNER: ""})
    assert staging.remove_stale(out) == [stale]
    assert recent.is_dir() and other.is_dir() and not stale.exists()


def test_a_plan_trial_directory_takes_one_format_s_export_after_another(plan, tmp_path):
    """Review of stop 61: in plan-trial's output directory (its marker) a re-export of one format recorded only
    that file, and the next format's re-export then refused plan-trial's own file as 'not written by an export'.
    A file the manifest does not list is plan-trial's there; one an export wrote and the user edited since is not."""
    from maps.export import default_path
    from maps.export._common import ExportError

    d = tmp_path / "plan-out"
    d.mkdir()
    (d / OUTPUT_MARKER).write_text("written by shiptrial")
    gpx, csv = (d / default_path(plan, fmt).name for fmt in ("gpx", "csv"))
    gpx.write_text("plan-trial's gpx")
    csv.write_text("plan-trial's csv")
    export_plan(plan, "gpx", gpx)
    export_plan(plan, "csv", csv)
    assert csv.read_text() != "plan-trial's csv" and gpx.read_text() != "plan-trial's gpx"
    gpx.write_text("edited by hand")
    with pytest.raises(ExportError, match="was changed after an export wrote it"):
        export_plan(plan, "gpx", gpx)
    assert gpx.read_text() == "edited by hand"
