"""Stop 62 (inputs2): the library's writers replace only their own files unless ``force`` (as the CLI does), and a
write the OS refuses (disk full, no permission, a file where a directory should be) is one line naming the output and
the OS's reason, exit 1, nothing left behind: no half-written file, no temporary."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cli.app import _run

ROWS = [{"ship": "model-ship", "speed_mps": 0.6, "criterion": "D", "mean_subtraction": "batchwise", "efficiency_vs_uniform": 1.2}]


def test_write_table_and_plot_summary_replace_only_a_sweeps_own_file_without_force(tmp_path):
    """A notebook's ``write_table(rows, "results.csv")`` replaced the user's results.csv (the CLI alone checked)."""
    from expdesign.sweep import SweepError, plot_summary, write_table

    table, plot = tmp_path / "results.csv", tmp_path / "results.png"
    table.write_text("name,score\nalice,3\n")
    plot.write_bytes(b"my own figure")
    with pytest.raises(SweepError, match=r"^table .*results\.csv: exists and was not written by shiptrial sweep; "):
        write_table(ROWS, table)
    with pytest.raises(SweepError, match=r"^plot .*results\.png: exists .*, or pass force=True to replace it$"):
        plot_summary(ROWS, plot)  # a notebook's fix is the keyword, not the CLI's --force (review of stop 62)
    assert table.read_text() == "name,score\nalice,3\n" and plot.read_bytes() == b"my own figure"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.csv", "results.png"]  # no temporary either
    write_table(ROWS, table, force=True)
    plot_summary(ROWS, plot, force=True)
    write_table(ROWS, table)  # its own files: replaced without force
    assert plot_summary(ROWS, plot).read_bytes()[:4] == b"\x89PNG" and table.read_text().startswith("ship,")


def test_simulate_file_replaces_only_its_own_recording_without_force(tmp_path):
    from identify.yawid.api import simulate_file
    from primitives.errors import UserError

    real = tmp_path / "trial_run.csv"
    real.write_text("# source: sea trial\nt,r\n0,0\n")
    with pytest.raises(UserError, match="exists and was not written by shiptrial yawid-sim; .*pass force=True"):
        simulate_file(real, seed=1)
    assert real.read_text() == "# source: sea trial\nt,r\n0,0\n"
    simulate_file(real, seed=1, force=True)
    assert "# seed: 2" in simulate_file(real, seed=2).read_text()  # its own recording


def test_write_saved_profile_replaces_only_a_saved_profile_without_force(tmp_path):
    from identify.steering.saved_profile import SAVED_HEADER, SavedProfile, write_saved_profile
    from primitives.errors import UserError

    saved = SavedProfile(text=f"# {SAVED_HEADER} from run.csv\nname = 'x'\n", profile=None, changes=[], source_line="")
    mine = tmp_path / "my-kvlcc2.toml"
    mine.write_text("# my hand-tuned copy\n")
    with pytest.raises(
        UserError, match=r"^path .*: exists and was not written by shiptrial steering --save-profile; .*force=True"
    ):
        write_saved_profile(saved, mine)
    assert mine.read_text() == "# my hand-tuned copy\n"
    write_saved_profile(saved, mine, force=True)
    assert write_saved_profile(saved, mine).read_text() == saved.text


@pytest.fixture
def full_disk(monkeypatch):
    """``os.replace`` onto a file named ``full_disk.name`` fails with ENOSPC, as on a full disk (root ignores
    chmod, so a read-only directory cannot be simulated here)."""
    real = os.replace

    class Disk:
        name = ""

    def replace(src, dst, *a, **kw):
        if Path(dst).name == Disk.name:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(src))
        return real(src, dst, *a, **kw)

    monkeypatch.setattr(os, "replace", replace)
    return Disk


def _one_line(capsys, argv: list[str], path: str) -> None:
    assert _run(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: {path}: cannot be written (No space left on device); nothing was written to it"]


def _listing(d: Path) -> list[str]:
    return sorted(str(p.relative_to(d)) for p in d.rglob("*"))


def test_a_full_disk_is_one_line_naming_the_output_and_leaves_nothing(tmp_path, monkeypatch, capsys, full_disk):
    """Before: a Rich traceback of OSError naming the temporary ('.c.toml.54uhnykh'), exit 1."""
    monkeypatch.chdir(tmp_path)
    Path("out").mkdir()
    full_disk.name = "c.toml"
    prof = ["profile", "new", "--name", "coaster", "--length", "100", "--beam", "16", "--draught", "6"]
    prof += ["--block-coefficient", "0.7", "--speed", "13", "--mcr-kw", "3000", "--out", "out/c.toml"]
    _one_line(capsys, prof, "out/c.toml")
    full_disk.name = "r.csv"
    _one_line(capsys, ["yawid-sim", "out/r.csv"], "out/r.csv")
    full_disk.name = "s.csv"
    Path("s.toml").write_text(
        '[sweep]\nships = ["model-ship"]\nlibrary = "standard"\nspeeds = [0.6]\ncriteria = ["D"]\n'
        'mean_subtraction = ["batchwise"]\nseed = 1\n'
    )
    _one_line(capsys, ["sweep", "s.toml", "--out", "out/s.csv"], "out/s.csv")
    full_disk.name = "loaded.csv"
    _one_line(capsys, ["mass-sim", "out/roll", "--seed", "3"], "out/roll/loaded.csv")
    assert _listing(tmp_path / "out") == []  # no temporary, no half-written file, no empty roll/


def test_a_full_disk_while_exporting_names_the_exported_file_not_the_staging_one(tmp_path, monkeypatch, capsys, full_disk):
    from maps.export._testing import synthetic_plan

    monkeypatch.chdir(tmp_path)
    plan = tmp_path / "plan.json"
    plan.write_text(synthetic_plan("model-ship").to_json())
    Path("desk").mkdir()
    full_disk.name = "route.gpx"
    _one_line(capsys, ["export", str(plan), "--format", "gpx", "--out", "desk/route.gpx"], "desk/route.gpx")
    full_disk.name = "model-ship-trial.geojson"
    _one_line(capsys, ["export", str(plan), "--format", "all", "--out", "desk/all"], "desk/all/model-ship-trial.geojson")
    assert _listing(tmp_path / "desk") == []


def test_a_failed_figure_write_is_worded_with_the_os_reason():
    """plan-trial's figures are written in a forked drawer (cli.forkjobs): its error names the file and the reason."""
    from cli.forkjobs import Failed, run_jobs
    from primitives.io import atomic_write_bytes

    def write():
        return atomic_write_bytes(Path("/proc/no-such-dir/x.pdf"), b"%PDF")

    with pytest.raises(Failed) as info:
        run_jobs([(Path("x.pdf"), "the PDF trial card", write)])
    assert str(info.value).startswith("x.pdf: writing the PDF trial card failed: ") and "Errno" not in str(info.value)


def test_a_path_under_a_file_is_a_write_error_naming_the_output(tmp_path):
    from primitives.io import WriteError, atomic_write_text

    (tmp_path / "afile").write_text("x")
    with pytest.raises(WriteError) as info:
        atomic_write_text(tmp_path / "afile" / "t.csv", "a\n")
    assert info.value.filename == str(tmp_path / "afile" / "t.csv") and info.value.strerror


def test_a_full_disk_at_the_sweeps_plot_says_the_finished_table_was_kept(tmp_path, monkeypatch, capsys, full_disk):
    """The plot is written after the table: a disk that fills between them left the table behind under an error
    that said only 'nothing was written' (review of stop 62). The table (the sweep's cells) is kept, and said so."""
    monkeypatch.chdir(tmp_path)
    Path("s.toml").write_text(
        '[sweep]\nships = ["model-ship"]\nlibrary = "standard"\nspeeds = [0.6]\ncriteria = ["D"]\n'
        'mean_subtraction = ["batchwise"]\nseed = 1\n'
    )
    full_disk.name = "s.png"
    assert _run(["sweep", "s.toml", "--out", "s.csv"]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        "wrote s.csv (the table; its plot was not written)",
        "error: s.png: cannot be written (No space left on device); nothing was written to it",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.csv", "s.toml"]


def test_a_json_reader_that_closes_its_pipe_ends_the_command_quietly():
    """``shiptrial primitives --json | head -c 50``: the reader goes away before the document is written; the command
    stops with 141 (128 + SIGPIPE, as a shell reports it) and no traceback (it printed one from the JSON writer)."""
    r, w = os.pipe()
    os.close(r)  # the reader is gone before the command writes
    try:
        cmd = [sys.executable, "-c", "from cli.app import main; main()", "primitives", "--ship", "model-ship", "--json"]
        p = subprocess.run(cmd, stdout=w, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(w)
    assert p.returncode == 141 and p.stderr == "", p.stderr[-500:]
